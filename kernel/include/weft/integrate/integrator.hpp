// weft/integrate/integrator.hpp — time integrators on shared SoA buffers.
//
// Design note
// -----------
// An integrator advances (x, v) by one step h of the ODE  x' = v, v' = a(x, v), where a
// comes from a ForceField. All integrators read the current state and write the next
// one into caller-provided buffers (x1, v1); they never modify (x0, v0), which is what
// lets the Simulation swap the result in only after the stability check, and roll back
// for free. Every stage combination is a whole-array Eigen expression over a block of
// rows (so it vectorises), run as one parallel pass; stage buffers are sized at
// construction, so advance() never allocates.
//
//   ExplicitEuler    x1 = x0 + h v0,  v1 = v0 + h a(x0, v0)                    order 1
//   SymplecticEuler  v1 = v0 + h a(x0, v0),  x1 = x0 + h v1                     order 1
//   Midpoint (RK2)   half Euler step to (xm, vm), then the full step with the
//                    midpoint derivative: x1 = x0 + h vm, v1 = v0 + h a(xm, vm)  order 2
//   Rk4              classic Runge-Kutta, weights 1/6 (1, 2, 2, 1)              order 4
//   VelocityVerlet   x1 = x0 + h v0 + h^2/2 a0,  v1 = v0 + h/2 (a0 + a1),
//                    a1 = a(x1, v0 + h a0); a1 is kept as the next step's a0, so one
//                    force evaluation per step (two on the first)                order 2
//   Rk45             Dormand-Prince 5(4): seven stages, first-same-as-last (six force
//                    evaluations per accepted substep), embedded fourth-order error
//                    estimate; adaptive mode covers the step h with substeps chosen by
//                    a PI controller, fixed mode takes one fifth-order step    order 5
//   ImplicitEuler    backward Euler linearised once per step (Baraff & Witkin 1998):
//                    (M - h df/dv - h^2 df/dx) dv = h (f0 + h df/dx v0), solved by
//                    matrix-free preconditioned conjugate gradients; x1 = x0 + h v1
//                    (one force evaluation, one Jacobian product per CG iteration)  order 1
//   Projective       projective dynamics (Liu et al. 2013): backward Euler on positions by
//                    local steps (each spring projected to its rest length) alternating
//                    with a global solve whose matrix M + h c I + (h^2 ks + h kd) L is
//                    factorised once per h; a fixed number of iterations    order 1
//
// See docs/integrators.md for stability limits and when to use which.
#pragma once

#include <limits>
#include <memory>
#include <string>

#include "weft/core/archive.hpp"
#include "weft/effects/force_field.hpp"

