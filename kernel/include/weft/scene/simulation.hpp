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
// With obstacles (SimulationOptions::collision) a step is split into time chunks, as the
// original design's rollback: integrate a chunk, measure the candidate's deepest
// penetration; above CollisionOptions::maxPenetration discard the candidate (the state was
// never touched, so the restore is exact) and retry with half the chunk, down to
// maxHalvings halvings, then accept it and count it; otherwise resolve its contacts
// (ContactSolver: time of impact, continuous detection, restitution, friction) and accept
// it. Chunks are dt / 2^k, so a step always ends at exactly t + dt.
//
// so instability is reported as a status naming the first bad particle and the state is
// never overwritten with NaN. A failed simulation refuses to step until the time step is
// changed (setTimeStep) or a state is set (setState). step() never allocates and never
// throws for physical events; constructors and setters throw std::invalid_argument for
// bad parameters. Work runs in the caller's tbb::task_arena when one is given.
#pragma once

#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "weft/collide/collision_model.hpp"
#include "weft/collide/obstacles.hpp"
#include "weft/collide/self_collision.hpp"
#include "weft/core/kinematic_path.hpp"
#include "weft/integrate/integrator.hpp"
#include "weft/integrate/stability.hpp"
#include "weft/model/model_builder.hpp"
#include "weft/rigid/particle_coupling.hpp"
#include "weft/rigid/rigid_world.hpp"

namespace weft {

/// Pinned particles moved along a path (a bar holding the cloth's edge). The particles
/// must be pinned in the model (inverse mass 0): forces never move them, the path does.
/// Within a step a kinematic particle moves along the chord from its position at t to
/// its position at t + dt (its velocity is the chord's), and it ends the step exactly on
/// the path, so it never drifts (the path: weft/core/kinematic_path.hpp).

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
  CollisionOptions collision;                // obstacles; none by default, then free
  SelfCollisionOptions selfCollision;        // cloth against itself and other cloths; off by default, then free
  // The mesh obstacles of `collision` prepared once and shared by Simulations (BVHs,
  // closedness, feature edges: weft/collide/collision_model.hpp); none: built for this
  // Simulation. Must be built from `collision`'s meshes, or the Simulation refuses it.
  std::shared_ptr<const CollisionModel> collisionModel;
  RigidOptions rigid;           // rigid bodies; none by default, then free
  bool profileEffects = false;  // measure the CPU time of each effect (effectTimes())
};

/// CPU time of each effect (s, summed over threads) since construction, measured while
/// SimulationOptions::profileEffects is on.
struct SceneEffectTimes {
  EffectTimes forces;        // drag, wind, repulsion
  double kinematicPins = 0;  // moving the kinematic pins
  double collision = 0;      // obstacles: detection, response and rollback decisions (wall time x threads)
  double selfCollision = 0;  // the self-collision pass (wall time x threads)
  double rigidBodies = 0;    // the rigid bodies' step (wall time x threads)
};

