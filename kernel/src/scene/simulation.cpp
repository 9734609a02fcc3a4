#include "weft/scene/simulation.hpp"

#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

namespace weft {

namespace {

const SimulationOptions& validated(const SimulationOptions& o) {
  if (!(std::isfinite(o.dt) && o.dt > 0))
    throw std::invalid_argument("SimulationOptions.dt must be finite and > 0 (s), got " + std::to_string(o.dt));
  if (!o.arena && o.threads < 0)
    throw std::invalid_argument("SimulationOptions.threads must be >= 0 (0 = all cores), got " +
                                std::to_string(o.threads));
  if (!(std::isfinite(o.gravity.x) && std::isfinite(o.gravity.y) && std::isfinite(o.gravity.z)))
    throw std::invalid_argument("SimulationOptions.gravity must be finite");
  validateEffects(o.effects, "SimulationOptions.effects");
  if (std::isnan(o.stability.maxStretch))
    throw std::invalid_argument("SimulationOptions.stability.maxStretch must not be NaN");
  return o;
}

double norm(const Vec3d& a) { return std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z); }

void validatePath(const KinematicPath& p, size_t set) {
  const std::string where = "SimulationOptions.kinematicPins[" + std::to_string(set) + "].path.";
  const auto finite = [&](const Vec3d& v, const char* field) {
    if (!(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z)))
      throw std::invalid_argument(where + field + " must be finite, got (" + std::to_string(v.x) + ", " +
                                  std::to_string(v.y) + ", " + std::to_string(v.z) + ")");
  };
  finite(p.velocity, "velocity");
  finite(p.center, "center");
  finite(p.axis, "axis");
  if (!std::isfinite(p.angularVelocity))
    throw std::invalid_argument(where + "angularVelocity must be finite (rad/s), got " +
                                std::to_string(p.angularVelocity));
  if (p.angularVelocity != 0 && !(norm(p.axis) > 0))
    throw std::invalid_argument(where + "axis must be a non-zero vector when angularVelocity is not 0");
  if (!(std::isfinite(p.startTime) && p.startTime >= 0))
    throw std::invalid_argument(where + "startTime must be finite and >= 0 (s), got " + std::to_string(p.startTime));
  if (!(p.endTime >= p.startTime))
    throw std::invalid_argument(where + "endTime must be >= startTime (s), got " + std::to_string(p.endTime));
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
  setState(initial);
  clockStart_ = state_.time;
  // Kinematic pins: validated against the model, tracked from the initial positions.
  for (size_t set = 0; set < options_.kinematicPins.size(); ++set) {
    const KinematicPins& pins = options_.kinematicPins[set];
    validatePath(pins.path, set);
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
      for (const KinematicTrack& t : tracks_)
        if (t.particle == i)
          throw std::invalid_argument(field + " = " + std::to_string(i) + " is already moved by another kinematic pin");
      tracks_.push_back({i,
                         static_cast<Index>(set),
                         {static_cast<double>(state_.x(i, 0)), static_cast<double>(state_.x(i, 1)),
                          static_cast<double>(state_.x(i, 2))}});
    }
  }
  trackEnd_.resize(tracks_.size());
  trackVelocity_.setZero(static_cast<Index>(tracks_.size()), 3);
  forces_.setProfiling(options_.profileEffects);
}

Vec3d kinematicPosition(const KinematicPath& path, const Vec3d& p0, double t) {
  const double tau = std::clamp(t, path.startTime, path.endTime) - path.startTime;
  const Vec3d r{p0.x - path.center.x, p0.y - path.center.y, p0.z - path.center.z};
  Vec3d q = r;
  if (path.angularVelocity != 0) {
    // Rodrigues: q = r cos + (k x r) sin + k (k . r)(1 - cos), k the unit axis.
    const double len = norm(path.axis);
    const Vec3d k{path.axis.x / len, path.axis.y / len, path.axis.z / len};
    const double angle = path.angularVelocity * tau;
    const double c = std::cos(angle), s = std::sin(angle);
    const double kr = k.x * r.x + k.y * r.y + k.z * r.z;
    const Vec3d kxr{k.y * r.z - k.z * r.y, k.z * r.x - k.x * r.z, k.x * r.y - k.y * r.x};
    q = {r.x * c + kxr.x * s + k.x * kr * (1 - c), r.y * c + kxr.y * s + k.y * kr * (1 - c),
         r.z * c + kxr.z * s + k.z * kr * (1 - c)};
  }
  return {path.center.x + path.velocity.x * tau + q.x, path.center.y + path.velocity.y * tau + q.y,
          path.center.z + path.velocity.z * tau + q.z};
}

