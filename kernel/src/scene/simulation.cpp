#include "weft/scene/simulation.hpp"

#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "collide/contact_solver.hpp"
#include "collide/self_collider.hpp"
#include "core/text.hpp"
#include "model/precision_limits.hpp"
#include "rigid/particle_contacts.hpp"
#include "weft/model/energy.hpp"

namespace weft {

namespace {

/// The largest |coordinate| of particles a and b (x's columns X), in double: what the
/// precision's rounding rules measure a spring by (setState's check, worstRounding).
template <class S>
double farthestEnd(const S* const (&X)[3], Index a, Index b) {
  double farthest = 0;
  for (int c = 0; c < 3; ++c)
    farthest = std::max({farthest, std::abs(static_cast<double>(X[c][a])), std::abs(static_cast<double>(X[c][b]))});
  return farthest;
}

const SimulationOptions& validated(const SimulationOptions& o) {
  if (!(std::isfinite(o.dt) && o.dt > 0)) detail::rejectField("SimulationOptions.dt", o.dt, "finite and > 0 (s)");
  if (!o.arena && o.threads < 0)
    throw std::invalid_argument("SimulationOptions.threads must be >= 0 (0 = all cores), got " +
                                std::to_string(o.threads));
  if (!(std::isfinite(o.gravity.x) && std::isfinite(o.gravity.y) && std::isfinite(o.gravity.z)))
    detail::rejectField("SimulationOptions.gravity", detail::number3(o.gravity), "finite (m/s^2)");
  validateEffects(o.effects, "SimulationOptions.effects");
  validateCollision(o.collision, "SimulationOptions.collision");
  validateSelfCollision(o.selfCollision, "SimulationOptions.selfCollision");
  validateRigidOptions(o.rigid);
  validateStabilityOptions(o.stability, "SimulationOptions.stability");
  return o;
}

double norm(const Vec3d& a) { return std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z); }

/// dt as the model's precision holds it: a normal number (in float, 1e39 would step by
/// infinity and 1e-46 by 0).
template <class S>
double requireStep(double dt, const char* field) {
  if (!detail::PrecisionLimits<S>::timeStep(dt))
    detail::rejectField(field, dt, detail::PrecisionLimits<S>::timeStepRule());
  return dt;
}

template <class S>
std::shared_ptr<const Model<S>> requireModel(std::shared_ptr<const Model<S>> model) {
  if (!model) throw std::invalid_argument("Simulation: model must not be null");
  return model;
}

std::unique_ptr<Executor> makeExecutor(const SimulationOptions& o) {
  return o.arena ? std::make_unique<Executor>(*o.arena) : std::make_unique<Executor>(o.threads);
}

}  // namespace

