#include "weft/rigid/particle_coupling.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
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

double det3(const Vec3& u, const Vec3& v, const Vec3& w) { return u.dot(v.cross(w)); }

/// Whether the point p (p0 -> p1) passes through the inside of the triangle (a, b, c),
/// every point moving linearly over t in [0, 1], an odd number of times. The point is in
/// the triangle's plane where f(t) = det(a - p, b - p, c - p) changes sign; f is a cubic,
/// monotone between the roots of its derivative, so each sign change is one root, found
/// by bisection; at each, the point's barycentric coordinates in the triangle say whether
/// it is inside (edges included, so a body through an edge is seen by both triangles).
bool passesThrough(const Vec3& p0, const Vec3& p1, const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1,
                   const Vec3& c0, const Vec3& c1) {
  const Vec3 A = a0 - p0, B = b0 - p0, C = c0 - p0;
  const Vec3 dA = (a1 - p1) - A, dB = (b1 - p1) - B, dC = (c1 - p1) - C;
  const auto f = [&](double t) { return det3(A + t * dA, B + t * dB, C + t * dC); };
  // f(t) = k3 t^3 + k2 t^2 + k1 t + k0 (det is linear in each argument).
  const double k3 = det3(dA, dB, dC);
  const double k2 = det3(dA, dB, C) + det3(dA, B, dC) + det3(A, dB, dC);
  const double k1 = det3(dA, B, C) + det3(A, dB, C) + det3(A, B, dC);
  // The ends of the monotone pieces: 0, the roots of f' = 3 k3 t^2 + 2 k2 t + k1 in (0, 1), 1.
  double ends[4] = {0, 1, 1, 1};
  int count = 1;
  const double qa = 3 * k3, qb = 2 * k2, qc = k1;
  if (qa != 0) {
    const double disc = qb * qb - 4 * qa * qc;
    if (disc > 0) {
      const double s = std::sqrt(disc);
      double r0 = (-qb - s) / (2 * qa), r1 = (-qb + s) / (2 * qa);
      if (r0 > r1) std::swap(r0, r1);
      for (const double r : {r0, r1})
        if (r > 0 && r < 1) ends[count++] = r;
    }
  } else if (qb != 0) {
    const double r = -qc / qb;
    if (r > 0 && r < 1) ends[count++] = r;
  }
  ends[count] = 1;
  int inside = 0;
  for (int k = 0; k < count; ++k) {
    double lo = ends[k], hi = ends[k + 1];
    const bool loNegative = f(lo) < 0;
    if (loNegative == (f(hi) < 0)) continue;  // no root in this piece
    for (int it = 0; it < 64 && hi - lo > 1e-15; ++it) {
      const double mid = 0.5 * (lo + hi);
      ((f(mid) < 0) == loNegative ? lo : hi) = mid;
    }
    const double t = 0.5 * (lo + hi);
    const Vec3 p = p0 + t * (p1 - p0), a = a0 + t * (a1 - a0);
    const Vec3 e1 = (b0 + t * (b1 - b0)) - a, e2 = (c0 + t * (c1 - c0)) - a, q = p - a;
    const double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2), q1 = q.dot(e1), q2 = q.dot(e2);
    const double den = d11 * d22 - d12 * d12;
    if (!(den > 1e-12 * d11 * d22)) continue;  // degenerate (or not finite) at that moment
    const double v = (d22 * q1 - d12 * q2) / den, w = (d11 * q2 - d12 * q1) / den;
    constexpr double kEdge = 1e-9;
    if (v >= -kEdge && w >= -kEdge && v + w <= 1 + kEdge) ++inside;
  }
  return inside % 2 == 1;
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
ParticleBodyContacts<S>::ParticleBodyContacts(const RigidModel& bodies, Index particleCount, double thickness,
                                              Index triangleCount)
    : thickness_(thickness) {
  if (!(std::isfinite(thickness) && thickness > 0))
    detail::rejectField("ParticleBodyContacts: thickness", thickness, "finite and > 0 (m)");
  if (particleCount < 0) throw std::invalid_argument("ParticleBodyContacts: particleCount must be >= 0");
  if (triangleCount < 0) throw std::invalid_argument("ParticleBodyContacts: triangleCount must be >= 0");
  records_.resize(static_cast<std::size_t>(particleCount) * kContactsPerParticle);
  const std::size_t pieces = static_cast<std::size_t>(bodies.pieceCount());
  start_.resize(pieces);
  end_.resize(pieces);
  boxMin_.resize(pieces);
  boxMax_.resize(pieces);
  supportSlots_.resize(records_.size());
  supportCount_.resize(static_cast<std::size_t>(particleCount));
  supports_.reserve(records_.size());
  side_.resize(static_cast<std::size_t>(particleCount));
  pathLo_.resize(static_cast<std::size_t>(Executor::blockCount(particleCount, kResolveBlock)));
  pathHi_.resize(pathLo_.size());
  triangleFlags_.resize(static_cast<std::size_t>(Executor::blockCount(triangleCount, kCrossingTriangles)));
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
  // Each block also keeps the box of its particles' paths, from x0 to where this pass leaves
  // them (countCrossings starts from it).
  exec.parallelForBlocks(n, kResolveBlock, [&](Index block, Index begin, Index end) {
    Vec3 pathLo = Vec3::Constant(std::numeric_limits<double>::infinity()), pathHi = -pathLo;
    for (Index i = begin; i < end; ++i) {
      Record* slots = &records_[static_cast<std::size_t>(i) * kContactsPerParticle];
      for (int k = 0; k < kContactsPerParticle; ++k) slots[k].piece = -1;
      const double wi = static_cast<double>(w[i]);
      const Vec3 a = row(x0, i);
      Vec3 b = row(x1, i);
      pathLo = pathLo.cwiseMin(a);
      pathHi = pathHi.cwiseMax(a);
      if (wi <= 0) {
        pathLo = pathLo.cwiseMin(b);
        pathHi = pathHi.cwiseMax(b);
        continue;
      }
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
      pathLo = pathLo.cwiseMin(b);
      pathHi = pathHi.cwiseMax(b);
    }
    pathLo_[static_cast<std::size_t>(block)] = pathLo;
    pathHi_[static_cast<std::size_t>(block)] = pathHi;
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

template <class S>
std::int64_t ParticleBodyContacts<S>::countCrossings(const Vec3Array<S>& x0, const Vec3Array<S>& x1,
                                                     const Triangles& triangles, const RigidWorld& world,
                                                     const Executor& exec, Index* first) {
  const RigidModel& m = world.model();
  const RigidState& before = world.stepStart();
  const RigidState& after = world.state();
  const Index count = triangles.count(), n = static_cast<Index>(x0.rows());
  if (Executor::blockCount(count, kCrossingTriangles) > static_cast<Index>(triangleFlags_.size()) ||
      n > static_cast<Index>(side_.size()))
    throw std::logic_error("ParticleBodyContacts::countCrossings: more triangles or particles than constructed for");
  const Index* ta = triangles.a.data();
  const Index* tb = triangles.b.data();
  const Index* tc = triangles.c.data();
  const S* X0[3] = {x0.data(), x0.data() + x0.rows(), x0.data() + 2 * x0.rows()};
  const S* X1[3] = {x1.data(), x1.data() + x1.rows(), x1.data() + 2 * x1.rows()};
  std::uint8_t* side = side_.data();
  std::uint8_t* flags = triangleFlags_.data();
  std::int64_t crossed = 0;
  *first = -1;
  // The box of every particle's path over the step (resolve's blocks): a body whose centre
  // stays outside it crosses nothing, and costs no pass over the particles.
  Vec3 clothLo = Vec3::Constant(std::numeric_limits<double>::infinity()), clothHi = -clothLo;
  for (Index k = 0; k < Executor::blockCount(n, kResolveBlock); ++k) {
    clothLo = clothLo.cwiseMin(pathLo_[static_cast<std::size_t>(k)]);
    clothHi = clothHi.cwiseMax(pathHi_[static_cast<std::size_t>(k)]);
  }
  for (Index body = 0; body < m.bodyCount(); ++body) {
    if (m.motion[body] == BodyMotion::Static) continue;
    const Vec3 p0 = before.x[body], p1 = after.x[body];
    const Vec3 lo = p0.cwiseMin(p1), hi = p0.cwiseMax(p1);
    if ((lo.array() > clothHi.array()).any() || (hi.array() < clothLo.array()).any()) continue;
    // The segment's box in S, rounded outwards (the test stays conservative in float).
    const auto down = [](double d) {
      const S r = static_cast<S>(d);
      return static_cast<double>(r) > d ? std::nextafter(r, -std::numeric_limits<S>::infinity()) : r;
    };
    const auto up = [](double d) {
      const S r = static_cast<S>(d);
      return static_cast<double>(r) < d ? std::nextafter(r, std::numeric_limits<S>::infinity()) : r;
    };
    const S lx = down(lo[0]), ly = down(lo[1]), lz = down(lo[2]);
    const S hx = up(hi[0]), hy = up(hi[1]), hz = up(hi[2]);
    // Where each particle's path lies against the centre's segment, axis by axis: bit 2c
    // wholly beyond it, bit 2c + 1 wholly short of it. A triangle whose corners share a bit
    // is apart from the segment over the whole step. (Not finite, the tests are all false
    // and the cubic's signs all agree: no crossing.)
    exec.parallelFor(n, kCrossingParticles, [&](Index begin, Index end) {
      const S* __restrict ax = X0[0];
      const S* __restrict ay = X0[1];
      const S* __restrict az = X0[2];
      const S* __restrict bx = X1[0];
      const S* __restrict by = X1[1];
      const S* __restrict bz = X1[2];
      // (Bounds copied in: the byte stores may alias anything, so captured ones would be
      // loaded again for every particle, and the loop would not vectorise.)
      const S lX = lx, lY = ly, lZ = lz, hX = hx, hY = hy, hZ = hz;
      std::uint8_t* __restrict out = side;
      for (Index i = begin; i < end; ++i)
        out[i] = static_cast<std::uint8_t>((ax[i] > hX && bx[i] > hX ? 1 : 0) | (ax[i] < lX && bx[i] < lX ? 2 : 0) |
                                           (ay[i] > hY && by[i] > hY ? 4 : 0) | (ay[i] < lY && by[i] < lY ? 8 : 0) |
                                           (az[i] > hZ && bz[i] > hZ ? 16 : 0) | (az[i] < lZ && bz[i] < lZ ? 32 : 0));
    });
    // Each block of triangles: the exact test on those whose corners share no bit.
    exec.parallelForBlocks(count, kCrossingTriangles, [&](Index block, Index begin, Index end) {
      const auto at = [](const S* const* X, Index i) {
        return Vec3(static_cast<double>(X[0][i]), static_cast<double>(X[1][i]), static_cast<double>(X[2][i]));
      };
      bool through = false;
      for (Index t = begin; t < end && !through; ++t)
        if ((side[ta[t]] & side[tb[t]] & side[tc[t]]) == 0)
          through = passesThrough(p0, p1, at(X0, ta[t]), at(X1, ta[t]), at(X0, tb[t]), at(X1, tb[t]), at(X0, tc[t]),
                                  at(X1, tc[t]));
      flags[block] = through ? 1 : 0;
    });
    bool through = false;
    for (Index k = 0; k < Executor::blockCount(count, kCrossingTriangles); ++k) through = through || flags[k] != 0;
    if (through) {  // one a body and step
      ++crossed;
      if (*first < 0) *first = body;
    }
  }
  return crossed;
}

template class ParticleBodyContacts<float>;
template class ParticleBodyContacts<double>;

}  // namespace weft
