#include "weft/rigid/particle_coupling.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/text.hpp"
#include "rigid/particle_contacts.hpp"

namespace weft {

namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

constexpr double kEpsilon = 1e-6;  // m: how close to the thickened surface the advancement stops
constexpr int kMaxAdvances = 64;
// A held particle supports a body whose direction from it is within 60 degrees of the
// normal it is held along (cos 60 = 0.5).
constexpr double kSupportAlignment = 0.5;

/// A lower bound of the distance from `p` (the piece's frame) to the piece, exact for a
/// sphere and inside a hull (the largest face-plane distance), 1-Lipschitz: safe steps
/// for conservative advancement.
double distanceBound(const RigidPiece& piece, const ConvexHull* hull, const Vec3& p) {
  if (piece.kind == RigidShapeDesc::Kind::Sphere) return p.norm() - piece.radius;
  double d = -std::numeric_limits<double>::infinity();
  for (const ConvexFace& f : hull->faces) d = std::max(d, f.normal.dot(p) - f.offset);
  return d;
}

template <class S>
Vec3 row(const Vec3Array<S>& x, Index i) {
  return {static_cast<double>(x(i, 0)), static_cast<double>(x(i, 1)), static_cast<double>(x(i, 2))};
}

template <class S>
void setRow(Vec3Array<S>& x, Index i, const Vec3& v) {
  x(i, 0) = static_cast<S>(v.x());
  x(i, 1) = static_cast<S>(v.y());
  x(i, 2) = static_cast<S>(v.z());
}

}  // namespace

template <class S>
ParticleBodyContacts<S>::ParticleBodyContacts(const RigidModel& bodies, Index particleCount, double thickness)
    : thickness_(thickness) {
  if (!(std::isfinite(thickness) && thickness > 0))
    detail::rejectField("ParticleBodyContacts: thickness", thickness, "finite and > 0 (m)");
  if (particleCount < 0) throw std::invalid_argument("ParticleBodyContacts: particleCount must be >= 0");
  records_.resize(static_cast<std::size_t>(particleCount) * kContactsPerParticle);
  const std::size_t pieces = static_cast<std::size_t>(bodies.pieceCount());
  start_.resize(pieces);
  end_.resize(pieces);
  boxMin_.resize(pieces);
  boxMax_.resize(pieces);
  supportSlots_.resize(records_.size());
  supportCount_.resize(static_cast<std::size_t>(particleCount));
  supports_.reserve(records_.size());
}