template <class S>
Simulation<S>::Simulation(std::shared_ptr<const Model<S>> model, State<S> initial, const SimulationOptions& options)
    : model_(requireModel(std::move(model))),
      options_(validated(options)),
      executor_(makeExecutor(options_)),
      forces_(*model_, options_.forceStrategy, options_.gravity, options_.effects),
      integrator_(makeIntegrator<S>(options_.integrator, *model_, options_.integration)),
      stability_(*model_, options_.stability),
      nextX_(model_->particleCount(), 3),
      nextV_(model_->particleCount(), 3) {
  requireStep<S>(options_.dt, "SimulationOptions.dt");
  validateCollisionReach(options_.collision, std::numeric_limits<S>::epsilon(), detail::PrecisionLimits<S>::kName,
                         "SimulationOptions.collision");
  setState(initial);
  clockStart_ = state_.time;
  // Kinematic pins: validated against the model, tracked from the initial positions.
  std::vector<char> tracked(options_.kinematicPins.empty() ? 0 : static_cast<size_t>(model_->particleCount()), 0);
  for (size_t set = 0; set < options_.kinematicPins.size(); ++set) {
    const KinematicPins& pins = options_.kinematicPins[set];
    validateKinematicPath(pins.path, "SimulationOptions.kinematicPins[" + std::to_string(set) + "].path.");
    KinematicPath path = pins.path;
    const double a = norm(path.axis);
    if (a > 0) path.axis = {path.axis.x / a, path.axis.y / a, path.axis.z / a};
    paths_.push_back(path);
    for (size_t k = 0; k < pins.particles.size(); ++k) {
      const Index i = pins.particles[k];
      const std::string field =
          "SimulationOptions.kinematicPins[" + std::to_string(set) + "].particles[" + std::to_string(k) + "]";
      if (i < 0 || i >= model_->particleCount())
        throw std::invalid_argument(field + " must be a particle index in [0, " +
                                    std::to_string(model_->particleCount()) + "), got " + std::to_string(i));
      if (!model_->isPinned(i))
        throw std::invalid_argument(field + " = " + std::to_string(i) +
                                    " is not pinned in the model (a kinematic particle must have inverse mass 0)");
      if (tracked[static_cast<size_t>(i)])
        throw std::invalid_argument(field + " = " + std::to_string(i) + " is already moved by another kinematic pin");
      tracked[static_cast<size_t>(i)] = 1;
      tracks_.push_back({i,
                         static_cast<Index>(set),
                         {static_cast<double>(state_.x(i, 0)), static_cast<double>(state_.x(i, 1)),
                          static_cast<double>(state_.x(i, 2))}});
    }
    double reach = 0;  // of the set's farthest particle from the path's centre
    for (const Index i : pins.particles)
      reach = std::max(reach, std::hypot(static_cast<double>(state_.x(i, 0)) - path.center.x,
                                         static_cast<double>(state_.x(i, 1)) - path.center.y,
                                         static_cast<double>(state_.x(i, 2)) - path.center.z));
    validateKinematicSpin(path, reach, "SimulationOptions.kinematicPins[" + std::to_string(set) + "].path.",
                          "its farthest particle");
  }
  trackEnd_.resize(tracks_.size());
  trackVelocity_.setZero(static_cast<Index>(tracks_.size()), 3);
  forces_.setProfiling(options_.profileEffects);
  forces_.reserve(*executor_);  // the grid stencil's windows, one per thread: none made by a step
  integrator_->reserve(*executor_);
  if (options_.collision.any()) {
    // The edges the contact pass tests against mesh edges: the cloth's surface edges and a
    // rope's links (structural and shear springs), when there is a mesh to test them on.
    const CollisionOptions& c = options_.collision;
    std::vector<Edge> edges;
    if (c.continuous && c.edges && !c.meshes.empty()) edges = model_->collisionEdges();  // derived once per Model
    // The cloth's triangles, tested against the meshes' corners.
    Triangles triangles;
    if (c.continuous && c.corners && !c.meshes.empty()) triangles = model_->triangles();
    contacts_ = std::make_unique<ContactSolver<S>>(options_.collision, model_->particleCount(), std::move(edges),
                                                   options_.collisionModel, std::move(triangles));
  }
  if (options_.collision.any() || options_.selfCollision.enabled) {
    backupX_.resize(model_->particleCount(), 3);
    backupV_.resize(model_->particleCount(), 3);
  }
  if (options_.selfCollision.enabled) {
    validateSelfCollision(options_.selfCollision, *model_, state_.x, "SimulationOptions.selfCollision");
    self_ = std::make_unique<SelfCollider<S>>(*model_, options_.selfCollision, state_.x, *executor_);
    if (contacts_) contacts_->recordSupports();  // what each particle rests on, for the self-collision response
  }
  if (!options_.rigid.bodies.empty()) {
    const Vec3d& g = options_.gravity;
    rigid_ = std::make_unique<RigidWorld>(options_.rigid, Eigen::Vector3d(g.x, g.y, g.z));
    if (options_.rigid.particleContacts && model_->particleCount() > 0) {
      coupling_ = std::make_unique<ParticleBodyContacts<S>>(rigid_->model(), model_->particleCount(),
                                                            options_.rigid.particleThickness, model_->triangleCount());
      rigid_->reserveSupports(model_->particleCount() * ParticleBodyContacts<S>::kContactsPerParticle);
      stepStartX_.resize(model_->particleCount(), 3);
      stepStartV_.resize(model_->particleCount(), 3);
    }
  }
  recordStart();
}

template <class S>
Simulation<S>::Simulation(ModelAndState<S> built, const SimulationOptions& options)
    : Simulation(std::make_shared<const Model<S>>(std::move(built.model)), std::move(built.state), options) {}

template <class S>
Simulation<S>::~Simulation() = default;

template <class S>
ContactReport Simulation<S>::contactReport(const State<S>* start) const {
  ContactReport report;
  if (!contacts_) return report;
  // The contact solver's clock counts from this simulation's initial state.
  const ScalarArray<S>& w = model_->inverseMass();
  const double t = state_.time - clockStart_;
  report.contacts = contacts_->countContacts(state_.x, w, t);
  report.maxPenetration = contacts_->penetration(state_.x, w, t);
  if (start) {
    if (start->x.rows() != state_.x.rows())
      throw std::invalid_argument("Simulation::contactReport: start has " + std::to_string(start->x.rows()) +
                                  " positions, the model has " + std::to_string(state_.x.rows()) + " particles");
    report.tunnelled = contacts_->countTunnelled(start->x, state_.x, w, start->time - clockStart_, t);
  }
  return report;
}

template <class S>
std::int64_t Simulation<S>::selfIntersectionCount() const {
  // (Only steps, setState and restore change the state, and each forgets the count.)
  if (nowIntersections_ < 0) nowIntersections_ = countSelfIntersections(*model_, state_.x, *executor_);
  return nowIntersections_;
}

