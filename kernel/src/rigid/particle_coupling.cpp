#include "weft/rigid/particle_coupling.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace weft {

namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

constexpr double kEpsilon = 1e-6;  // m: how close to the thickened surface the advancement stops
constexpr int kMaxAdvances = 64;

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
    throw std::invalid_argument("ParticleBodyContacts: thickness must be finite and > 0 (m), got " +
                                std::to_string(thickness));
  if (particleCount < 0) throw std::invalid_argument("ParticleBodyContacts: particleCount must be >= 0");
  records_.resize(static_cast<std::size_t>(particleCount) * kContactsPerParticle);
  const std::size_t pieces = static_cast<std::size_t>(bodies.pieceCount());
  start_.resize(pieces);
  end_.resize(pieces);
  boxMin_.resize(pieces);
  boxMax_.resize(pieces);
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
    ++stats.contacts;
    stats.impulse += r.impulse.norm();
    world.applyImpulse(m.pieces[r.piece].body, -r.impulse, r.point);
  }
  return stats;
}

template class ParticleBodyContacts<float>;
template class ParticleBodyContacts<double>;

}  // namespace weft
