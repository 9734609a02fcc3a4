// weft/scene/simulation.hpp — a model, a state and the step assembled for them.
//
// Design note
// -----------
// Simulation is the embedding API. It owns the State, shares the (immutable) Model, and
// holds what the step needs, all sized at construction: the ForceField (active force
// terms and the parallel strategy), the Integrator and its stage buffers, the next-state
// buffers and the StabilityCheck. A step is
//
//     integrator.advance(x, v) -> (x', v')   (each stage: forces -> accelerations -> combination)
//     check (x', v')                          error control gave up? finite? no spring beyond maxStretch?
//     ok: swap (x', v') in, t += dt           failure: keep (x, v), return the status
//
// so instability is reported as a status naming the first bad particle and the state is
// never overwritten with NaN. A failed simulation refuses to step until the time step is
// changed (setTimeStep) or a state is set (setState). step() never allocates and never
// throws for physical events; constructors and setters throw std::invalid_argument for
// bad parameters. Work runs in the caller's tbb::task_arena when one is given.
#pragma once

#include <limits>
#include <memory>
#include <vector>

#include "weft/integrate/integrator.hpp"
#include "weft/integrate/stability.hpp"
#include "weft/model/builder.hpp"

namespace weft {

/// A prescribed rigid motion: translation at `velocity` plus rotation about `axis` through
/// `center` at `angularVelocity`, active between startTime and endTime (s, on the
/// simulation's clock counted from its initial state) and frozen outside. A particle whose
/// initial position is p0 is at  center + velocity tau + R(axis, angularVelocity tau)(p0 - center)
/// with tau = clamp(t, startTime, endTime) - startTime.
struct KinematicPath {
  Vec3d velocity{0, 0, 0};                                   // m/s
  Vec3d center{0, 0, 0};                                     // m, the rotation centre at tau = 0
  Vec3d axis{0, 1, 0};                                       // direction of the rotation axis (normalised on use)
  double angularVelocity = 0;                                // rad/s (right hand about axis)
  double startTime = 0;                                      // s (>= 0)
  double endTime = std::numeric_limits<double>::infinity();  // s (>= startTime)
};

/// Pinned particles moved along a path (a bar holding the cloth's edge). The particles
/// must be pinned in the model (inverse mass 0): forces never move them, the path does.
/// Within a step a kinematic particle moves along the chord from its position at t to
/// its position at t + dt (its velocity is the chord's), and it ends the step exactly on
/// the path, so it never drifts.
/// Position (m) at time t (s, counted from the initial state) of a particle starting at p0.
Vec3d kinematicPosition(const KinematicPath& path, const Vec3d& p0, double t);

struct KinematicPins {
  std::vector<Index> particles;
  KinematicPath path;
};

struct SimulationOptions {
  IntegratorKind integrator = IntegratorKind::Rk4;
  double dt = 1e-3;                  // fixed time step, s (> 0)
  int threads = 0;                   // arena size when weft owns the arena (0 = all cores)
  tbb::task_arena* arena = nullptr;  // the embedding program's arena (then `threads` is ignored)
  ForceStrategy forceStrategy = ForceStrategy::Auto;
  Vec3d gravity{0, -9.81, 0};  // m/s^2
  ParticleEffects effects;     // per-particle effects (viscous drag); absent by default, then free
  StabilityOptions stability;
  IntegratorOptions integration;             // tolerances of rk45, CG settings of implicit
  std::vector<KinematicPins> kinematicPins;  // moving pins; none by default, then free
  bool profileEffects = false;               // measure the CPU time of each effect (effectTimes())
};

/// CPU time of each effect (s, summed over threads) since construction, measured while
/// SimulationOptions::profileEffects is on.
struct SceneEffectTimes {
  EffectTimes forces;        // drag, wind, repulsion
  double kinematicPins = 0;  // moving the kinematic pins
};

template <class S>
class Simulation {
 public:
  Simulation(std::shared_ptr<const Model<S>> model, State<S> initial, const SimulationOptions& options);
  Simulation(ModelAndState<S> built, const SimulationOptions& options);
  ~Simulation();

  /// Advances one fixed step. On failure the state is unchanged and the status says why.
  StepStatus step();
  /// Advances up to `steps` steps; stops at the first failure and returns its status.
  StepStatus run(Index steps);

  const Model<S>& model() const { return *model_; }
  const State<S>& state() const { return state_; }
  /// Replaces the state (same particle count) and clears a failure.
  void setState(const State<S>& state);
  double timeStep() const { return options_.dt; }
  /// Changes the fixed step (> 0) and clears a failure.
  void setTimeStep(double dt);

  const SimulationOptions& options() const { return options_; }
  IntegratorKind integrator() const { return options_.integrator; }
  ForceStrategy forceStrategy() const { return forces_.strategy(); }
  int threadCount() const { return executor_->threadCount(); }
  const Executor& executor() const { return *executor_; }

  /// Status of the last step (Ok until a step fails).
  const StepStatus& status() const { return status_; }
  Index stepCount() const { return stepCount_; }
  /// Work of the last step (accepted or not), and the sum over all steps taken (counts
  /// summed, residual and error estimate the largest).
  const StepWork& lastWork() const { return lastWork_; }
  const StepWork& totalWork() const { return totalWork_; }
  std::int64_t forceEvaluations() const { return totalWork_.forceEvaluations; }
  /// Time spent in each effect (zeros unless SimulationOptions::profileEffects).
  SceneEffectTimes effectTimes() const;

 private:
  std::shared_ptr<const Model<S>> model_;
  State<S> state_;
  SimulationOptions options_;
  std::unique_ptr<Executor> executor_;
  ForceField<S> forces_;
  std::unique_ptr<Integrator<S>> integrator_;
  StabilityCheck<S> stability_;
  Vec3Array<S> nextX_;  // (n x 3) candidate positions, m
  Vec3Array<S> nextV_;  // (n x 3) candidate velocities, m/s
  StepStatus status_;
  StepWork lastWork_;
  StepWork totalWork_;
  Index stepCount_ = 0;
  // Kinematic pins: one entry per moved particle, with its position at the start.
  struct KinematicTrack {
    Index particle;
    Index path;
    Vec3d reference;
  };
  std::vector<KinematicTrack> tracks_;
  std::vector<Vec3d> trackEnd_;       // position of each track at the end of the current step
  Vec3Array<S> trackVelocity_;        // (tracks x 3) velocities before the step, restored on failure
  std::vector<KinematicPath> paths_;  // with normalised axes
  double clockStart_ = 0;             // simulation time of the initial state
  double kinematicSeconds_ = 0;
};

extern template class Simulation<float>;
extern template class Simulation<double>;

}  // namespace weft