/// Simulation::contactReport: contacts with obstacles in a state, and tunnelling over a run.
struct ContactReport {
  std::int64_t contacts = 0;   // free particles within thickness + epsilon of an obstacle
  double maxPenetration = 0;   // m, thickness - distance, the deepest
  std::int64_t tunnelled = 0;  // free particles that went through an obstacle since the start state given
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
  /// Whether every particle's position and velocity, every rigid body's position,
  /// orientation and velocities and the time are finite numbers. With the stability check on
  /// a step never leaves them otherwise; with it off (StabilityOptions::enabled = false)
  /// nothing stops a state that overflowed, and this is how a caller tells.
  bool stateFinite() const;
  /// What the steps so far did that does not stop them but that their results should not
  /// be read without, one line each for people (allocates; call after a run, not per step).
  /// Today:
  /// - a free particle that started inside an obstacle, deeper than the collision
  ///   thickness (the response pushes it out within a step, which can tear the cloth
  ///   around it), with the depth;
  /// - free particles that went through an obstacle since the start (tunnelledCount()),
  ///   with what to change;
  /// - with self-collision on: a cloth that started with pairs of triangles intersecting
  ///   (startIntersectionCount(); the pass cannot undo them), and one that has more now
  ///   than at the start (selfIntersectionCount(): it passed through itself), with what to
  ///   change; with it off, after a step, a cloth whose triangles intersect now (nothing kept
  ///   it from passing through itself), with the option that would;
  /// - rigid bodies let into each other deeper than RigidStats::kDeepShare of the thinner
  ///   piece's inner radius (RigidStats::deepestShare), naming them, the depth, the step and
  ///   what to change;
  /// - a spring whose length rounding to the precision can change by more than 1 % of its
  ///   rest length (it lies that far from the origin), now or at the start, naming the
  ///   worst one (a model where that exceeds 10 % does not build);
  /// - after a step, a structural spring (weft::stretch) longer than kStretchWarning x its rest length (stretched past
  ///   twice it, short of the check's StabilityOptions::maxStretch), naming the longest, with
  ///   the likelier cause for the integrator: too few projective iterations (the last step's
  ///   last one still changed it by more than kUnconvergedProjective; they leave a
  ///   stiff cloth softer than it is, and contacts then pull it apart), a step past an explicit
  ///   method's stability limit, or a step too large; springs meant to be that soft can ignore it
  ///   (not said with a particle that started inside an obstacle or a body that went through
  ///   the cloth: their lines say it tears);
  /// - adaptive rk45 that took kStiffSubsteps or more substeps a step on average with its
  ///   mean substep within 4x of its stability limit (estimateStableTimeStep): a model too
  ///   stiff for an explicit method, with the methods that take one solve a step; before the
  ///   first step, the same when dt / (4 x that limit), the least a step can take, is
  ///   kStiffSubsteps or more (so a run that will crawl says why before it starts).
  /// "The start" is the state the simulation was built with, or the last one given to
  /// setState() or load()/restore(). Empty when there is nothing to say. On a model with
  /// triangles it runs the exact intersection check (a BVH built for the call, once per state).
  std::vector<std::string> warnings() const;
  /// The mean substeps a step of adaptive rk45 from which warnings() speaks of stiffness.
  static constexpr double kStiffSubsteps = 100;
  /// The length, in rest lengths, past which warnings() speaks of a spring after a step.
  static constexpr double kStretchWarning = 2;
  /// The last iteration's change (StepWork::linearResidual) past which that warning blames
  /// projective dynamics' iteration count (40 iterations leave 0.04 on a 64^2 flag at 1/60 s,
  /// 160 leave 0.003: docs/integrators.md).
  static constexpr double kUnconvergedProjective = 0.01;
  /// Free particles that went through an obstacle between the start (as for warnings())
  /// and now: contactReport(&start).tunnelled, with the start kept by the simulation (its
  /// positions, only when there are obstacles). A particle that went through a solid
  /// obstacle and out of it is not counted (the two states are compared, not the steps).
  std::int64_t tunnelledCount() const;
  /// The deepest a free particle was inside an obstacle at the start, beyond the collision
  /// thickness (m; 0 when none was, or without obstacles). Measured on the first call after
  /// a new start, from the start's positions (as startIntersectionCount(), and likewise
  /// for one thread at a time).
  double startPenetration() const;
  /// With self-collision on, the pairs of triangles intersecting at the start (as for
  /// warnings(); what selfIntersectionCount() said then); 0 with it off. The simulation keeps
  /// the start's positions and counts on the first call after a new start, not when it
  /// starts (a construction does not pay for a check nobody reads); the count is kept, so
  /// like the steps this is for one thread at a time.
  std::int64_t startIntersectionCount() const;
  /// Replaces the state (same particle count, finite positions and time, speeds at most
  /// kMaxSpeed, coordinates the precision holds to a tenth of every spring's length; else
  /// std::invalid_argument naming the entry) and clears a failure. One pass over the
  /// particles and one over the springs; allocates nothing (a reset in a loop is cheap).
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
  std::int64_t forceEvaluationCount() const { return totalWork_.forceEvaluations; }
  [[deprecated("use forceEvaluationCount()")]] std::int64_t forceEvaluations() const { return forceEvaluationCount(); }
  /// Collision findings of the last step and summed over all steps (zeros without obstacles).
  const CollisionStats& lastCollision() const { return lastCollision_; }
  const CollisionStats& totalCollision() const { return totalCollision_; }
  /// What the contact pass finds in the current state (serial, for reports; not part of a
  /// step): free particles in contact and the deepest penetration now, and with `start` (a
  /// state this simulation passed through, such as the one a run began from) the free
  /// particles that tunnelled through an obstacle between it and now. Zeros without
  /// obstacles.
  ContactReport contactReport(const State<S>* start = nullptr) const;
  /// Self-collision findings of the last step and summed over all steps (zeros when off).
  const SelfCollisionStats& lastSelfCollision() const { return lastSelf_; }
  const SelfCollisionStats& totalSelfCollision() const { return totalSelf_; }
  /// Pairs of triangles sharing no particle that intersect in the current state: the exact
  /// check of weft/collide/self_collision.hpp, for any model (self-collision on or off).
  /// Builds a BVH: for reports and tests, not for every step of a fast loop. The count is
  /// kept until the state changes (a step, setState(), load()/restore()), so asking again,
  /// or warnings() after it, costs nothing; like the steps, for one thread at a time.
  std::int64_t selfIntersectionCount() const;
  [[deprecated("use selfIntersectionCount()")]] std::int64_t selfIntersections() const {
    return selfIntersectionCount();
  }
  /// The self-collision pass (null when SimulationOptions::selfCollision is off).
  const SelfCollider<S>* selfCollider() const { return self_.get(); }
  /// Bytes held by the buffers that grow with the contacts: the self-collision candidate,
  /// primitive and contact lists (0 when self-collision is off). They keep their largest
  /// size so far, so a step allocates only when it lists more than any before: a cloth
  /// whose contacts keep growing (wrung tighter and tighter) grows its memory by this much.
  std::size_t contactListBytes() const;
  /// The contact solver (null without obstacles).
  const ContactSolver<S>* contactSolver() const { return contacts_.get(); }
  /// The rigid bodies, stepped with the particles in the same fixed step (null without
  /// SimulationOptions::rigid bodies). Always double precision: a few bodies cost little,
  /// and resting stacks want the digits.
  const RigidWorld* rigidWorld() const { return rigid_.get(); }
  RigidWorld* rigidWorld() { return rigid_.get(); }
  /// Contacts between particles and rigid bodies in the last step and summed over all
  /// steps (zeros without both), with the moving bodies that went through a cloth
  /// (`crossings`: the cloth did not hold them; warnings() says so).
  const ParticleBodyStats& lastParticleBodyContacts() const { return lastCoupling_; }
  const ParticleBodyStats& totalParticleBodyContacts() const { return totalCoupling_; }
  /// Time spent in each effect (zeros unless SimulationOptions::profileEffects).
  SceneEffectTimes effectTimes() const;