template <class S>
void Simulation<S>::setState(const State<S>& state) {
  const Index n = model_->particleCount();
  if (state.x.rows() != n || state.v.rows() != n)
    throw std::invalid_argument("Simulation::setState: state has " + std::to_string(state.x.rows()) +
                                " positions and " + std::to_string(state.v.rows()) + " velocities, the model has " +
                                std::to_string(n) + " particles");
  for (const auto* array : {&state.x, &state.v}) {
    if (array->allFinite()) continue;
    for (Index i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c)
        if (!std::isfinite((*array)(i, c)))
          detail::rejectField(std::string("Simulation::setState: state.") + (array == &state.x ? "x(" : "v(") +
                                  std::to_string(i) + ", " + std::to_string(c) + ")",
                              static_cast<double>((*array)(i, c)), "finite");
  }
  for (Index i = 0; i < n; ++i)  // (finite, but its kinetic energy is not: 1e300 m/s)
    if (!detail::speedWithinLimit(state.v(i, 0), state.v(i, 1), state.v(i, 2)))
      detail::rejectField("Simulation::setState: state.v(" + std::to_string(i) + ")",
                          detail::number3(state.v(i, 0), state.v(i, 1), state.v(i, 2)), detail::speedRule());
  // Positions the precision can simulate: squares of distances finite, and every spring's
  // length kept to a tenth under rounding (ModelBuilder::build's rules).
  using Limits = detail::PrecisionLimits<S>;
  for (Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c)
      if (!Limits::coordinate(static_cast<double>(state.x(i, c))))
        detail::rejectField("Simulation::setState: state.x(" + std::to_string(i) + ", " + std::to_string(c) + ")",
                            static_cast<double>(state.x(i, c)), Limits::coordinateRule());
  // The same pass finds the start's worst rounding (worstRounding's, for recordStart). (The
  // test inline, the message only for a spring that fails: a call per spring, and a second
  // pass for the rounding, made setState 4x slower, 1.5 ms on the 128^2 flag.)
  const Springs<S>& springs = model_->springs();
  const S* X[3] = {state.x.data(), state.x.data() + n, state.x.data() + 2 * n};
  Rounding rounding;
  for (Index k = 0; k < springs.count(); ++k) {
    const Index a = springs.a[k], b = springs.b[k];
    const double rest = static_cast<double>(springs.restLength[k]);
    const double farthest = farthestEnd(X, a, b);
    if (!Limits::springResolved(rest, farthest))
      Limits::requireSpringResolved(
          "Simulation::setState", k, a, b, rest,
          {static_cast<double>(state.x(a, 0)), static_cast<double>(state.x(a, 1)), static_cast<double>(state.x(a, 2)),
           static_cast<double>(state.x(b, 0)), static_cast<double>(state.x(b, 1)), static_cast<double>(state.x(b, 2))});
    rounding.consider(Limits::roundingShare(rest, farthest), farthest, k);
  }
  // The clock drives kinematic pins, paths and wind: a clock that is not a finite number
  // would put NaN into the positions at the next step.
  detail::requireField(std::isfinite(state.time), "Simulation::setState: state.time", state.time, "finite (s)");
  state_ = state;
  status_ = StepStatus{};
  integrator_->reset();
  recordStart(&rounding);
}

template <class S>
void Simulation<S>::recordStart(const Rounding* rounding) {
  // (While the constructor sets the first state there is neither yet: it records after.)
  if (contacts_ || self_) {
    startX_ = state_.x;
    startTime_ = state_.time;
  }
  startRounding_ = rounding ? *rounding : worstRounding(state_.x);  // (one pass over the springs)
  startPenetration_ = -1;                                           // (both measured when asked for)
  startIntersections_ = -1;
  nowIntersections_ = -1;
  startStep_ = stepCount_;
}

template <class S>
double Simulation<S>::startPenetration() const {
  if (!contacts_) return 0;
  if (startPenetration_ < 0)
    startPenetration_ = std::max(0.0, contacts_->penetration(startX_, model_->inverseMass(), startTime_ - clockStart_) -
                                          options_.collision.thickness);
  return startPenetration_;
}

template <class S>
std::int64_t Simulation<S>::startIntersectionCount() const {
  if (!self_ || model_->triangleCount() < 2) return 0;
  if (startIntersections_ < 0) startIntersections_ = countSelfIntersections(*model_, startX_, *executor_);
  return startIntersections_;
}

template <class S>
std::int64_t Simulation<S>::tunnelledCount() const {
  if (!contacts_) return 0;
  return contacts_->countTunnelled(startX_, state_.x, model_->inverseMass(), startTime_ - clockStart_,
                                   state_.time - clockStart_);
}

template <class S>
void Simulation<S>::setTimeStep(double dt) {
  if (!(std::isfinite(dt) && dt > 0)) detail::rejectField("Simulation::setTimeStep: dt", dt, "finite and > 0 (s)");
  requireStep<S>(dt, "Simulation::setTimeStep: dt");
  options_.dt = dt;
  status_ = StepStatus{};
}