template <class S>
Simulation<S>::Simulation(ModelAndState<S> built, const SimulationOptions& options)
    : Simulation(std::make_shared<const Model<S>>(std::move(built.model)), std::move(built.state), options) {}

template <class S>
Simulation<S>::~Simulation() = default;

template <class S>
void Simulation<S>::setState(const State<S>& state) {
  const Index n = model_->particleCount();
  if (state.x.rows() != n || state.v.rows() != n)
    throw std::invalid_argument("Simulation::setState: state has " + std::to_string(state.x.rows()) +
                                " positions and " + std::to_string(state.v.rows()) + " velocities, the model has " +
                                std::to_string(n) + " particles");
  if (!state.x.allFinite() || !state.v.allFinite())
    throw std::invalid_argument("Simulation::setState: state has non-finite positions or velocities");
  state_ = state;
  status_ = StepStatus{};
  integrator_->reset();
}

template <class S>
void Simulation<S>::setTimeStep(double dt) {
  if (!(std::isfinite(dt) && dt > 0))
    throw std::invalid_argument("Simulation::setTimeStep: dt must be finite and > 0 (s), got " + std::to_string(dt));
  options_.dt = dt;
  status_ = StepStatus{};
}

template <class S>
StepStatus Simulation<S>::step() {
  if (!status_.ok()) return status_;
  const bool kinematic = !tracks_.empty();
  if (kinematic) {
    // Kinematic particles start the step exactly on their path and move along the chord
    // to where the path is at t + dt: with inverse mass 0 every integrator moves them by
    // exactly h v.
    const auto start =
        options_.profileEffects ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
    const double t0 = state_.time - clockStart_, t1 = t0 + options_.dt;
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
      state_.v(i, 0) = static_cast<S>((b.x - a.x) / options_.dt);
      state_.v(i, 1) = static_cast<S>((b.y - a.y) / options_.dt);
      state_.v(i, 2) = static_cast<S>((b.z - a.z) / options_.dt);
    }
    if (options_.profileEffects)
      kinematicSeconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  forces_.beginStep(state_.time);
  executor_->run([&] {
    lastWork_ =
        integrator_->advance(forces_, state_.x, state_.v, static_cast<S>(options_.dt), nextX_, nextV_, *executor_);
    if (lastWork_.failed) {
      status_ = StepStatus{};
      status_.code = StepCode::StepSizeUnderflow;
      status_.value = static_cast<double>(lastWork_.substeps + lastWork_.rejectedSubsteps);
    } else {
      status_ = stability_.check(nextX_, nextV_, *executor_);
    }
  });
  totalWork_ += lastWork_;
  if (!status_.ok()) {
    status_.time = state_.time;
    integrator_->reset();                        // anything it carried belongs to the rejected candidate
    for (size_t k = 0; k < tracks_.size(); ++k)  // the state is left as it was
      for (int c = 0; c < 3; ++c) state_.v(tracks_[k].particle, c) = trackVelocity_(static_cast<Index>(k), c);
    return status_;
  }
  for (size_t k = 0; k < tracks_.size(); ++k) {  // exactly on the path, no drift
    const Index i = tracks_[k].particle;
    nextX_(i, 0) = static_cast<S>(trackEnd_[k].x);
    nextX_(i, 1) = static_cast<S>(trackEnd_[k].y);
    nextX_(i, 2) = static_cast<S>(trackEnd_[k].z);
  }
  state_.x.swap(nextX_);  // O(1): exchanges storage, no copy, no allocation
  state_.v.swap(nextV_);
  ++stepCount_;
  state_.time += options_.dt;
  return status_;
}

template <class S>
SceneEffectTimes Simulation<S>::effectTimes() const {
  SceneEffectTimes t;
  t.forces = forces_.effectTimes();
  t.kinematicPins = kinematicSeconds_;
  return t;
}

template <class S>
StepStatus Simulation<S>::run(Index steps) {
  for (Index k = 0; k < steps; ++k)
    if (!step().ok()) break;
  return status_;
}

template class Simulation<float>;
template class Simulation<double>;

}  // namespace weft
