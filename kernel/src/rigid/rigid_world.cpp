#include "weft/rigid/rigid_world.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/text.hpp"
#include "rigid_rules.hpp"

namespace weft {

namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Quaterniond;

Vec3 toEigen(const Vec3d& v) { return {v.x, v.y, v.z}; }
Vec3d toVec3d(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

/// Throws std::invalid_argument unless 0 <= k < count ("<where>: <what> k is outside [0, count)").
void requireIndex(Index k, Index count, const char* where, const char* what) {
  if (k < 0 || k >= count)
    throw std::invalid_argument(std::string(where) + ": " + what + " " + std::to_string(k) + " is outside [0, " +
                                std::to_string(count) + ")");
}

/// Whether q can be normalised to a rotation: finite and not (nearly) zero (the rule
/// validateRigidOptions applies to a body's orientation).
bool rotationQuaternion(const Quat& q) {
  const double norm = q.norm();
  return std::isfinite(norm) && norm > 1e-12;
}

/// Rotation of a kinematic path at time t (what kinematicRotate does to a direction).
Mat3 pathRotation(const KinematicPath& path, double t) {
  Mat3 r;
  for (int c = 0; c < 3; ++c) {
    Vec3d e{c == 0 ? 1.0 : 0.0, c == 1 ? 1.0 : 0.0, c == 2 ? 1.0 : 0.0};
    r.col(c) = toEigen(kinematicRotate(path, e, t));
  }
  return r;
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
  if (!finite(gravity)) detail::rejectField("RigidWorld: gravity", detail::number3(gravity), "finite (m/s^2)");
  const std::size_t n = model_->bodyCount();
  const std::size_t pieces = model_->pieceCount();
  rotation_.resize(n);
  pushV_.assign(n, Vec3::Zero());
  pushW_.assign(n, Vec3::Zero());
  invInertiaWorld_.resize(n);
  kinematicX0_.assign(n, Eigen::Vector3d::Zero());  // (zero for the other bodies: checkpoints hold no garbage)
  kinematicQ0_.assign(n, Eigen::Quaterniond::Identity());
  targetX_.resize(n);
  targetQ_.resize(n);
  piecePose_.resize(pieces);
  boxMin_.resize(pieces);
  boxMax_.resize(pieces);
  sweepOrder_.resize(pieces);
  capacityPairs_ = options_.maxPairs > 0 ? options_.maxPairs : static_cast<Index>(16 * pieces + 64);
  const std::size_t cap = static_cast<std::size_t>(capacityPairs_);
  try {
    reservePairs(cap);
  } catch (const std::bad_alloc&) {
    const double bytes =
        static_cast<double>(cap) * (2 * sizeof(Pair) + 2 * sizeof(PairCache) + sizeof(ContactManifold) +
                                    4 * (sizeof(Constraint) + sizeof(WarmPoint)) + sizeof(Block));
    throw std::invalid_argument("RigidWorld: rigid.maxPairs = " + std::to_string(options_.maxPairs) + " (" +
                                std::to_string(cap) + " pairs) needs about " +
                                detail::number(std::round(10 * bytes / (1 << 30)) / 10) +
                                " GiB of contact buffers, more than this machine could allocate");
  }
  bodyColours_.resize(n);
  colourStart_.reserve(kColours + 2);
  colourCount_.reserve(kColours + 1);
  lastPairFirstConstraint_.push_back(0);
  setState(initial);
}

void RigidWorld::reservePairs(std::size_t cap) {
  for (auto* v : {&pairs_, &lastPairs_}) v->reserve(cap);
  for (auto* v : {&caches_, &lastCaches_}) v->reserve(cap);
  manifolds_.reserve(cap);
  if (chunked()) endDepth_.reserve(cap);
  margins_.reserve(cap);
  outcomes_.reserve(cap);
  constraints_.reserve(4 * cap);
  lastPoints_.reserve(4 * cap);
  pairFirstConstraint_.reserve(cap + 1);
  blocks_.reserve(cap);
  colourOrder_.reserve(cap);
  lastPairFirstConstraint_.reserve(cap + 1);
}

void RigidWorld::setState(const RigidState& s) {
  const std::size_t n = model_->bodyCount();
  if (s.x.size() != n || s.q.size() != n || s.v.size() != n || s.w.size() != n)
    throw std::invalid_argument("RigidWorld::setState: the state has " + std::to_string(s.x.size()) +
                                " bodies, the model " + std::to_string(n));
  for (std::size_t b = 0; b < n; ++b) {
    if (!(finite(s.x[b]) && finite(s.v[b]) && finite(s.w[b]) && std::isfinite(s.q[b].norm())))
      throw std::invalid_argument("RigidWorld::setState: body " + std::to_string(b) + " is not finite");
    // The field's name, built only for a message (piece by piece: a chain of operator+ trips
    // GCC 12's -Wrestrict).
    const auto field = [b](const char* what) {
      std::string f = "RigidWorld::setState: state.";
      f += what;
      f += "[";
      f += std::to_string(b);
      f += "]";
      return f;
    };
    if (s.x[b].cwiseAbs().maxCoeff() > kFarthestBody)
      detail::rejectField(field("x"), detail::number3(s.x[b]), detail::farthestBodyRule());
    if (!detail::speedWithinLimit(s.v[b].x(), s.v[b].y(), s.v[b].z()))
      detail::rejectField(field("v"), detail::number3(s.v[b]), detail::speedRule());
    if (model_->motion[b] == BodyMotion::Dynamic && !detail::spinWithinLimit(s.w[b], model_->reach[b]))
      detail::rejectField(field("w"), detail::number3(s.w[b]), detail::spinRule(model_->reach[b]));
    if (!rotationQuaternion(s.q[b]))
      detail::rejectField("RigidWorld::setState: state.q[" + std::to_string(b) + "]",
                          "norm " + detail::number(s.q[b].norm()), "a finite non-zero quaternion (norm > 1e-12)");
  }
  if (!std::isfinite(s.time)) detail::rejectField("RigidWorld::setState: state.time", s.time, "finite (s)");
  state_ = s;
  for (auto& q : state_.q) q.normalize();
  backup_ = state_;
  stepBegin_ = state_;
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
  lastPoints_.clear();
  lastPairFirstConstraint_.assign(1, 0);
  lastSupports_.clear();
  supportInput_.clear();
}

template <class Archive, class Self>
void RigidWorld::transfer(Archive& a, Self& self) {
  a.field(self.state_.x, "rigid body positions");
  a.field(self.state_.q, "rigid body orientations");
  a.field(self.state_.v, "rigid body velocities");
  a.field(self.state_.w, "rigid body angular velocities");
  a.field(self.state_.time, "rigid time");
  a.field(self.kinematicX0_, "kinematic origins");
  a.field(self.kinematicQ0_, "kinematic orientations");
  a.field(self.lastPairs_, "rigid pairs");
  a.field(self.lastCaches_, "rigid witness caches");
  a.field(self.lastPoints_, "rigid contact points");
  a.field(self.lastPairFirstConstraint_, "rigid pair constraints");
  a.field(self.lastSupports_, "rigid support contacts");
  a.field(self.lastSubstep_, "the last substep");
  a.field(self.last_, "the last step's statistics");
  a.field(self.total_, "the run's statistics");
}

void RigidWorld::saveCarry(ArchiveWriter& out) const {
  out.section("RIGD");
  transfer(out, *this);
}

void RigidWorld::loadCarry(ArchiveReader& in) {
  in.section("RIGD");
  transfer(in, *this);
  // Sizes and indices the next step follows: in range and in order, or the file is refused
  // (Simulation::restore then puts the world back as it was).
  const RigidState& s = state_;
  const std::size_t n = model_->bodyCount();
  if (s.x.size() != n || s.q.size() != n || s.v.size() != n || s.w.size() != n || kinematicX0_.size() != n ||
      kinematicQ0_.size() != n)
    in.fail("the file has " + std::to_string(s.x.size()) + " rigid bodies, this simulation " + std::to_string(n));
  for (std::size_t b = 0; b < n; ++b)
    if (!(finite(s.x[b]) && finite(s.v[b]) && finite(s.w[b]) && rotationQuaternion(s.q[b])) ||
        (model_->motion[b] == BodyMotion::Kinematic &&
         !(finite(kinematicX0_[b]) && rotationQuaternion(kinematicQ0_[b]))))
      in.fail("rigid body " + std::to_string(b) + " is not finite (or has a zero orientation)");
  if (!std::isfinite(s.time)) in.fail("the rigid time is not finite");
  const Index pieces = model_->pieceCount();
  for (std::size_t k = 0; k < lastPairs_.size(); ++k) {
    const Pair& p = lastPairs_[k];
    if (!(p.a >= 0 && p.a < p.b && p.b < pieces) || (k > 0 && !(lastPairs_[k - 1].key() < p.key())))
      in.fail("rigid pair " + std::to_string(k) + " (" + std::to_string(p.a) + ", " + std::to_string(p.b) +
              ") is not a sorted pair of the model's " + std::to_string(pieces) + " pieces");
  }
  if (lastCaches_.size() != lastPairs_.size())
    in.fail(std::to_string(lastCaches_.size()) + " witness caches for " + std::to_string(lastPairs_.size()) + " pairs");
  for (const PairCache& c : lastCaches_) in.checkFlag(c, offsetof(PairCache, touching), "a witness cache");
  const std::vector<Index>& first = lastPairFirstConstraint_;
  bool csr = first.size() == lastPairs_.size() + 1 && first.front() == 0 &&
             first.back() == static_cast<Index>(lastPoints_.size());
  for (std::size_t k = 1; csr && k < first.size(); ++k) csr = first[k - 1] <= first[k];
  if (!csr) in.fail("the rigid pairs' constraint ranges do not cover the constraints in order");
  if (!(std::isfinite(lastSubstep_) && lastSubstep_ >= 0)) in.fail("the last substep is not >= 0");
  backup_ = state_;
  stepBegin_ = state_;
  supportInput_.clear();
}

void RigidWorld::reserveSupports(Index capacity) {
  const std::size_t c = static_cast<std::size_t>(std::max<Index>(capacity, 0));
  supportInput_.reserve(c);
  supports_.reserve(c);
  lastSupports_.reserve(c);
}

void RigidWorld::setSupports(const SupportContact* contacts, Index count) {
  if (count < 0 || static_cast<std::size_t>(count) > supportInput_.capacity())
    throw std::invalid_argument("RigidWorld::setSupports: " + std::to_string(count) + " support contacts, room for " +
                                std::to_string(supportInput_.capacity()) + " (reserveSupports)");
  for (Index k = 0; k < count; ++k) {
    const SupportContact& c = contacts[k];
    if (c.body < 0 || c.body >= model_->bodyCount() || model_->motion[c.body] != BodyMotion::Dynamic)
      throw std::invalid_argument("RigidWorld::setSupports: contact " + std::to_string(k) + " names body " +
                                  std::to_string(c.body) + ", not a dynamic body");
    if (k > 0 && contacts[k - 1].key >= c.key)
      throw std::invalid_argument("RigidWorld::setSupports: keys must increase (contact " + std::to_string(k) + ")");
  }
  supportInput_.assign(contacts, contacts + count);  // within the capacity: no allocation
}

Eigen::Vector3d RigidWorld::bodyOrigin(Index b) const {
  requireIndex(b, model_->bodyCount(), "RigidWorld::bodyOrigin", "body");
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
  requireIndex(b, model_->bodyCount(), "RigidWorld::angularMomentum", "body");
  const Mat3 r = state_.q[b].toRotationMatrix();
  return r * model_->inertia[b] * r.transpose() * state_.w[b];
}

Pose RigidWorld::piecePose(Index p, const RigidState& s) const {
  requireIndex(p, model_->pieceCount(), "RigidWorld::piecePose", "piece");
  const RigidPiece& piece = model_->pieces[p];
  const Mat3 r = s.q[piece.body].toRotationMatrix();
  Pose pose;
  pose.rotation = r * piece.rotation;
  pose.position = s.x[piece.body] + r * piece.offset;
  return pose;
}

void RigidWorld::applyImpulse(Index b, const Eigen::Vector3d& impulse, const Eigen::Vector3d& point) {
  requireIndex(b, model_->bodyCount(), "RigidWorld::applyImpulse", "body");
  if (!finite(impulse))
    detail::rejectField("RigidWorld::applyImpulse: impulse", detail::number3(impulse), "finite (N s)");
  if (!finite(point)) detail::rejectField("RigidWorld::applyImpulse: point", detail::number3(point), "finite (m)");
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
  s.time = stepStart().time;
  state_ = stepStart();
  supportInput_.clear();
  return s;
}

namespace {
/// Copy-assignment into equally sized vectors: no allocation after the first time.
void copyState(const RigidState& from, RigidState& to) {
  to.x = from.x;
  to.q = from.q;
  to.v = from.v;
  to.w = from.w;
  to.time = from.time;
}
}  // namespace

StepStatus RigidWorld::step(double h, const Executor& executor) {
  if (!(std::isfinite(h) && h > 0)) detail::rejectField("RigidWorld::step: h", h, "finite and > 0 (s)");
  if (!chunked()) {
    double shorter = 0;
    const StepStatus s = stepChunk(h, executor, true, shorter);
    supportInput_.clear();  // supports hold for one step
    if (!s.ok()) return s;
    last_.chunks = 1;
    total_.add(last_);
    return s;
  }
  return stepInChunks(h, executor);
}

StepStatus RigidWorld::stepInChunks(double h, const Executor& executor) {
  double shorter = 0;
  // The original design's loop: chunks of the step, each cut before it is taken while a
  // pair apart could meet too deep within it, or taken back after it ended too deep; the
  // next chunk may be twice as long again. Chunk lengths are h / 2^k, so they add up to h.
  // Speculative contacts with redoDeepSteps take the same loop with no cut before a chunk
  // and a deeper limit after it (kDeepShare of the thinner piece): the whole step is one
  // chunk unless it let bodies into each other.
  // Bodies that start (or are pushed) deeper into each other than the limit end chunk
  // after chunk too deep however short it is: rollback has no hold on them, and the loop
  // could take up to 2^maxHalvings chunks, each twice. After 16 (maxHalvings + 1) chunks
  // taken or taken back in a step (a landing pile takes about 4), the rest of the step is
  // taken without rollback (chunks still doubling), so a step costs at most about
  // 17 (maxHalvings + 1) chunks.
  const std::int64_t budget = 16 * (options_.maxHalvings + 1);
  std::int64_t attempts = 0;
  copyState(state_, stepBegin_);
  RigidStats step;
  const double shortest = std::ldexp(h, -options_.maxHalvings);
  double done = 0, chunk = h;
  while (done < h) {
    const double length = std::min(chunk, h - done);
    const bool spent = attempts++ >= budget;
    const bool force = length <= shortest || spent;
    const StepStatus s = stepChunk(length, executor, force, shorter);
    if (!s.ok()) {
      supportInput_.clear();
      return s;  // the state is where the step started
    }
    if (shorter > 0 && !force) {
      ++step.rollbacks;
      chunk = length / 2;
      while (chunk > shorter && chunk > shortest) chunk /= 2;
      chunk = std::max(chunk, shortest);
      continue;
    }
    if (shorter > 0) ++last_.halvingLimitHits;
    ++last_.chunks;
    const std::int64_t rollbacks = step.rollbacks;
    step.add(last_);
    step.rollbacks = rollbacks;
    done += length;
    chunk = std::min(h, 2 * length);
  }
  state_.time = stepBegin_.time + h;
  supportInput_.clear();
  if (!rollback() && step.chunks > 1) step.redoneSteps = 1;
  last_ = step;
  total_.add(last_);
  return {};
}

StepStatus RigidWorld::stepChunk(double h, const Executor& executor, bool force, double& shorter) {
  const RigidModel& m = *model_;
  const Index n = m.bodyCount();
  shorter = 0;
  copyState(state_, backup_);
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
  if (rollback()) {
    // The time of impact: a pair apart (its nearest point beyond the slop) closes by at
    // most its motion bound over the chunk (the margin's growth); the chunk may be as long
    // as lets the nearest such pair end no deeper than rollbackPenetration.
    double longest = h;
    for (std::size_t k = 0; k < manifolds_.size(); ++k) {
      const ContactManifold& man = manifolds_[k];
      if (man.pointCount == 0) continue;
      double nearest = man.points[0].separation;
      for (int p = 1; p < man.pointCount; ++p) nearest = std::min(nearest, man.points[p].separation);
      const double rate = (margins_[k] - options_.speculativeDistance) / h;  // m/s
      if (nearest <= options_.linearSlop || rate <= 0) continue;
      longest = std::min(longest, (nearest + options_.rollbackPenetration) / rate);
    }
    if (longest < h) {
      shorter = longest;
      if (!force) {
        state_ = backup_;
        return {};
      }
    }
  }

  // 4-5. Substeps (Box2D v3's soft step): the contact set of the step, each substep warm
  // started, solved, its penetration recovered by split impulses, positions integrated and
  // the separations advanced; then restitution.
  const int substeps = options_.substeps;
  const double hs = h / substeps;
  for (Index b = 0; b < n; ++b)
    if (m.motion[b] == BodyMotion::Dynamic) state_.v[b] = backup_.v[b];  // gravity comes per substep
  invStep_ = 1 / hs;
  buildConstraints(hs);
  buildSupports(hs);
  for (int sub = 0; sub < substeps; ++sub) {
    for (Index b = 0; b < n; ++b)
      if (m.motion[b] == BodyMotion::Dynamic) state_.v[b] += hs * gravity_;
    warmStart(executor);
    // Symmetric Gauss-Seidel: sweeps alternate in direction, so no contact point is always
    // solved first.
    for (int i = 0; i < options_.velocityIterations; ++i) {
      solveVelocities(i % 2 == 1, executor);
      solveSupports(i % 2 == 1);
    }
    solvePositions(hs, executor);
    integratePositions(hs, sub == substeps - 1, executor);
    advanceSeparations(hs, executor);
  }
  applyRestitution();
  if (!rollback() && !force && endsTooDeep(executor, true)) {
    // A speculative chunk that let bodies into each other (redoDeepSteps): taken back, halved.
    shorter = h / 2;
    state_ = backup_;
    return {};
  }
  if (rollback()) {
    // Taken back when a pair ended deeper than the limit and than it started.
    if (endsTooDeep(executor, false)) {
      shorter = h / 2;
      if (!force) {
        state_ = backup_;
        return {};
      }
    }
  }
  lastSubstep_ = hs;
  state_.time = backup_.time + h;

  for (Index b = 0; b < n; ++b) {
    if (m.motion[b] != BodyMotion::Dynamic) continue;
    if (!(finite(state_.x[b]) && finite(state_.v[b]) && finite(state_.w[b]) && std::isfinite(state_.q[b].w()))) {
      const double value = !finite(state_.x[b]) ? state_.x[b].sum() : state_.v[b].sum() + state_.w[b].sum();
      return fail(StepCode::NonFinite, b, value);
    }
    // Finite speeds whose kinetic energy is not (m |v|^2 + |w|^2 tr I bounds twice it): the
    // energy and the next step's impulses would overflow.
    const double twiceEnergyBound =
        m.mass[b] * state_.v[b].squaredNorm() + state_.w[b].squaredNorm() * m.inertia[b].trace();
    if (!std::isfinite(twiceEnergyBound)) return fail(StepCode::NonFinite, b, twiceEnergyBound);
  }

  // What this step found is what the next one starts from.
  std::swap(pairs_, lastPairs_);
  std::swap(caches_, lastCaches_);
  lastPoints_.clear();
  for (const Constraint& c : constraints_)
    lastPoints_.push_back(
        {c.anchor, c.normalImpulse, c.tangentImpulse1 * c.tangent1 + c.tangentImpulse2 * c.tangent2, c.featureId, 0});
  std::swap(pairFirstConstraint_, lastPairFirstConstraint_);
  std::swap(supports_, lastSupports_);
  return {};
}

void RigidWorld::broadPhase(double h, const Executor& executor, bool& overflow, Index& nonFinite) {
  const RigidModel& m = *model_;
  const Index pieces = m.pieceCount();
  const bool sweep = options_.continuous || rollback();
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

bool RigidWorld::endsTooDeep(const Executor& executor, bool share) {
  // The narrow phase again at the end of the chunk (a copy of each pair's cache: the
  // witness answers as the exact test does, cheaply for pairs that moved little); a
  // rotating body can meet another with a point its start manifold did not hold.
  const RigidModel& m = *model_;
  const Index count = static_cast<Index>(pairs_.size());
  endDepth_.resize(static_cast<std::size_t>(count));  // within the reserved capacity
  const auto limit = [&](Index k) {
    return share
               ? RigidStats::kDeepShare * std::min(m.pieces[pairs_[k].a].innerRadius, m.pieces[pairs_[k].b].innerRadius)
               : options_.rollbackPenetration;
  };
  const auto startDepth = [&](Index k) {
    const ContactManifold& man = manifolds_[k];
    double start = 0;
    for (int p = 0; p < man.pointCount; ++p) start = std::max(start, -man.points[p].separation);
    return start;
  };
  executor.parallelFor(count, 16, [&](Index begin, Index end) {
    for (Index k = begin; k < end; ++k) {
      // The deep limit (speculative steps): a pair whose start depth and twice its motion
      // bound over the chunk (the margin's growth, from the velocities at its start; twice,
      // for what the solve adds) stay within the limit is not queried again.
      if (share && options_.continuous &&
          startDepth(k) + 2 * (margins_[k] - options_.speculativeDistance) <= limit(k)) {
        endDepth_[k] = 0;
        continue;
      }
      const Pair pair = pairs_[k];
      const RigidPiece& pa = m.pieces[pair.a];
      const RigidPiece& pb = m.pieces[pair.b];
      const Pose poseA = piecePose(pair.a, state_), poseB = piecePose(pair.b, state_);
      ContactManifold out;
      using Kind = RigidShapeDesc::Kind;
      if (pa.kind == Kind::Sphere && pb.kind == Kind::Sphere) {
        sphereSphere(poseA.position, pa.radius, poseB.position, pb.radius, 0, out);
      } else if (pa.kind == Kind::Sphere) {
        collideSphereHull(poseA.position, pa.radius, m.hulls[pb.hull], poseB, 0, out);
      } else if (pb.kind == Kind::Sphere) {
        collideSphereHull(poseB.position, pb.radius, m.hulls[pa.hull], poseA, 0, out);
      } else {
        PairCache cache = caches_[k];
        collideHulls(m.hulls[pa.hull], poseA, m.hulls[pb.hull], poseB, 0, options_.narrowPhase, cache, out);
      }
      double depth = 0;
      for (int p = 0; p < out.pointCount; ++p) depth = std::max(depth, -out.points[p].separation);
      endDepth_[k] = depth;
    }
  });
  for (Index k = 0; k < count; ++k)
    if (endDepth_[k] > limit(k) && endDepth_[k] > startDepth(k)) return true;
  return false;
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
      if (options_.continuous || rollback()) {
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

}  // namespace weft