template <class S>
bool Simulation<S>::advanceChunk(double h) {
  if (!tracks_.empty()) {
    // Kinematic particles start the chunk exactly on their path and move along the chord
    // to where the path is at t + h: with inverse mass 0 every integrator moves them by
    // exactly h v.
    const auto start =
        options_.profileEffects ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
    const double t0 = state_.time - clockStart_, t1 = t0 + h;
    for (size_t k = 0; k < tracks_.size(); ++k) {
      const KinematicTrack& tr = tracks_[k];
      const KinematicPath& path = paths_[tr.path];
      const Vec3d a = kinematicPosition(path, tr.reference, t0), b = kinematicPosition(path, tr.reference, t1);
      trackEnd_[k] = b;
      const Index i = tr.particle, r = static_cast<Index>(k);
      for (int c = 0; c < 3; ++c) trackVelocity_(r, c) = state_.v(i, c);
      state_.x(i, 0) = static_cast<S>(a.x);
      state_.x(i, 1) = static_cast<S>(a.y);
      state_.x(i, 2) = static_cast<S>(a.z);
      state_.v(i, 0) = static_cast<S>((b.x - a.x) / h);
      state_.v(i, 1) = static_cast<S>((b.y - a.y) / h);
      state_.v(i, 2) = static_cast<S>((b.z - a.z) / h);
    }
    if (options_.profileEffects)
      kinematicSeconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  forces_.beginStep(state_.time);
  StepWork work;
  executor_->run([&] {
    work = integrator_->advance(forces_, state_.x, state_.v, static_cast<S>(h), nextX_, nextV_, *executor_);
    if (work.failed) {
      status_ = StepStatus{};
      status_.code = StepCode::StepSizeUnderflow;
      status_.value = static_cast<double>(work.substeps + work.rejectedSubsteps);
    } else {
      status_ = stability_.check(nextX_, nextV_, *executor_);
    }
  });
  lastWork_ += work;
  if (!status_.ok()) {
    status_.time = state_.time;
    rejectChunk();  // the state is left as it was
    return false;
  }
  for (size_t k = 0; k < tracks_.size(); ++k) {  // exactly on the path, no drift
    const Index i = tracks_[k].particle;
    nextX_(i, 0) = static_cast<S>(trackEnd_[k].x);
    nextX_(i, 1) = static_cast<S>(trackEnd_[k].y);
    nextX_(i, 2) = static_cast<S>(trackEnd_[k].z);
  }
  return true;
}

template <class S>
void Simulation<S>::rejectChunk() {
  integrator_->reset();  // anything it carried belongs to the rejected candidate
  for (size_t k = 0; k < tracks_.size(); ++k)
    for (int c = 0; c < 3; ++c) state_.v(tracks_[k].particle, c) = trackVelocity_(static_cast<Index>(k), c);
}

template <class S>
void Simulation<S>::acceptChunk(double h) {
  state_.x.swap(nextX_);  // O(1): exchanges storage, no copy, no allocation
  state_.v.swap(nextV_);
  state_.time += h;
}

template <class S>
StepStatus Simulation<S>::step() {
  if (!status_.ok()) return status_;
  // (A step that fails leaves the state as it was, but for pinned particles on a path, which
  // it puts on it, where they already are unless setState() moved them off: the count kept
  // is forgotten whatever the step's outcome.)
  nowIntersections_ = -1;
  if (!rigid_) return stepParticles();
  // Bodies first: a failure of either part leaves both where they were.
  StepStatus bodies;
  const auto start =
      options_.profileEffects ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
  executor_->run([&] {
    // Particles that something holds carry the bodies resting on them (support contacts).
    if (coupling_ && options_.rigid.particleSupports)
      coupling_->collectSupports(state_.x, state_.v, model_->inverseMass(), *rigid_, *executor_);
    bodies = rigid_->step(options_.dt, *executor_);
  });
  if (options_.profileEffects)
    rigidSeconds_ +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() * executor_->threadCount();
  if (!bodies.ok()) {
    status_ = bodies;
    return status_;
  }
  if (coupling_) {  // same sizes: copies, no allocation
    stepStartX_ = state_.x;
    stepStartV_ = state_.v;
  }
  const double stepStart = state_.time;
  const StepStatus particles = stepParticles();
  if (!particles.ok()) {
    rigid_->undoStep();
    return particles;
  }
  if (coupling_) {
    // Particles and bodies push each other (the bodies' reaction acts from the next step).
    const auto couplingStart =
        options_.profileEffects ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
    executor_->run([&] {
      lastCoupling_ = coupling_->resolve(stepStartX_, state_.x, state_.v, model_->inverseMass(), *rigid_, *executor_);
    });
    StepStatus after;
    if (lastCoupling_.contacts > 0) {
      integrator_->reset();  // the state changed after the integrator saw it
      // The coupling moved particles after their step was checked: what it made is checked
      // too, and a failure puts both parts back where the step found them.
      executor_->run([&] { after = stability_.check(state_.x, state_.v, *executor_); });
    }
    if (options_.profileEffects)
      rigidSeconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - couplingStart).count() *
                       executor_->threadCount();
    if (!after.ok()) {
      state_.x = stepStartX_;
      state_.v = stepStartV_;
      state_.time = stepStart;
      --stepCount_;
      rigid_->undoStep();  // (the reactions the coupling gave the bodies with it)
      status_ = after;
      status_.time = stepStart;
      return status_;
    }
    // Bodies the cloth did not hold (a count for the report, not a failure: the step is
    // what the coupling makes of it, and the body has passed).
    if (model_->triangleCount() > 0) {
      const auto crossingStart =
          options_.profileEffects ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
      executor_->run([&] {
        lastCoupling_.crossings = coupling_->countCrossings(stepStartX_, state_.x, model_->triangles(), *rigid_,
                                                            *executor_, &lastCoupling_.firstCrossingBody);
      });
      lastCoupling_.firstCrossingTime = stepStart;
      if (options_.profileEffects)
        rigidSeconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - crossingStart).count() *
                         executor_->threadCount();
    }
    totalCoupling_ += lastCoupling_;
  }
  return particles;
}

