#include "weft/rigid/rigid_world.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

namespace weft {

namespace {

constexpr double kWarmStartDistance = 0.01;  // m

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Quaterniond;

Vec3 toEigen(const Vec3d& v) { return {v.x, v.y, v.z}; }
Vec3d toVec3d(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

/// Rotation of a kinematic path at time t (what kinematicRotate does to a direction).
Mat3 pathRotation(const KinematicPath& path, double t) {
  Mat3 r;
  for (int c = 0; c < 3; ++c) {
    Vec3d e{c == 0 ? 1.0 : 0.0, c == 1 ? 1.0 : 0.0, c == 2 ? 1.0 : 0.0};
    r.col(c) = toEigen(kinematicRotate(path, e, t));
  }
  return r;
}

/// Orthonormal tangents of a unit normal, a fixed function of it (warm starting of
/// friction re-projects the stored world impulse, so the basis may change between steps).
void tangents(const Vec3& n, Vec3& t1, Vec3& t2) {
  if (std::abs(n.x()) >= 0.57735026918962576) {
    t1 = Vec3(n.y(), -n.x(), 0).normalized();
  } else {
    t1 = Vec3(0, n.z(), -n.y()).normalized();
  }
  t2 = n.cross(t1);
}

/// Rotation over h with the world angular momentum L held fixed (torque-free motion
/// between contact impulses): RK4 on dq/dt = 1/2 (0, w(q)) q with w(q) = R I^-1 R^T L.
Quat integrateRotation(const Quat& q0, const Vec3& L, const Mat3& invInertiaBody, double h) {
  const auto derivative = [&](const Eigen::Vector4d& c) -> Eigen::Vector4d {
    Quat q(c[3], c[0], c[1], c[2]);
    q.normalize();
    const Mat3 r = q.toRotationMatrix();
    const Vec3 w = r * (invInertiaBody * (r.transpose() * L));
    const Quat dq = Quat(0, w.x(), w.y(), w.z()) * q;
    return 0.5 * dq.coeffs();
  };
  const Eigen::Vector4d c0 = q0.coeffs();
  const Eigen::Vector4d k1 = derivative(c0);
  const Eigen::Vector4d k2 = derivative(c0 + 0.5 * h * k1);
  const Eigen::Vector4d k3 = derivative(c0 + 0.5 * h * k2);
  const Eigen::Vector4d k4 = derivative(c0 + h * k3);
  const Eigen::Vector4d c = c0 + (h / 6) * (k1 + 2 * k2 + 2 * k3 + k4);
  Quat q(c[3], c[0], c[1], c[2]);
  q.normalize();
  return q;
}

void sphereSphere(const Vec3& ca, double ra, const Vec3& cb, double rb, double margin, ContactManifold& out) {
  out.pointCount = 0;
  const Vec3 d = cb - ca;
  const double dist = d.norm();
  const double s = dist - ra - rb;
  if (s > margin) return;
  out.normal = dist > 1e-12 ? Vec3(d / dist) : Vec3::UnitY();
  out.pointCount = 1;
  out.points[0].position = ca + out.normal * (ra + 0.5 * s);
  out.points[0].separation = s;
  out.points[0].featureId = 0;
}

}  // namespace

RigidWorld::RigidWorld(const RigidOptions& options, const Eigen::Vector3d& gravity)
    : RigidWorld(buildRigidModel(options.bodies), options, gravity) {}

RigidWorld::RigidWorld(std::shared_ptr<const RigidModel> model, const RigidOptions& options,
                       const Eigen::Vector3d& gravity)
    : RigidWorld(model, model ? initialRigidState(*model, options.bodies) : RigidState{}, options, gravity) {}

RigidWorld::RigidWorld(std::shared_ptr<const RigidModel> model, RigidState initial, const RigidOptions& options,
                       const Eigen::Vector3d& gravity)
    : model_(std::move(model)), options_(options), gravity_(gravity) {
  if (!model_) throw std::invalid_argument("RigidWorld: model must not be null");
  RigidOptions check = options;
  check.bodies.clear();
  validateRigidOptions(check);
  if (!finite(gravity)) throw std::invalid_argument("RigidWorld: gravity must be finite (m/s^2)");
  const std::size_t n = model_->bodyCount();
  const std::size_t pieces = model_->pieceCount();
  rotation_.resize(n);
  pushV_.assign(n, Vec3::Zero());
  pushW_.assign(n, Vec3::Zero());
  invInertiaWorld_.resize(n);
  kinematicX0_.resize(n);
  kinematicQ0_.resize(n);
  targetX_.resize(n);
  targetQ_.resize(n);
  piecePose_.resize(pieces);
  boxMin_.resize(pieces);
  boxMax_.resize(pieces);
  sweepOrder_.resize(pieces);
  capacityPairs_ = options_.maxPairs > 0 ? options_.maxPairs : static_cast<Index>(16 * pieces + 64);
  const std::size_t cap = static_cast<std::size_t>(capacityPairs_);
  for (auto* v : {&pairs_, &lastPairs_}) v->reserve(cap);
  for (auto* v : {&caches_, &lastCaches_}) v->reserve(cap);
  manifolds_.reserve(cap);
  margins_.reserve(cap);
  outcomes_.reserve(cap);
  constraints_.reserve(4 * cap);
  lastConstraints_.reserve(4 * cap);
  pairFirstConstraint_.reserve(cap + 1);
  blocks_.reserve(cap);
  lastPairFirstConstraint_.reserve(cap + 1);
  lastPairFirstConstraint_.push_back(0);
  setState(initial);
}

void RigidWorld::setState(const RigidState& s) {
  const std::size_t n = model_->bodyCount();
  if (s.x.size() != n || s.q.size() != n || s.v.size() != n || s.w.size() != n)
    throw std::invalid_argument("RigidWorld::setState: the state has " + std::to_string(s.x.size()) +
                                " bodies, the model " + std::to_string(n));
  for (std::size_t b = 0; b < n; ++b) {
    if (!(finite(s.x[b]) && finite(s.v[b]) && finite(s.w[b]) && std::isfinite(s.q[b].norm())))
      throw std::invalid_argument("RigidWorld::setState: body " + std::to_string(b) + " is not finite");
  }
  state_ = s;
  for (auto& q : state_.q) q.normalize();
  backup_ = state_;
  // Kinematic bodies: where the path starts them (time 0), so that later positions are
  // computed from the path and never accumulate rounding.
  for (std::size_t b = 0; b < n; ++b) {
    if (model_->motion[b] != BodyMotion::Kinematic) continue;
    const KinematicPath& path = model_->paths[b];
    kinematicX0_[b] = toEigen(kinematicInverse(path, toVec3d(state_.x[b]), state_.time));
    kinematicQ0_[b] = Quat(pathRotation(path, state_.time).transpose() * state_.q[b].toRotationMatrix());
  }
  // A new state: nothing of the last contacts carries over.
  lastPairs_.clear();
  lastCaches_.clear();
  lastConstraints_.clear();
  lastPairFirstConstraint_.assign(1, 0);
}

Eigen::Vector3d RigidWorld::bodyOrigin(Index b) const {
  return state_.x[b] - state_.q[b].toRotationMatrix() * model_->centreOfMass[b];
}

double RigidWorld::energy() const {
  double e = 0;
  for (Index b = 0; b < model_->bodyCount(); ++b) {
    if (model_->motion[b] != BodyMotion::Dynamic) continue;
    const Mat3 r = state_.q[b].toRotationMatrix();
    const double m = model_->mass[b];
    e += 0.5 * m * state_.v[b].squaredNorm();
    e += 0.5 * state_.w[b].dot(r * model_->inertia[b] * r.transpose() * state_.w[b]);
    e -= m * gravity_.dot(state_.x[b]);
  }
  return e;
}

Eigen::Vector3d RigidWorld::angularMomentum(Index b) const {
  const Mat3 r = state_.q[b].toRotationMatrix();
  return r * model_->inertia[b] * r.transpose() * state_.w[b];
}

Pose RigidWorld::piecePose(Index p, const RigidState& s) const {
  const RigidPiece& piece = model_->pieces[p];
  const Mat3 r = s.q[piece.body].toRotationMatrix();
  Pose pose;
  pose.rotation = r * piece.rotation;
  pose.position = s.x[piece.body] + r * piece.offset;
  return pose;
}

void RigidWorld::applyImpulse(Index b, const Eigen::Vector3d& impulse, const Eigen::Vector3d& point) {
  if (model_->motion[b] != BodyMotion::Dynamic) return;
  const Mat3 r = state_.q[b].toRotationMatrix();
  state_.v[b] += model_->inverseMass[b] * impulse;
  state_.w[b] += r * model_->inverseInertia[b] * r.transpose() * (point - state_.x[b]).cross(impulse);
}

StepStatus RigidWorld::fail(StepCode code, Index body, double value) {
  StepStatus s;
  s.code = code;
  s.body = body;
  s.value = value;
  s.time = backup_.time;
  state_ = backup_;
  return s;
}

StepStatus RigidWorld::step(double h, const Executor& executor) {
  const RigidModel& m = *model_;
  const Index n = m.bodyCount();
  // Copy-assignment into equally sized vectors: no allocation after the first step.
  backup_.x = state_.x;
  backup_.q = state_.q;
  backup_.v = state_.v;
  backup_.w = state_.w;
  backup_.time = state_.time;
  last_ = RigidStats{};

  // 1. Velocities.
  for (Index b = 0; b < n; ++b) {
    switch (m.motion[b]) {
      case BodyMotion::Static:
        break;
      case BodyMotion::Dynamic:
        state_.v[b] += h * gravity_;
        break;
      case BodyMotion::Kinematic: {
        const KinematicPath& path = m.paths[b];
        const double t1 = state_.time + h;
        targetX_[b] = toEigen(kinematicPosition(path, toVec3d(kinematicX0_[b]), t1));
        const Mat3 r1 = pathRotation(path, t1) * kinematicQ0_[b].toRotationMatrix();
        targetQ_[b] = Quat(r1).normalized();
        state_.v[b] = (targetX_[b] - state_.x[b]) / h;
        const Eigen::AngleAxisd turn(r1 * state_.q[b].toRotationMatrix().transpose());
        state_.w[b] = turn.axis() * (turn.angle() / h);
        break;
      }
    }
    rotation_[b] = state_.q[b].toRotationMatrix();
    invInertiaWorld_[b] = rotation_[b] * m.inverseInertia[b] * rotation_[b].transpose();
  }

  // 2-3. Broad and narrow phase, on the velocities with the whole step's gravity (so the
  // swept bounds and margins cover where the bodies can get).
  bool overflow = false;
  Index nonFinite = -1;
  broadPhase(h, executor, overflow, nonFinite);
  if (nonFinite >= 0) return fail(StepCode::NonFinite, nonFinite, state_.x[nonFinite].sum());
  if (overflow) return fail(StepCode::CapacityExceeded, -1, static_cast<double>(capacityPairs_));
  narrowPhase(h, executor);

  // 4-5. Substeps (Box2D v3's soft step): the contact set of the step, each substep warm
  // started, solved, its penetration recovered by split impulses, positions integrated and
  // the separations advanced; then restitution.
  const int substeps = options_.substeps;
  const double hs = h / substeps;
  for (Index b = 0; b < n; ++b)
    if (m.motion[b] == BodyMotion::Dynamic) state_.v[b] = backup_.v[b];  // gravity comes per substep
  invStep_ = 1 / hs;
  buildConstraints(hs);
  for (int sub = 0; sub < substeps; ++sub) {
    for (Index b = 0; b < n; ++b)
      if (m.motion[b] == BodyMotion::Dynamic) state_.v[b] += hs * gravity_;
    warmStart();
    // Symmetric Gauss-Seidel: sweeps alternate in direction, so no contact point is always
    // solved first.
    for (int i = 0; i < options_.velocityIterations; ++i) solveVelocities(i % 2 == 1);
    solvePositions(hs);
    integratePositions(hs, sub == substeps - 1);
    advanceSeparations(hs);
  }
  lastSubstep_ = hs;
  applyRestitution();
  state_.time = backup_.time + h;

  for (Index b = 0; b < n; ++b) {
    if (m.motion[b] != BodyMotion::Dynamic) continue;
    if (!(finite(state_.x[b]) && finite(state_.v[b]) && finite(state_.w[b]) && std::isfinite(state_.q[b].w()))) {
      const double value = !finite(state_.x[b]) ? state_.x[b].sum() : state_.v[b].sum() + state_.w[b].sum();
      return fail(StepCode::NonFinite, b, value);
    }
  }

  // What this step found is what the next one starts from.
  std::swap(pairs_, lastPairs_);
  std::swap(caches_, lastCaches_);
  std::swap(constraints_, lastConstraints_);
  std::swap(pairFirstConstraint_, lastPairFirstConstraint_);
  total_.add(last_);
  return {};
}

void RigidWorld::broadPhase(double h, const Executor& executor, bool& overflow, Index& nonFinite) {
  const RigidModel& m = *model_;
  const Index pieces = m.pieceCount();
  const bool sweep = options_.continuous;
  const double grow = options_.speculativeDistance;
  executor.parallelFor(pieces, 64, [&](Index begin, Index end) {
    for (Index i = begin; i < end; ++i) {
      const RigidPiece& p = m.pieces[i];
      const Index b = p.body;
      Pose& pose = piecePose_[i];
      pose.rotation = rotation_[b] * p.rotation;
      pose.position = state_.x[b] + rotation_[b] * p.offset;
      // The piece's box in world axes: its own box rotated (|R| half extents).
      const Vec3 c = pose.position + pose.rotation * (0.5 * (p.localMin + p.localMax));
      const Vec3 half = pose.rotation.cwiseAbs() * (0.5 * (p.localMax - p.localMin));
      Vec3 lo = c - half, hi = c + half;
      double extra = grow;
      if (sweep) {
        // The extruded silhouette: the box swept along the step's translation, grown by
        // the furthest a point of the piece can travel through the rotation.
        const Vec3 d = h * state_.v[b];
        lo = lo.cwiseMin(lo + d);
        hi = hi.cwiseMax(hi + d);
        extra += h * state_.w[b].norm() * (p.centre.norm() + p.boundingRadius);
      }
      boxMin_[i] = lo.array() - extra;
      boxMax_[i] = hi.array() + extra;
    }
  });
  // A non-finite box (a body flung to infinity) would break the sort's ordering: stop here.
  for (Index i = 0; i < pieces; ++i) {
    if (!(boxMin_[i].allFinite() && boxMax_[i].allFinite())) {
      nonFinite = m.pieces[i].body;
      return;
    }
  }
  for (Index i = 0; i < pieces; ++i) sweepOrder_[i] = i;
  std::sort(sweepOrder_.begin(), sweepOrder_.end(), [&](Index a, Index b) {
    return boxMin_[a].x() < boxMin_[b].x() || (boxMin_[a].x() == boxMin_[b].x() && a < b);
  });
  pairs_.clear();
  for (Index ii = 0; ii < pieces; ++ii) {
    const Index i = sweepOrder_[ii];
    const Index bi = m.pieces[i].body;
    for (Index jj = ii + 1; jj < pieces; ++jj) {
      const Index j = sweepOrder_[jj];
      if (boxMin_[j].x() > boxMax_[i].x()) break;
      const Index bj = m.pieces[j].body;
      if (bi == bj) continue;
      if (m.motion[bi] != BodyMotion::Dynamic && m.motion[bj] != BodyMotion::Dynamic) continue;
      if (boxMin_[j].y() > boxMax_[i].y() || boxMin_[i].y() > boxMax_[j].y()) continue;
      if (boxMin_[j].z() > boxMax_[i].z() || boxMin_[i].z() > boxMax_[j].z()) continue;
      if (static_cast<Index>(pairs_.size()) == capacityPairs_) {
        overflow = true;
        return;
      }
      pairs_.push_back({std::min(i, j), std::max(i, j)});
    }
  }
  std::sort(pairs_.begin(), pairs_.end(), [](const Pair& a, const Pair& b) { return a.key() < b.key(); });
  last_.candidatePairs = static_cast<std::int64_t>(pairs_.size());
}

void RigidWorld::narrowPhase(double h, const Executor& executor) {
  const RigidModel& m = *model_;
  const Index count = static_cast<Index>(pairs_.size());
  manifolds_.resize(count);
  margins_.resize(count);
  outcomes_.resize(count);
  caches_.resize(count);
  executor.parallelFor(count, 16, [&](Index begin, Index end) {
    for (Index k = begin; k < end; ++k) {
      const Pair pair = pairs_[k];
      const RigidPiece& pa = m.pieces[pair.a];
      const RigidPiece& pb = m.pieces[pair.b];
      // The pair's cache from the last step, if it was a pair then.
      const std::uint64_t key = pair.key();
      const auto found = std::lower_bound(lastPairs_.begin(), lastPairs_.end(), key,
                                          [](const Pair& p, std::uint64_t kk) { return p.key() < kk; });
      if (found != lastPairs_.end() && found->key() == key) {
        caches_[k] = lastCaches_[found - lastPairs_.begin()];
      } else {
        caches_[k] = PairCache{};
      }
      double margin = options_.speculativeDistance;
      if (options_.continuous) {
        const Index a = pa.body, b = pb.body;
        margin +=
            h * ((state_.v[b] - state_.v[a]).norm() + state_.w[a].norm() * (pa.centre.norm() + pa.boundingRadius) +
                 state_.w[b].norm() * (pb.centre.norm() + pb.boundingRadius));
      }
      margins_[k] = margin;
      ContactManifold& out = manifolds_[k];
      const Pose& poseA = piecePose_[pair.a];
      const Pose& poseB = piecePose_[pair.b];
      outcomes_[k] = NarrowPhaseOutcome::FullQuery;
      using Kind = RigidShapeDesc::Kind;
      if (pa.kind == Kind::Sphere && pb.kind == Kind::Sphere) {
        sphereSphere(poseA.position, pa.radius, poseB.position, pb.radius, margin, out);
      } else if (pa.kind == Kind::Sphere) {
        collideSphereHull(poseA.position, pa.radius, m.hulls[pb.hull], poseB, margin, out);
      } else if (pb.kind == Kind::Sphere) {
        collideSphereHull(poseB.position, pb.radius, m.hulls[pa.hull], poseA, margin, out);
        out.normal = -out.normal;
      } else {
        outcomes_[k] = collideHulls(m.hulls[pa.hull], poseA, m.hulls[pb.hull], poseB, margin, options_.narrowPhase,
                                    caches_[k], out);
      }
    }
  });
  for (Index k = 0; k < count; ++k) {
    const bool hulls = m.pieces[pairs_[k].a].kind == RigidShapeDesc::Kind::Hull &&
                       m.pieces[pairs_[k].b].kind == RigidShapeDesc::Kind::Hull;
    if (hulls) {
      ++last_.narrowQueries;
      if (outcomes_[k] != NarrowPhaseOutcome::FullQuery) ++last_.witnessHits;
    }
    if (manifolds_[k].pointCount > 0) {
      ++last_.touchingPairs;
      last_.contacts += manifolds_[k].pointCount;
    }
  }
}

void RigidWorld::buildConstraints(double h) {
  const RigidModel& m = *model_;
  const Index count = static_cast<Index>(pairs_.size());
  constraints_.clear();
  pairFirstConstraint_.clear();
  for (Index k = 0; k < count; ++k) {
    pairFirstConstraint_.push_back(static_cast<Index>(constraints_.size()));
    const ContactManifold& man = manifolds_[k];
    if (man.pointCount == 0) continue;
    const Index a = m.pieces[pairs_[k].a].body;
    const Index b = m.pieces[pairs_[k].b].body;
    const std::uint64_t key = pairs_[k].key();
    // The same pair's points of the last step, for warm starting.
    const auto found = std::lower_bound(lastPairs_.begin(), lastPairs_.end(), key,
                                        [](const Pair& p, std::uint64_t kk) { return p.key() < kk; });
    Index lastBegin = 0, lastEnd = 0;
    if (found != lastPairs_.end() && found->key() == key) {
      const std::size_t li = static_cast<std::size_t>(found - lastPairs_.begin());
      lastBegin = lastPairFirstConstraint_[li];
      lastEnd = lastPairFirstConstraint_[li + 1];
    }
    const double muStatic = std::sqrt(m.staticFriction[a] * m.staticFriction[b]);
    const double muKinetic = std::sqrt(m.kineticFriction[a] * m.kineticFriction[b]);
    const double e = std::max(m.restitution[a], m.restitution[b]);
    const double ima = m.inverseMass[a], imb = m.inverseMass[b];
    const Mat3& iia = invInertiaWorld_[a];
    const Mat3& iib = invInertiaWorld_[b];
    for (int p = 0; p < man.pointCount; ++p) {
      const ContactPoint& cp = man.points[p];
      Constraint c;
      c.bodyA = a;
      c.bodyB = b;
      c.rA = cp.position - state_.x[a];
      c.rB = cp.position - state_.x[b];
      c.normal = man.normal;
      tangents(c.normal, c.tangent1, c.tangent2);
      const auto effectiveMass = [&](const Vec3& dir) {
        const Vec3 ra = c.rA.cross(dir), rb = c.rB.cross(dir);
        const double sum = ima + imb + ra.dot(iia * ra) + rb.dot(iib * rb);
        return sum > 0 ? 1 / sum : 0.0;
      };
      c.normalMass = effectiveMass(c.normal);
      c.tangentMass1 = effectiveMass(c.tangent1);
      c.tangentMass2 = effectiveMass(c.tangent2);
      c.inverseMassA = ima;
      c.inverseMassB = imb;
      for (int k = 0; k < 3; ++k) {
        c.crossA[k] = c.rA.cross(c.direction(k));
        c.crossB[k] = c.rB.cross(c.direction(k));
        c.angularA[k] = iia * c.crossA[k];
        c.angularB[k] = iib * c.crossB[k];
      }
      c.separation = cp.separation;
      c.previousSeparation = cp.separation;
      last_.maxPenetration = std::max(last_.maxPenetration, -cp.separation);
      const Vec3 dv = state_.v[b] + state_.w[b].cross(c.rB) - state_.v[a] - state_.w[a].cross(c.rA);
      c.approachVelocity = dv.dot(c.normal);
      const Vec3 slip = dv - c.approachVelocity * c.normal;
      c.friction = slip.norm() < options_.staticSpeed ? muStatic : muKinetic;
      c.restitution = e;
      c.pairKey = key;
      c.featureId = cp.featureId;
      // Warm start from the last step's point of this pair with the same feature id or,
      // when the features changed (ties between coincident edges flip them), the nearest
      // one in body A's frame within kWarmStartDistance (as Jolt matches by position).
      c.anchor = rotation_[a].transpose() * c.rA;
      Index match = -1;
      double nearest = kWarmStartDistance * kWarmStartDistance;
      for (Index l = lastBegin; l < lastEnd; ++l) {
        const Constraint& old = lastConstraints_[l];
        if (old.featureId == c.featureId) {
          match = l;
          break;
        }
        const double d2 = (old.anchor - c.anchor).squaredNorm();
        if (d2 < nearest) {
          nearest = d2;
          match = l;
        }
      }
      if (match >= 0) {
        // Impulses per substep: rescaled when the substep changed.
        const double scale = lastSubstep_ > 0 ? h / lastSubstep_ : 1.0;
        const Constraint& old = lastConstraints_[match];
        c.normalImpulse = scale * old.normalImpulse;
        const Vec3 friction = scale * (old.tangentImpulse1 * old.tangent1 + old.tangentImpulse2 * old.tangent2);
        c.tangentImpulse1 = friction.dot(c.tangent1);
        c.tangentImpulse2 = friction.dot(c.tangent2);
        ++last_.warmStarted;
      }
      constraints_.push_back(c);
    }
  }
  pairFirstConstraint_.push_back(static_cast<Index>(constraints_.size()));
  // One block per manifold: the (regularised) inverse of K_ij = n . (velocity change at
  // point i per unit normal impulse at point j). Points of one face are coplanar, so K has
  // rank 3 at most: the small ridge makes the answer the one of least impulse, spread
  // evenly over the points, as a body resting on four corners has.
  blocks_.clear();
  for (Index k = 0; k < count; ++k) {
    const Index first = pairFirstConstraint_[k], end = pairFirstConstraint_[k + 1];
    if (end == first) continue;
    Block block;
    block.first = first;
    block.count = static_cast<int>(end - first);
    if (block.count > 1) {
      const Constraint* c = constraints_.data() + first;
      const Index a = c[0].bodyA, b = c[0].bodyB;
      const double im = m.inverseMass[a] + m.inverseMass[b];
      Eigen::Matrix4d K = Eigen::Matrix4d::Identity();
      for (int i = 0; i < block.count; ++i) {
        const Vec3 ai = c[i].rA.cross(c[i].normal), bi = c[i].rB.cross(c[i].normal);
        for (int j = 0; j < block.count; ++j) {
          const Vec3 aj = c[j].rA.cross(c[j].normal), bj = c[j].rB.cross(c[j].normal);
          K(i, j) =
              im * c[i].normal.dot(c[j].normal) + ai.dot(invInertiaWorld_[a] * aj) + bi.dot(invInertiaWorld_[b] * bj);
        }
      }
      const double ridge = 1e-6 * K.diagonal().head(block.count).maxCoeff();
      for (int i = 0; i < block.count; ++i) K(i, i) += ridge;
      block.inverse = Eigen::Matrix4d::Zero();
      if (block.count == 4) {
        block.inverse = K.inverse();
      } else if (block.count == 3) {
        block.inverse.topLeftCorner<3, 3>() = K.topLeftCorner<3, 3>().inverse();
      } else {
        block.inverse.topLeftCorner<2, 2>() = K.topLeftCorner<2, 2>().inverse();
      }
    }
    blocks_.push_back(block);
  }
  (void)h;
}

void RigidWorld::warmStart() {
  const RigidModel& m = *model_;
  for (Constraint& c : constraints_) {
    // An impulse found while the point was still apart at the start of its substep is an
    // impact (a speculative contact closing): it stopped the approach once and must not
    // be applied again (it would throw the body back). Only resting contact carries over.
    const bool impact = c.previousSeparation > options_.linearSlop;
    c.previousSeparation = c.separation;
    if (impact) {
      c.normalImpulse = c.tangentImpulse1 = c.tangentImpulse2 = 0;
      continue;
    }
    apply(c, 0, c.normalImpulse);
    apply(c, 1, c.tangentImpulse1);
    apply(c, 2, c.tangentImpulse2);
  }
}

void RigidWorld::advanceSeparations(double hs) {
  // The points moved with the bodies' velocities (real and split) over the substep.
  for (Constraint& c : constraints_) {
    const Index a = c.bodyA, b = c.bodyB;
    const Vec3 va = state_.v[a] + pushV_[a] + (state_.w[a] + pushW_[a]).cross(c.rA);
    const Vec3 vb = state_.v[b] + pushV_[b] + (state_.w[b] + pushW_[b]).cross(c.rB);
    c.separation += hs * (vb - va).dot(c.normal);
  }
}

double RigidWorld::relativeVelocity(const Constraint& c, int k) const {
  return c.direction(k).dot(state_.v[c.bodyB] - state_.v[c.bodyA]) + c.crossB[k].dot(state_.w[c.bodyB]) -
         c.crossA[k].dot(state_.w[c.bodyA]);
}

void RigidWorld::apply(const Constraint& c, int k, double lambda) {
  const Vec3& d = c.direction(k);
  state_.v[c.bodyA] -= (c.inverseMassA * lambda) * d;
  state_.w[c.bodyA] -= lambda * c.angularA[k];
  state_.v[c.bodyB] += (c.inverseMassB * lambda) * d;
  state_.w[c.bodyB] += lambda * c.angularB[k];
}

void RigidWorld::solveFriction(Constraint& c) {
  const double limit = c.friction * c.normalImpulse;
  double l1 = c.tangentImpulse1 - c.tangentMass1 * relativeVelocity(c, 1);
  double l2 = c.tangentImpulse2 - c.tangentMass2 * relativeVelocity(c, 2);
  const double len = std::sqrt(l1 * l1 + l2 * l2);
  if (len > limit) {  // Coulomb's cone
    const double scale = len > 0 ? limit / len : 0;
    l1 *= scale;
    l2 *= scale;
  }
  apply(c, 1, l1 - c.tangentImpulse1);
  apply(c, 2, l2 - c.tangentImpulse2);
  c.tangentImpulse1 = l1;
  c.tangentImpulse2 = l2;
}

void RigidWorld::solveNormal(Constraint& c) {
  // A speculative point (s > 0) lets the gap close within the substep and no more.
  const double allowed = c.separation > 0 ? c.separation * invStep_ : 0.0;
  const double total = std::max(c.normalImpulse - c.normalMass * (relativeVelocity(c, 0) + allowed), 0.0);
  apply(c, 0, total - c.normalImpulse);
  c.normalImpulse = total;
  c.maxNormalImpulse = std::max(c.maxNormalImpulse, total);
}

void RigidWorld::solveVelocities(bool backward) {
  const std::size_t count = blocks_.size();
  for (std::size_t k = 0; k < count; ++k) {
    const Block& block = blocks_[backward ? count - 1 - k : k];
    Constraint* c = constraints_.data() + block.first;
    // Friction first, the normal last (non-penetration matters most).
    if (block.count == 1) {
      solveFriction(c[0]);
      solveNormal(c[0]);
      continue;
    }
    // Friction symmetrically: each point's tangential impulse from the same velocities
    // (Jacobi within the manifold, each point taking its share), so no corner is served
    // first and a symmetric stack stays symmetric.
    {
      std::array<double, 8> slip;
      for (int p = 0; p < block.count; ++p) {
        slip[2 * p] = relativeVelocity(c[p], 1);
        slip[2 * p + 1] = relativeVelocity(c[p], 2);
      }
      const double share = 1.0 / block.count;
      for (int p = 0; p < block.count; ++p) {
        Constraint& q = c[p];
        const double limit = q.friction * q.normalImpulse;
        double l1 = q.tangentImpulse1 - share * q.tangentMass1 * slip[2 * p];
        double l2 = q.tangentImpulse2 - share * q.tangentMass2 * slip[2 * p + 1];
        const double len = std::sqrt(l1 * l1 + l2 * l2);
        if (len > limit) {
          const double scale = len > 0 ? limit / len : 0;
          l1 *= scale;
          l2 *= scale;
        }
        apply(q, 1, l1 - q.tangentImpulse1);
        apply(q, 2, l2 - q.tangentImpulse2);
        q.tangentImpulse1 = l1;
        q.tangentImpulse2 = l2;
      }
    }
    // The manifold's normal impulses together (the block solver Box2D v2 uses for two
    // points, here for up to four): the increments that bring every point to its target
    // normal velocity at once, through the inverse of the points' coupling matrix K. A
    // point-by-point sweep would let the first point take the whole load and spin the
    // body; the block answer is symmetric. When it would pull (a total below zero), the
    // points are solved one by one instead.
    Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
    for (int p = 0; p < block.count; ++p) {
      const double allowed = c[p].separation > 0 ? c[p].separation * invStep_ : 0.0;
      rhs[p] = -(relativeVelocity(c[p], 0) + allowed);
    }
    const Eigen::Vector4d x = block.inverse * rhs;
    bool valid = true;
    for (int p = 0; p < block.count; ++p) valid = valid && c[p].normalImpulse + x[p] >= 0;
    if (!valid) {
      for (int p = 0; p < block.count; ++p) solveNormal(c[p]);
      continue;
    }
    for (int p = 0; p < block.count; ++p) {
      c[p].normalImpulse += x[p];
      c[p].maxNormalImpulse = std::max(c[p].maxNormalImpulse, c[p].normalImpulse);
      apply(c[p], 0, x[p]);
    }
  }
}

void RigidWorld::solvePositions(double h) {
  // Split impulses (Catto; Bullet's splitImpulse): penetration is recovered through
  // velocities that move the positions of this step only and are then forgotten, so
  // pushing bodies apart never leaves energy in them (a stack does not hop or rock).
  const RigidModel& m = *model_;
  const Index n = m.bodyCount();
  for (Index b = 0; b < n; ++b) {
    pushV_[b].setZero();
    pushW_[b].setZero();
  }
  for (int it = 0; it < options_.positionIterations; ++it) {
    for (Constraint& c : constraints_) {
      const double depth = -(c.separation + options_.linearSlop);
      if (depth <= 0) continue;
      const Index a = c.bodyA, b = c.bodyB;
      const Vec3 dv = pushV_[b] + pushW_[b].cross(c.rB) - pushV_[a] - pushW_[a].cross(c.rA);
      const double target = std::min(options_.penetrationRate * depth / h, options_.maxPushVelocity);
      const double lambda = -c.normalMass * (dv.dot(c.normal) - target);
      const double total = std::max(c.pushImpulse + lambda, 0.0);
      const Vec3 impulse = (total - c.pushImpulse) * c.normal;
      c.pushImpulse = total;
      pushV_[a] -= m.inverseMass[a] * impulse;
      pushW_[a] -= invInertiaWorld_[a] * c.rA.cross(impulse);
      pushV_[b] += m.inverseMass[b] * impulse;
      pushW_[b] += invInertiaWorld_[b] * c.rB.cross(impulse);
    }
  }
}

void RigidWorld::integratePositions(double h, bool last) {
  const RigidModel& m = *model_;
  for (Index b = 0; b < m.bodyCount(); ++b) {
    switch (m.motion[b]) {
      case BodyMotion::Static:
        break;
      case BodyMotion::Kinematic:
        if (last) {  // exactly on the path at the end of the step
          state_.x[b] = targetX_[b];
          state_.q[b] = targetQ_[b];
        } else {
          state_.x[b] += h * state_.v[b];
          const double turn = h * state_.w[b].norm();
          if (turn > 0)
            state_.q[b] = (Quat(Eigen::AngleAxisd(turn, state_.w[b] / state_.w[b].norm())) * state_.q[b]).normalized();
        }
        rotation_[b] = state_.q[b].toRotationMatrix();
        break;
      case BodyMotion::Dynamic: {
        state_.x[b] += h * (state_.v[b] + pushV_[b]);
        // Torque-free rotation with the world angular momentum fixed over the step, then
        // the split-impulse turn (positions only).
        const Vec3 L = rotation_[b] * m.inertia[b] * rotation_[b].transpose() * state_.w[b];
        state_.q[b] = integrateRotation(state_.q[b], L, m.inverseInertia[b], h);
        const double turn = h * pushW_[b].norm();
        if (turn > 0)
          state_.q[b] = (Quat(Eigen::AngleAxisd(turn, pushW_[b] / pushW_[b].norm())) * state_.q[b]).normalized();
        const Mat3 r = state_.q[b].toRotationMatrix();
        rotation_[b] = r;
        invInertiaWorld_[b] = r * m.inverseInertia[b] * r.transpose();
        state_.w[b] = invInertiaWorld_[b] * L;
        break;
      }
    }
  }
}

void RigidWorld::applyRestitution() {
  const RigidModel& m = *model_;
  for (Constraint& c : constraints_) {
    if (c.restitution == 0 || c.approachVelocity > -options_.restitutionThreshold || c.maxNormalImpulse == 0) continue;
    const Index a = c.bodyA, b = c.bodyB;
    const Vec3 dv = state_.v[b] + state_.w[b].cross(c.rB) - state_.v[a] - state_.w[a].cross(c.rA);
    const double vn = dv.dot(c.normal);
    const double lambda = -c.normalMass * (vn + c.restitution * c.approachVelocity);
    const double total = std::max(c.normalImpulse + lambda, 0.0);
    const Vec3 impulse = (total - c.normalImpulse) * c.normal;
    c.normalImpulse = total;
    state_.v[a] -= m.inverseMass[a] * impulse;
    state_.w[a] -= invInertiaWorld_[a] * c.rA.cross(impulse);
    state_.v[b] += m.inverseMass[b] * impulse;
    state_.w[b] += invInertiaWorld_[b] * c.rB.cross(impulse);
  }
}

}  // namespace weft