template <class S>
Index ParticleBodyContacts<S>::collectSupports(const Vec3Array<S>& x, const Vec3Array<S>& v, const ScalarArray<S>& w,
                                               RigidWorld& world, const Executor& exec) {
  const RigidModel& m = world.model();
  const RigidState& now = world.state();
  const Index pieces = m.pieceCount();
  const double thickness = thickness_;
  // A particle within half a thickness of a static or kinematic piece lies on it (held);
  // a held particle supports a dynamic piece within the speculative distance.
  const double hold = 0.5 * thickness;
  const double reach = world.options().speculativeDistance;
  bool anyDynamic = false;
  for (Index p = 0; p < pieces; ++p) {
    end_[p] = world.piecePose(p, now);
    const RigidPiece& piece = m.pieces[p];
    anyDynamic = anyDynamic || m.motion[piece.body] == BodyMotion::Dynamic;
    const Vec3 half = 0.5 * (piece.localMax - piece.localMin), mid = 0.5 * (piece.localMax + piece.localMin);
    const Vec3 c = end_[p].position + end_[p].rotation * mid;
    const Vec3 e = end_[p].rotation.cwiseAbs() * half;
    const double grow = thickness + std::max(hold, reach);
    boxMin_[p] = c - e - Vec3::Constant(grow);
    boxMax_[p] = c + e + Vec3::Constant(grow);
  }
  if (!anyDynamic) {
    world.setSupports(nullptr, 0);
    return 0;
  }
  // Separation (distance - thickness) of a particle at `c` from piece p within `margin`,
  // the normal from the particle into the piece and the point on the piece's surface.
  const auto separation = [&](Index p, const Vec3& c, double margin, Vec3& normal, Vec3& point) {
    const RigidPiece& piece = m.pieces[p];
    if (piece.kind == RigidShapeDesc::Kind::Sphere) {
      const Vec3 d = end_[p].position - c;
      const double dist = d.norm();
      normal = dist > 1e-12 ? Vec3(d / dist) : Vec3(-Vec3::UnitY());
      point = end_[p].position - piece.radius * normal;
      return dist - piece.radius - thickness;
    }
    ContactManifold out;
    collideSphereHull(c, thickness, m.hulls[piece.hull], end_[p], margin, out);
    if (out.pointCount == 0) return std::numeric_limits<double>::infinity();
    normal = out.normal;  // from the particle to the hull
    point = out.points[0].position;
    return out.points[0].separation;
  };
  const Index n = static_cast<Index>(x.rows());
  exec.parallelFor(n, 256, [&](Index begin, Index end) {
    for (Index i = begin; i < end; ++i) {
      int& used = supportCount_[static_cast<std::size_t>(i)];
      used = 0;
      const Vec3 c = row(x, i);
      const auto inBox = [&](Index p) {
        return !((c.array() > boxMax_[p].array()).any() || (c.array() < boxMin_[p].array()).any());
      };
      // Held: pinned (any direction), or lying on a static or kinematic piece, which holds
      // it along that piece's normal only.
      const bool pinned = static_cast<double>(w[i]) <= 0;
      bool held = pinned;
      Vec3 normal = Vec3::Zero(), point = Vec3::Zero(), holdNormal = Vec3::Zero();
      double holdSpeed = 0;  // of the holder's surface along holdNormal, m/s
      for (Index p = 0; p < pieces && !held; ++p) {
        const Index holder = m.pieces[p].body;
        if (m.motion[holder] == BodyMotion::Dynamic || !inBox(p)) continue;
        held = separation(p, c, hold, normal, point) <= hold;
        holdNormal = -normal;  // from the holder to the particle
        holdSpeed = (now.v[holder] + now.w[holder].cross(point - now.x[holder])).dot(holdNormal);
      }
      if (!held) continue;
      SupportContact* slots = &supportSlots_[static_cast<std::size_t>(i) * kContactsPerParticle];
      for (Index p = 0; p < pieces && used < kContactsPerParticle; ++p) {
        const Index body = m.pieces[p].body;
        if (m.motion[body] != BodyMotion::Dynamic || !inBox(p)) continue;
        const double s = separation(p, c, reach, normal, point);
        if (!(s <= reach)) continue;
        // A particle lying on a table holds a body up, not sideways: a body beside it (the
        // cloth sliding against a box's side) is left to the particle contacts. Along the
        // contact normal the point moves as the holder's surface does (a particle sliding
        // under a box's lower edge does not push the box away, it drags it by friction; a
        // particle leaving the table does not throw the box up).
        Vec3 velocity = row(v, i);
        if (!pinned) {
          const double align = normal.dot(holdNormal);
          if (align < kSupportAlignment) continue;
          velocity += (holdSpeed * align - velocity.dot(normal)) * normal;
        }
        SupportContact& sc = slots[used++];
        sc.body = body;
        sc.point = point;
        sc.normal = normal;
        sc.separation = s;
        sc.velocity = velocity;
        sc.key = (std::uint64_t(std::uint32_t(i)) << 32) | std::uint32_t(p);
      }
    }
  });
  // In particle order: the same list, and keys increasing, for any thread count.
  supports_.clear();
  for (Index i = 0; i < n; ++i)
    for (int k = 0; k < supportCount_[static_cast<std::size_t>(i)]; ++k)
      supports_.push_back(supportSlots_[static_cast<std::size_t>(i) * kContactsPerParticle + k]);
  world.setSupports(supports_.data(), static_cast<Index>(supports_.size()));
  return static_cast<Index>(supports_.size());
}