template <class S>
StepStatus Simulation<S>::stepParticles() {
  if (contacts_ || self_) return stepWithContacts();
  lastWork_ = StepWork{};
  if (advanceChunk(options_.dt)) {
    acceptChunk(options_.dt);
    ++stepCount_;
  }
  totalWork_ += lastWork_;
  return status_;
}

template <class S>
StepStatus Simulation<S>::stepWithContacts() {
  const auto start =
      options_.profileEffects ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
  double integrateSeconds = 0, selfSeconds = 0;
  const double stepStart = state_.time, dt = options_.dt;
  const CollisionOptions& co = contacts_ ? contacts_->options() : options_.collision;
  const ScalarArray<S>& w = model_->inverseMass();
  // The step is 2^maxHalvings ticks; a chunk is 2^(maxHalvings - halvings) of them, so
  // every chunk length dt * ticks / total is exact and the chunks end exactly at t + dt.
  const std::int64_t total = std::int64_t(1) << co.maxHalvings;
  std::int64_t done = 0;
  int halvings = 0;
  lastWork_ = StepWork{};
  lastCollision_ = CollisionStats{};
  lastSelf_ = SelfCollisionStats{};
  bool ok = true;
  while (done < total) {
    const std::int64_t ticks = std::min(total >> halvings, total - done);
    const double h =
        dt * static_cast<double>(ticks) / static_cast<double>(total);  // exact: ticks / total is a power of 2
    const double t0 = state_.time - clockStart_, t1 = t0 + h;
    const auto integrateStart =
        options_.profileEffects ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
    ok = advanceChunk(h);
    if (options_.profileEffects)
      integrateSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - integrateStart).count();
    if (!ok) break;
    double depth = 0;
    if (contacts_) executor_->run([&] { depth = contacts_->deepestPenetration(nextX_, w, t1, *executor_); });
    if (depth > co.maxPenetration) {
      if (halvings < co.maxHalvings) {  // roll back: the state is untouched; retry with half the chunk
        rejectChunk();
        ++halvings;
        ++lastCollision_.rollbacks;
        continue;
      }
      ++lastCollision_.acceptedDeep;
    }
    CollisionStats found;
    if (contacts_) executor_->run([&] { found = contacts_->resolve(state_.x, nextX_, nextV_, w, t0, t1, *executor_); });
    lastCollision_ += found;
    SelfCollisionStats self;
    if (self_) {
      const auto selfStart =
          options_.profileEffects ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
      executor_->run([&] {
        self = self_->resolve(state_.x, nextX_, nextV_, w, h, *executor_, contacts_ ? contacts_->supports() : nullptr);
      });
      if (options_.profileEffects)
        selfSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - selfStart).count();
    }
    lastSelf_ += self;
    if (self_ && self_->overflowed()) {
      // The chunk is not resolved: its swept boxes overlap too much. A shorter chunk sweeps
      // less (the candidates of a fast cloth fall with the square of the chunk); at the
      // halving limit the step fails.
      if (halvings < co.maxHalvings) {
        rejectChunk();
        ++halvings;
        ++lastCollision_.rollbacks;
        continue;
      }
      status_ = StepStatus{};
      status_.code = StepCode::TooManyCandidates;
      status_.value = static_cast<double>(self_->options().maxCandidatesPerTriangle);
      status_.time = state_.time;
      rejectChunk();
      ok = false;
      break;
    }
    if (found.contacts > 0 || found.edgeContacts > 0 || self.contacts > 0 || self.frozen > 0) {
      integrator_->reset();  // the response changed the candidate it may have cached
      // The response moved particles after the integrator's candidate was checked: what it
      // made is checked too (a response to a huge step can stretch a spring past the limit).
      executor_->run([&] { status_ = stability_.check(nextX_, nextV_, *executor_); });
      if (!status_.ok()) {
        status_.time = state_.time;
        rejectChunk();  // the state is left as it was
        ok = false;
        break;
      }
    }
    if (done == 0 && ticks < total) {
      // The first chunk taken of a step in several: keep the state as the step found it, to
      // put back if a later chunk fails (a step in one chunk never needs it). Kinematic
      // particles are where a failed chunk leaves them: on their path, with the velocity
      // they had before the step.
      backupX_ = state_.x;  // (same sizes: copies, no allocation)
      backupV_ = state_.v;
      for (size_t k = 0; k < tracks_.size(); ++k)
        for (int c = 0; c < 3; ++c) backupV_(tracks_[k].particle, c) = trackVelocity_(static_cast<Index>(k), c);
    }
    acceptChunk(h);
    done += ticks;
  }
  if (ok) {
    state_.time = stepStart + dt;  // the same clock as a step without obstacles
    ++stepCount_;
  } else if (done > 0) {  // a failure leaves the state as the step found it
    state_.x = backupX_;
    state_.v = backupV_;
    state_.time = stepStart;
    status_.time = stepStart;
  }
  totalWork_ += lastWork_;
  totalCollision_ += lastCollision_;
  totalSelf_ += lastSelf_;
  if (options_.profileEffects) {
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    collisionSeconds_ += (wall - integrateSeconds - selfSeconds) * executor_->threadCount();
    selfSeconds_ += selfSeconds * executor_->threadCount();
  }
  return status_;
}