  /// Checkpoints. save() writes everything a later step depends on to `path`: the state and
  /// its time, the time step, the status, what the integrator carries from step to step
  /// (Verlet's acceleration, rk45's slope and proposed substep, implicit Euler's warm start),
  /// the rigid bodies with their warm-start and witness caches, the kinematic pins' origins
  /// and the statistics. The file is binary, versioned and checksummed, written to
  /// `path`.tmp, flushed to the disk (fsync) and renamed into place, so an interrupted save,
  /// or a machine that loses power just after it, leaves the previous file whole. load()
  /// reads it into a Simulation built like the one that saved it (the same model, options and
  /// initial state): its steps then give bitwise the states the saved one would have reached,
  /// for any thread count. (The obstacles' and self-collision's caches only save work: they
  /// are rebuilt, and change no result.) A file of another format or weft version, precision,
  /// model (a fingerprint of its masses, springs and triangles), integrator or body count, or
  /// a damaged one (its checksum), is refused with a std::runtime_error naming the file and
  /// what differs, and the Simulation is unchanged. Effect timers (effectTimes) are not
  /// saved. Both allocate; step() still does not.
  void save(const std::string& path) const;
  void load(const std::string& path);
  /// The same in memory: a checkpoint's bytes, and restoring from them (`source` names them
  /// in messages).
  std::string checkpoint() const;
  void restore(std::string_view bytes, const std::string& source = "memory");
  /// The format version of checkpoint files this build writes and reads.
  // 2: the self-collision section; 3: its pushes; 4: implicit Euler's multigrid step (auto) and
  // StepWork::multigridSolves; 5: the run's particle-body contacts, with the bodies that went
  // through a cloth; 6: the rigid contacts' warm start kept as points (RigidWorld::WarmPoint) and
  // RigidStats::redoneSteps
  static constexpr std::uint32_t kCheckpointFormat = 6;

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
  // The start the warnings compare the run with (with obstacles or self-collision only):
  // positions and time; how deep beyond the thickness a particle was inside an obstacle,
  // and the pairs of triangles intersecting (both -1 until measured: only when asked for).
  Vec3Array<S> startX_;
  double startTime_ = 0;
  mutable double startPenetration_ = -1;
  mutable std::int64_t startIntersections_ = -1;
  Index startStep_ = 0;  // stepCount_ at the start (only steps change the state since)
  // The spring whose length rounding to S changes most (Simulation::warnings()).
  struct Rounding {
    double share = 0;     // of its rest length
    double farthest = 0;  // m, the largest |coordinate| of its ends
    Index spring = -1;
    // Keeps spring s if its share is larger (the first on a tie; a spring of rest length 0
    // has share 0 and is never kept).
    void consider(double s_share, double s_farthest, Index s) {
      if (s_share > share) *this = {s_share, s_farthest, s};
    }
  };
  // `rounding`: the start's worstRounding when the caller has it (setState finds it in the
  // pass that checks the springs), else computed here.
  void recordStart(const Rounding* rounding = nullptr);
  Rounding worstRounding(const Vec3Array<S>& x) const;
  Rounding startRounding_;
  std::string roundingWarning() const;
  std::string stretchWarning() const;
  // selfIntersectionCount() of the state now (-1: not counted since a step, a new start or
  // a restore, each of which forgets it).
  mutable std::int64_t nowIntersections_ = -1;
  double kinematicSeconds_ = 0;
  // Collision (null without obstacles) and its findings.
  std::unique_ptr<ContactSolver<S>> contacts_;
  CollisionStats lastCollision_, totalCollision_;
  std::unique_ptr<SelfCollider<S>> self_;  // null unless SimulationOptions::selfCollision.enabled
  SelfCollisionStats lastSelf_, totalSelf_;
  double collisionSeconds_ = 0;
  double selfSeconds_ = 0;
  double rigidSeconds_ = 0;
  /// Integrates the chunk [t, t + h] from the state into (nextX_, nextV_), the kinematic
  /// pins on their path; false (status_ set, state untouched) when the check failed.
  bool advanceChunk(double h);
  /// Undoes what advanceChunk did to the state (the kinematic pins' velocities) and forgets
  /// what the integrator carried from the rejected candidate.
  void rejectChunk();
  /// Swaps the candidate in: t += h.
  void acceptChunk(double h);
  /// One step through chunks with rollback (obstacles or self-collision present).
  StepStatus stepWithContacts();
  /// The particles' step (without or with obstacles).
  StepStatus stepParticles();
  std::unique_ptr<RigidWorld> rigid_;                  // null without rigid bodies
  std::unique_ptr<ParticleBodyContacts<S>> coupling_;  // null unless particles and bodies meet
  Vec3Array<S> stepStartX_, stepStartV_;               // (n x 3) x and v at the step's start (coupling only): put back
                                                       // when what the coupling made fails the stability check
  // With contacts or self-collision: the state at the step's start, put back when a chunk
  // after the first fails (the chunks before it were taken).
  Vec3Array<S> backupX_, backupV_;
  bool rollingBack_ = false;  // restore() is putting back the state before a refused load
  ParticleBodyStats lastCoupling_, totalCoupling_;
  /// Checkpoints: the fields of the "SIMU" section in order, written by an ArchiveWriter
  /// (Self const) and read by an ArchiveReader with the same code (checkpoint.cpp).
  template <class Archive, class Self>
  static void transfer(Archive& archive, Self& self);
};

extern template class Simulation<float>;
extern template class Simulation<double>;

}  // namespace weft