template <class S>
ParticleBodyStats ParticleBodyContacts<S>::resolve(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1,
                                                   const ScalarArray<S>& w, RigidWorld& world, const Executor& exec) {
  const RigidModel& m = world.model();
  const RigidState& before = world.stepStart();
  const RigidState& after = world.state();
  const Index pieces = m.pieceCount();
  const double thickness = thickness_;
  // Each piece at both ends of the step and the box it swept, grown by the thickness.
  for (Index p = 0; p < pieces; ++p) {
    start_[p] = world.piecePose(p, before);
    end_[p] = world.piecePose(p, after);
    const RigidPiece& piece = m.pieces[p];
    const Vec3 half = 0.5 * (piece.localMax - piece.localMin), mid = 0.5 * (piece.localMax + piece.localMin);
    Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const Pose* pose : {&start_[p], &end_[p]}) {
      const Vec3 c = pose->position + pose->rotation * mid;
      const Vec3 e = pose->rotation.cwiseAbs() * half;
      lo = lo.cwiseMin(c - e);
      hi = hi.cwiseMax(c + e);
    }
    boxMin_[p] = lo.array() - thickness;
    boxMax_[p] = hi.array() + thickness;
  }
  // Inverse world inertia of each body at the end of the step.
  const auto inverseInertia = [&](Index b) {
    const Mat3 r = after.q[b].toRotationMatrix();
    return Mat3(r * m.inverseInertia[b] * r.transpose());
  };

  const Index n = static_cast<Index>(x1.rows());
  exec.parallelFor(n, 256, [&](Index begin, Index end) {
    for (Index i = begin; i < end; ++i) {
      Record* slots = &records_[static_cast<std::size_t>(i) * kContactsPerParticle];
      for (int k = 0; k < kContactsPerParticle; ++k) slots[k].piece = -1;
      const double wi = static_cast<double>(w[i]);
      if (wi <= 0) continue;
      const Vec3 a = row(x0, i);
      Vec3 b = row(x1, i);
      const Vec3 segLo = a.cwiseMin(b), segHi = a.cwiseMax(b);
      int used = 0;
      for (Index p = 0; p < pieces && used < kContactsPerParticle; ++p) {
        if ((segLo.array() > boxMax_[p].array()).any() || (segHi.array() < boxMin_[p].array()).any()) continue;
        const RigidPiece& piece = m.pieces[p];
        const ConvexHull* hull = piece.kind == RigidShapeDesc::Kind::Hull ? &m.hulls[piece.hull] : nullptr;
        const Pose& p0 = start_[p];
        const Pose& p1 = end_[p];
        // The segment in the piece's frame: the body's motion taken out.
        const Vec3 l0 = p0.rotation.transpose() * (a - p0.position);
        const Vec3 l1 = p1.rotation.transpose() * (b - p1.position);
        const Vec3 d = l1 - l0;
        const double len = d.norm();
        double tau = 0;
        bool hit = false;
        for (int it = 0; it < kMaxAdvances; ++it) {
          const double gap = distanceBound(piece, hull, l0 + tau * d) - thickness;
          if (gap <= kEpsilon) {
            hit = true;
            break;
          }
          if (len <= 0) break;
          tau += gap / len;
          if (tau > 1) break;
        }
        if (!hit) continue;
        const bool endInside = distanceBound(piece, hull, l1) - thickness <= kEpsilon;
        // Started in contact and ends clear: it leaves the surface, nothing to resolve.
        if (!endInside && tau == 0) continue;
        // Where the particle is stopped (the impact point, or the end if it ends in
        // contact), at the end of the step.
        const Vec3 local = endInside ? l1 : Vec3(l0 + tau * d);
        Vec3 xc = p1.rotation * local + p1.position;
        // Exact distance and outward normal at that point.
        Vec3 normal;
        double separation;  // distance - thickness
        if (!hull) {
          const double r = local.norm();
          normal = p1.rotation * (r > 1e-12 ? Vec3(local / r) : Vec3::UnitY());
          separation = r - piece.radius - thickness;
        } else {
          ContactManifold out;
          collideSphereHull(xc, thickness, *hull, p1, std::numeric_limits<double>::infinity(), out);
          if (out.pointCount == 0) continue;
          normal = -out.normal;  // the manifold's normal points from the particle to the hull
          separation = out.points[0].separation;
        }
        if (separation > kEpsilon && !endInside) {
          // Stopped on the way in but the exact distance says clear: the bound was loose
          // (near an edge or corner): no contact yet.
          continue;
        }
        if (separation < 0) xc += (-separation) * normal;
        // Velocity relative to the body's surface; inelastic normal, Coulomb friction.
        const Index body = piece.body;
        const bool dynamic = m.motion[body] == BodyMotion::Dynamic;
        const Vec3 r = xc - after.x[body];
        const Vec3 u = after.v[body] + after.w[body].cross(r);
        const Vec3 v = row(v1, i);
        const Vec3 rel = v - u;
        const double vn = rel.dot(normal);
        Vec3 impulse = Vec3::Zero();
        if (vn < 0) {
          const Mat3 ii = dynamic ? inverseInertia(body) : Mat3::Zero();
          const auto k = [&](const Vec3& dir) {
            const Vec3 rd = r.cross(dir);
            return wi + m.inverseMass[body] + rd.dot(ii * rd);
          };
          const double jn = -vn / k(normal);
          impulse = jn * normal;
          const Vec3 slip = rel - vn * normal;
          const double slipSpeed = slip.norm();
          if (slipSpeed > 0) {
            const Vec3 t = slip / slipSpeed;
            const double stick = slipSpeed / k(t);
            const double jt = stick <= m.staticFriction[body] * jn ? stick : m.kineticFriction[body] * jn;
            impulse -= jt * t;
          }
          setRow(v1, i, v + wi * impulse);
        }
        setRow(x1, i, xc);
        b = xc;
        slots[used].piece = p;
        slots[used].impulse = impulse;
        slots[used].point = xc;
        ++used;
      }
    }
  });
  // The reactions, in particle order: the same sums for any thread count.
  ParticleBodyStats stats;
  for (const Record& r : records_) {
    if (r.piece < 0) continue;
    // (A reaction that is not a number is not passed on: applyImpulse would refuse it, and
    // the particle that made it fails the next step's check.)
    if (!(r.impulse.allFinite() && r.point.allFinite())) continue;
    ++stats.contacts;
    stats.impulse += r.impulse.norm();
    world.applyImpulse(m.pieces[r.piece].body, -r.impulse, r.point);
  }
  return stats;
}

template class ParticleBodyContacts<float>;
template class ParticleBodyContacts<double>;

}  // namespace weft
