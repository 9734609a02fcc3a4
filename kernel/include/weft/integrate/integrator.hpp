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
//
// See docs/integrators.md for stability limits and when to use which.
#pragma once

#include <memory>
#include <string>

#include "weft/effects/force_field.hpp"

namespace weft {

enum class IntegratorKind { ExplicitEuler, SymplecticEuler, Midpoint, Rk4, VelocityVerlet };

/// Short name used on the command line: euler, symplectic, midpoint, rk4, verlet.
const char* integratorName(IntegratorKind kind);
/// Parses a short name; throws std::invalid_argument naming the value otherwise.
IntegratorKind parseIntegrator(const std::string& name);
/// Global order of accuracy.
int integratorOrder(IntegratorKind kind);
/// Force evaluations of a step in steady state (Verlet's first step after a reset costs
/// one more: see Integrator::reset).
int integratorForceEvaluations(IntegratorKind kind);
/// Largest omega h at which the method is stable on an undamped spring (the imaginary
/// axis of its stability region): 2 for symplectic Euler and Verlet, 2 sqrt(2) for RK4,
/// 0 for explicit Euler and midpoint, which amplify an undamped oscillation at any step.
double integratorStabilityLimit(IntegratorKind kind);
/// Every integrator, in the order above (for parameterised tests and sweeps).
inline constexpr IntegratorKind kAllIntegrators[] = {IntegratorKind::ExplicitEuler, IntegratorKind::SymplecticEuler,
                                                     IntegratorKind::Midpoint, IntegratorKind::Rk4,
                                                     IntegratorKind::VelocityVerlet};

/// The work one step did, reported by every integrator the same way.
struct StepWork {
  Index forceEvaluations = 0;  // calls of ForceField::accelerations
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

  /// (x1, v1) = the state one step h after (x0, v0). All buffers (n x 3), distinct, and of
  /// the particle count given at construction.
  virtual StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                           Vec3Array<S>& v1, const Executor& exec) = 0;
};

/// An integrator with its stage buffers sized for `particleCount` particles.
template <class S>
std::unique_ptr<Integrator<S>> makeIntegrator(IntegratorKind kind, Index particleCount);

extern template std::unique_ptr<Integrator<float>> makeIntegrator(IntegratorKind, Index);
extern template std::unique_ptr<Integrator<double>> makeIntegrator(IntegratorKind, Index);

}  // namespace weft