namespace weft {

enum class IntegratorKind {
  ExplicitEuler,
  SymplecticEuler,
  Midpoint,
  Rk4,
  VelocityVerlet,
  Rk45,
  ImplicitEuler,
  Projective
};

/// Short name used on the command line: euler, symplectic, midpoint, rk4, verlet, rk45,
/// implicit, projective.
const char* integratorName(IntegratorKind kind);
/// Parses a short name; throws std::invalid_argument naming the value otherwise.
IntegratorKind parseIntegrator(const std::string& name);
/// Global order of accuracy.
int integratorOrder(IntegratorKind kind);
/// Force evaluations of a step in steady state (Verlet's first step after a reset costs
/// one more: see Integrator::reset; for Rk45 this is per accepted substep, and the first
/// substep after a reset costs one more).
int integratorForceEvaluations(IntegratorKind kind);
/// Largest omega h at which the method is stable on an undamped spring (the imaginary
/// axis of its stability region): 2 for symplectic Euler and Verlet, 2 sqrt(2) for RK4,
/// 0.9972 for a fixed Dormand-Prince step (|R(iy)| <= 1 up to there, and grows slowly
/// beyond: 1.0000014 per step at 1, 1.03 at 2), infinity for implicit Euler (A-stable),
/// 0 for explicit Euler and midpoint, which amplify an undamped oscillation at any step.
/// For adaptive Rk45 the limit applies to its substeps, which the controller chooses.
double integratorStabilityLimit(IntegratorKind kind);
/// True for the methods whose stability limit is finite (all explicit ones).
inline bool integratorIsExplicit(IntegratorKind kind) {
  return kind != IntegratorKind::ImplicitEuler && kind != IntegratorKind::Projective;
}
/// Every integrator, in the order above (for parameterised tests and sweeps).
inline constexpr IntegratorKind kAllIntegrators[] = {IntegratorKind::ExplicitEuler,  IntegratorKind::SymplecticEuler,
                                                     IntegratorKind::Midpoint,       IntegratorKind::Rk4,
                                                     IntegratorKind::VelocityVerlet, IntegratorKind::Rk45,
                                                     IntegratorKind::ImplicitEuler,  IntegratorKind::Projective};

/// Implicit Euler's CG preconditioner (IntegratorOptions::preconditioner):
///   Jacobi       1 / diag(A) per coordinate
///   BlockJacobi  the inverse of each particle's 3x3 diagonal block of A
///   Projective   one prefactored solve with the springs' scalar matrix
///                M + h c I + (h^2 ks + h kd) L (projective dynamics' global matrix),
///                factorised once per h (the factorisation allocates; cached for two h)
///   Multigrid    one aggregation multigrid W-cycle: the springs' blocks summed over 2 x 2
///                blocks of a grid (pairs of pairs on other models) level by level down
///                to at most 32 nodes, solved there exactly; block-Jacobi smoothing. For
///                large steps on stiff or large cloth (20x fewer iterations on the 128^2
///                flag at 1/60 s); where block-Jacobi needs < 10 iterations it is slower
///   Auto         (the default) block-Jacobi, and the multigrid for every step at least as
///                long as the shortest step whose block-Jacobi solve took more than a
///                threshold (at first kAutoMultigridIterations) or stopped at
///                maxLinearIterations. The multigrid's first solve at that length is
///                judged against that block-Jacobi solve (a multigrid iteration counted
///                as 4.7 block-Jacobi iterations, its levels as 2): if it costs more, the
///                length goes back to block-Jacobi and the threshold rises above that
///                cost. So a stiff cloth moves to the multigrid from its second or third
///                step on, and a shorter step (setTimeStep, a collision chunk) is
///                block-Jacobi's until it too needs that many. Kept across setState and
///                in checkpoints. Both are built at construction, so switching allocates
///                nothing (docs/integrators.md has the measurements)
enum class Preconditioner { Jacobi, BlockJacobi, Projective, Multigrid, Auto };
inline constexpr Preconditioner kAllPreconditioners[] = {Preconditioner::Jacobi, Preconditioner::BlockJacobi,
                                                         Preconditioner::Projective, Preconditioner::Multigrid,
                                                         Preconditioner::Auto};
/// Preconditioner::Auto's first threshold: the multigrid for steps as long as one whose
/// block-Jacobi solve took more iterations than this (where the two cost about the same
/// on the flag from 16^2 to 128^2 at 1/60 and 1/600 s and CG 1e-6).
inline constexpr Index kAutoMultigridIterations = 40;
/// Names on the command line and in scene files: jacobi, block-jacobi, projective, multigrid,
/// auto.
const char* preconditionerName(Preconditioner p);
/// Parses a name; throws std::invalid_argument naming the value otherwise.
Preconditioner parsePreconditioner(const std::string& name);

/// The largest IntegratorOptions::maxSubsteps and maxLinearIterations (2^30).
inline constexpr Index kMaxIterationCap = Index(1) << 30;

/// Parameters of the adaptive and the implicit methods (the others have none). Checked by
/// validateIntegratorOptions; the Simulation checks them at construction.
struct IntegratorOptions {
  // Rk45 (both tolerances are raised to at least 64 eps of the scalar type, 7.6e-6 in
  // float: below that the error estimate measures rounding and only shrinks the substeps)
  bool adaptive = true;             // false: one fixed fifth-order step per step (for order tests)
  double relativeTolerance = 1e-6;  // per coordinate, relative to max(|y0|, |y1|)
  double absoluteTolerance = 1e-6;  // per coordinate (> 0): m for positions, m/s for velocities
  double minSubstep = 1e-12;        // s; an error still too large at this substep fails the step
  Index maxSubsteps = 100000;       // accepted + rejected substeps per step before it fails (<= 2^30)
  // ImplicitEuler
  double linearTolerance = 1e-6;                         // CG stops when |r| <= linearTolerance |b| (filtered 2-norms)
  Index maxLinearIterations = 1000;                      // in [1, 2^30]
  Preconditioner preconditioner = Preconditioner::Auto;  // implicit Euler's CG
  // Projective: local/global iterations per step (one global solve each, >= 1)
  int projectiveIterations = 10;
};
/// Throws std::invalid_argument naming the field and the value of the first bad option.
void validateIntegratorOptions(const IntegratorOptions& options);

/// The work one step did, reported by every integrator the same way.
struct StepWork {
  Index forceEvaluations = 0;   // calls of ForceField::accelerations
  Index substeps = 0;           // accepted (sub)steps: 1 for fixed-step methods
  Index rejectedSubsteps = 0;   // Rk45: trial substeps rejected by the error control
  Index linearIterations = 0;   // ImplicitEuler: CG iterations (one Jacobian product each);
                                // Projective: global solves (one per iteration)
  Index linearUnconverged = 0;  // ImplicitEuler: solves that stopped at maxLinearIterations
  double linearResidual = 0;    // ImplicitEuler: final |r| / |b| of the solve; Projective: the
                                // last iteration's largest coordinate change over the step's
                                // largest displacement (largest if summed)
  Index factorizations = 0;     // Projective: global matrices factorised (a new time step h)
  Index multigridSolves = 0;    // ImplicitEuler: solves preconditioned by the multigrid
  double errorEstimate = 0;     // Rk45: largest scaled error of an accepted substep (<= 1)
  bool failed = false;          // Rk45: error control gave up (minSubstep or maxSubsteps); the
                                // result must not be used
  /// Adds another step's work (counts add, residual and error take the maximum).
  StepWork& operator+=(const StepWork& o) {
    forceEvaluations += o.forceEvaluations;
    substeps += o.substeps;
    rejectedSubsteps += o.rejectedSubsteps;
    linearIterations += o.linearIterations;
    linearUnconverged += o.linearUnconverged;
    factorizations += o.factorizations;
    multigridSolves += o.multigridSolves;
    linearResidual = linearResidual > o.linearResidual ? linearResidual : o.linearResidual;
    errorEstimate = errorEstimate > o.errorEstimate ? errorEstimate : o.errorEstimate;
    failed = failed || o.failed;
    return *this;
  }
};

template <class S>
class Integrator {
 public:
  virtual ~Integrator() = default;
  virtual IntegratorKind kind() const = 0;