template <class S>
std::size_t Simulation<S>::contactListBytes() const {
  return self_ ? self_->listBytes() : 0;
}

template <class S>
SceneEffectTimes Simulation<S>::effectTimes() const {
  SceneEffectTimes t;
  t.forces = forces_.effectTimes();
  t.kinematicPins = kinematicSeconds_;
  t.collision = collisionSeconds_;
  t.selfCollision = selfSeconds_;
  t.rigidBodies = rigidSeconds_;
  return t;
}

template <class S>
StepStatus Simulation<S>::run(Index steps) {
  for (Index k = 0; k < steps; ++k)
    if (!step().ok()) break;
  return status_;
}

template <class S>
bool Simulation<S>::stateFinite() const {
  if (!(state_.x.allFinite() && state_.v.allFinite() && std::isfinite(state_.time))) return false;
  if (!rigid_) return true;
  const RigidState& r = rigid_->state();
  for (size_t b = 0; b < r.x.size(); ++b)
    if (!(r.x[b].allFinite() && r.q[b].coeffs().allFinite() && r.v[b].allFinite() && r.w[b].allFinite())) return false;
  return std::isfinite(r.time);
}

// The spring whose length rounding to S changes the most at positions x, as a share of its
// rest length (PrecisionLimits::roundingShare); the first such spring on a tie.
template <class S>
typename Simulation<S>::Rounding Simulation<S>::worstRounding(const Vec3Array<S>& x) const {
  const Springs<S>& sp = model_->springs();
  Rounding worst;
  const Index n = static_cast<Index>(x.rows());
  const S* X[3] = {x.data(), x.data() + n, x.data() + 2 * n};
  for (Index s = 0; s < sp.count(); ++s) {
    const double rest = static_cast<double>(sp.restLength[s]);
    if (!(rest > 0)) continue;
    const double farthest = farthestEnd(X, sp.a[s], sp.b[s]);
    worst.consider(detail::PrecisionLimits<S>::roundingShare(rest, farthest), farthest, s);
  }
  return worst;
}

// A line for warnings() when a spring's rounding share passes
// PrecisionLimits::kRoundingWarning at the start or now. A start past it is said the same
// way after any run that stays about where it started (so that a caller comparing the lines
// before and after a run sees nothing new); a state now a quarter worse than that, or past
// it when the start was not, is said too. (Past a tenth the model does not build and
// setState() refuses the state; a run can still carry a cloth there.)
template <class S>
std::string Simulation<S>::roundingWarning() const {
  using Limits = detail::PrecisionLimits<S>;
  const Rounding now = stepCount_ == startStep_ ? startRounding_ : worstRounding(state_.x);
  const bool fromStart = startRounding_.share > Limits::kRoundingWarning;
  const bool worseNow = now.share > (fromStart ? 1.25 * startRounding_.share : Limits::kRoundingWarning);
  if (!fromStart && !worseNow) return {};
  const Springs<S>& sp = model_->springs();
  std::ostringstream w;
  const auto describe = [&](const Rounding& r, bool start) {
    w << "spring " << r.spring << " (particles " << sp.a[r.spring] << " and " << sp.b[r.spring] << ", rest length "
      << static_cast<double>(sp.restLength[r.spring]) << " m) " << (start ? "was " : "is ") << r.farthest
      << " m from the origin" << (start ? " at the start" : "") << ", where rounding to " << Limits::kName
      << " can change its length by " << 100 * r.share << " % of its rest length";
  };
  if (fromStart) describe(startRounding_, true);
  if (fromStart && worseNow) w << "; and ";
  if (worseNow) describe(now, false);
  w << " (more than " << 100 * Limits::kRoundingWarning
    << " %): lengths, stretches and forces are that much less accurate; use double precision or build the model "
       "nearer the origin";
  return w.str();
}