  /// Forgets anything carried from step to step (Verlet's acceleration). The Simulation
  /// calls it whenever the state changes other than by an accepted step of this
  /// integrator: a new state, or a rejected step.
  virtual void reset() {}

  /// Makes what a step on `exec` needs per thread (implicit Euler's stencil windows), so
  /// that no step allocates; the Simulation calls it when built. An integrator stepped
  /// without it makes them in its first step.
  virtual void reserve(const Executor&) {}

  /// Checkpoints (Simulation::save / load): writes, and reads back in the same order, what
  /// the integrator carries from step to step (Verlet's acceleration, rk45's slope and
  /// proposed substep, implicit Euler's warm start); nothing for the others.
  virtual void saveCarry(ArchiveWriter&) const {}
  virtual void loadCarry(ArchiveReader&) {}

  /// (x1, v1) = the state one step h after (x0, v0). All buffers (n x 3), distinct, and of
  /// the particle count given at construction.
  virtual StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                           Vec3Array<S>& v1, const Executor& exec) = 0;
};

/// An integrator with its stage buffers sized for `model` (which must outlive it when the
/// kind is ImplicitEuler or Projective: they read the model's springs). Throws
/// std::invalid_argument for bad options.
template <class S>
std::unique_ptr<Integrator<S>> makeIntegrator(IntegratorKind kind, const Model<S>& model,
                                              const IntegratorOptions& options = {});

extern template std::unique_ptr<Integrator<float>> makeIntegrator(IntegratorKind, const Model<float>&,
                                                                  const IntegratorOptions&);
extern template std::unique_ptr<Integrator<double>> makeIntegrator(IntegratorKind, const Model<double>&,
                                                                   const IntegratorOptions&);

}  // namespace weft