// A line for warnings() when, after a step, a structural spring (what `max_stretch` of
// weft run measures: weft::stretch) is longer than kStretchWarning x its rest length. The
// check of each step stops a run at StabilityOptions::maxStretch (10 x by default); a cloth
// pulled past twice its length and short of that would otherwise end "ok" and look torn:
// projective dynamics with too few iterations on a cloth that folds onto itself ended so at
// 8.4 x (its contacts pull apart a cloth the iterations leave too soft to pull back).
template <class S>
std::string Simulation<S>::stretchWarning() const {
  if (stepCount_ == startStep_) return {};
  const Stretch now = stretch(*model_, state_);
  const double longest = now.max + 1;
  if (!(longest > kStretchWarning)) return {};
  const Springs<S>& sp = model_->springs();
  const Index worst = now.longest;
  std::ostringstream w;
  w << "spring " << worst << " (particles " << sp.a[worst] << " and " << sp.b[worst] << ") is " << longest
    << " x its rest length now (the longest; more than " << kStretchWarning
    << " x): unless the springs are meant to be that soft, the cloth is being pulled apart; ";
  const IntegratorKind kind = options_.integrator;
  if (kind == IntegratorKind::Projective && lastWork_.linearResidual > kUnconvergedProjective) {
    w << "projective dynamics with " << options_.integration.projectiveIterations
      << " iterations leaves a stiff cloth softer than it is (the last step's last iteration still changed it by "
      << lastWork_.linearResidual
      << " of its displacement), and contacts can then stretch what the iterations do not pull back: raise the "
         "iterations (IntegratorOptions::projectiveIterations, --pd-iterations) or reduce dt (now "
      << options_.dt << " s)";
  } else if (kind == IntegratorKind::ImplicitEuler || kind == IntegratorKind::Projective) {
    w << "reduce dt (now " << options_.dt << " s)";
  } else {
    const double stable = estimateStableTimeStep(*model_, kind);
    w << "an explicit method near or past its stability limit stretches springs before the check stops it at "
      << options_.stability.maxStretch << " x: reduce dt (now " << options_.dt << " s";
    if (stable > 0 && std::isfinite(stable)) w << "; its estimated stability limit " << stable << " s";
    w << ")";
  }
  return w.str();
}

template <class S>
std::vector<std::string> Simulation<S>::warnings() const {
  std::vector<std::string> out;
  if (const double deep = startPenetration(); deep > 0) {
    std::ostringstream w;
    w << "a particle started " << deep
      << " m inside an obstacle (beyond the collision thickness): the response pushes it out within a step and "
         "can tear the cloth around it; move the body or the obstacle";
    out.push_back(w.str());
  }
  const std::int64_t started = startIntersectionCount();
  if (started > 0)
    out.push_back("the cloth started with " + std::to_string(started) +
                  " pairs of triangles intersecting: self-collision keeps cloth from passing through itself and "
                  "cannot undo an intersection it starts with; move the cloths apart");
  if (self_ && model_->triangleCount() > 1) {
    // (No step since the start: the state is the start's, and so is the count.)
    const std::int64_t now = stepCount_ == startStep_ ? started : selfIntersectionCount();
    if (now > started) {
      std::ostringstream w;
      w << now << " pairs of triangles intersect now, " << started
        << " at the start: the cloth passed through itself although self-collision was on; ";
      if (totalSelf_.unresolved > 0 || !paths_.empty())
        w << "the pass moves only free particles, so pinned ones that a path moves (or that hold the cloth where it "
             "is pushed) go through it"
          << (totalSelf_.unresolved > 0 ? " (" + std::to_string(totalSelf_.unresolved) + " pairs it could not stop)"
                                        : std::string())
          << ": change the pins or the path; if that is not the case, reduce dt (now " << options_.dt
          << " s), and please report the scene";
      else
        w << "its failsafe stops every pair that comes too close, so this is not expected: reduce dt (now "
          << options_.dt << " s), and please report the scene";
      out.push_back(w.str());
    }
  }
  // Self-collision off: nothing keeps a cloth from passing through itself or another cloth.
  // A run that ended so says it (the start is not kept for this, so the count is of now).
  if (!self_ && model_->triangleCount() > 1 && stepCount_ > startStep_)
    if (const std::int64_t now = selfIntersectionCount(); now > 0)
      out.push_back(std::to_string(now) + (now == 1 ? " pair" : " pairs") +
                    " of triangles sharing no particle intersect now: self-collision is off, so nothing keeps cloth "
                    "from passing through itself or through another cloth; turn it on (SimulationOptions::"
                    "selfCollision, \"self_collision\" in a scene file) where cloth folds or cloths meet");
  if (const std::int64_t tunnelled = tunnelledCount(); tunnelled > 0)
    out.push_back(std::to_string(tunnelled) + (tunnelled == 1 ? " particle" : " particles") +
                  " went through an obstacle over the run (they ended inside it or beyond a thin one): " +
                  (options_.collision.continuous
                       ? "the continuous detection did not hold them; reduce dt"
                       : "the detection is not continuous (collision.continuous false); turn it on"));
  if (totalCoupling_.crossings > 0) {
    const Index b = totalCoupling_.firstCrossingBody;
    std::ostringstream w;
    w << "rigid body " << b << " (" << rigid_->model().names[static_cast<size_t>(b)]
      << ") went through the cloth in the step starting at t = " << totalCoupling_.firstCrossingTime << " s ("
      << totalCoupling_.crossings << (totalCoupling_.crossings == 1 ? " crossing" : " crossings")
      << " of a body's centre through a cloth triangle over the run): ";
    if (rigid_->model().motion[static_cast<size_t>(b)] == BodyMotion::Kinematic)
      w << "its path took it through the cloth, which could not get out of its way. Particles keep out of bodies, not "
           "the triangles between them, and pinned ones are not moved at all. Keep the path clear of pinned "
           "particles, slow it down, or put the particles closer together than the body is wide";
    else
      w << "the cloth could not carry it. Particles keep out of bodies, not the triangles between them, so the body "
           "pushed the particles apart and passed between them. Make the body lighter or the cloth stiffer, or its "
           "particles closer together than the body is wide";
    out.push_back(w.str());
  }
  if (const std::string rounding = roundingWarning(); !rounding.empty()) out.push_back(rounding);
  // (A particle that started inside an obstacle, or a body driven through the cloth, tears
  // it, and their lines above say so: a stretched spring is then no news.)
  if (startPenetration() == 0 && totalCoupling_.crossings == 0)
    if (const std::string stretched = stretchWarning(); !stretched.empty()) out.push_back(stretched);
  // Adaptive rk45 on a stiff model: its error control holds the substep near the stability
  // limit of the stiffest spring, not where the accuracy asks, and the run takes that many
  // substeps a step where an implicit method takes one solve. Before the first step it is
  // foreseen from the same limit: a step needs at least dt / (4 x the limit) substeps (the
  // bound on the stiffest mode is within 4x of it), said before a run that would otherwise
  // crawl without a word.
  if (options_.integrator == IntegratorKind::Rk45 && options_.integration.adaptive) {
    const double stable = estimateStableTimeStep(*model_, IntegratorKind::Rk45);
    const char* instead =
        "implicit Euler (integrator implicit) or projective dynamics (projective) take one solve a step";
    std::ostringstream w;
    if (stepCount_ == 0) {
      if (const double least = options_.dt / (4 * stable); least >= kStiffSubsteps)
        w << "rk45 will take at least " << std::floor(least) << " substeps a step (dt " << options_.dt
          << " s against a stability limit on the stiffest spring of " << stable
          << " s, within 4x): the model is stiff for an explicit method, so the substeps will keep it stable rather "
             "than accurate and the run will be slow; "
          << instead;
    } else {
      const double perStep = static_cast<double>(totalWork_.substeps) / static_cast<double>(stepCount_);
      const double mean = options_.dt / perStep;
      if (perStep >= kStiffSubsteps && mean <= 4 * stable)
        w << "rk45 took " << perStep << " substeps a step on average (a mean substep of " << mean
          << " s, within 4x of its stability limit on the stiffest spring, " << stable
          << " s): the model is stiff for an explicit method, so the substeps keep it stable rather than accurate; "
          << instead;
    }
    if (!w.str().empty()) out.push_back(w.str());
  }
  if (rigid_ && rigid_->totalStats().deepestShare > RigidStats::kDeepShare) {
    const RigidStats& t = rigid_->totalStats();
    const auto body = [&](Index b) {
      return std::to_string(b) + " (" + rigid_->model().names[static_cast<size_t>(b)] + ")";
    };
    std::ostringstream w;
    w << "rigid bodies " << body(t.deepestA) << " and " << body(t.deepestB) << " were " << t.deepestDepth
      << " m into each other in the step, or the part of one, starting at t = " << t.deepestTime << " s, "
      << t.deepestShare << " x the thinner piece's inner radius (" << t.deepestDepth / t.deepestShare
      << " m): the contacts let them pass into each other, so motions after that are not to be trusted. "
      << (t.deepestTime == 0 ? "If they were placed overlapping, move them apart; otherwise reduce " : "Reduce ")
      << "dt (now " << options_.dt << " s)"
      << (rigid_->options().timeOfImpact == RigidTimeOfImpact::Rollback ? ""
          : rigid_->options().redoDeepSteps
              ? " or take the rollback time of impact (--time-of-impact rollback)"
              : ", turn redo_deep_steps on (RigidOptions::redoDeepSteps: such a step is taken again in halves) or "
                "take the rollback time of impact (--time-of-impact rollback)");
    out.push_back(w.str());
  }
  return out;
}

template class Simulation<float>;
template class Simulation<double>;

}  // namespace weft
