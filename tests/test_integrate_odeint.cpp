// tests/test_integrate_odeint.cpp — weft's integrators cross-checked against Boost.Odeint.
//
// The cloth comparisons give odeint a right-hand side built on weft's own ForceField
// (same model, same gravity, same force strategy, one thread), so what is compared is the
// time integration alone:
//   rk4             vs runge_kutta4, fixed steps: the same formula, summed in a different
//                   order, so agreement to rounding (see expectRoundingAgreement);
//   rk45 (fixed)    vs runge_kutta_dopri5 as a fixed stepper: the same Dormand-Prince
//                   fifth-order formula, with the same coefficients and summation order
//                   (bitwise equal in Release; agreement to rounding is what is required);
//   rk45 (adaptive) vs a dopri5 reference with tolerances 1e-12: agreement to the order of
//                   weft's tolerances.
// The oscillator comparison gives odeint the closed-form linear ODE instead, so it checks
// weft's spring force along with the integration.
//
// Boost is a test-only dependency (header-only; see tests/CMakeLists.txt).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <boost/numeric/odeint/integrate/integrate_adaptive.hpp>
#include <boost/numeric/odeint/stepper/generation.hpp>
#include <boost/numeric/odeint/stepper/runge_kutta4.hpp>
#include <boost/numeric/odeint/stepper/runge_kutta_dopri5.hpp>
#include <cmath>
#include <cstdio>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "support/test_support.hpp"

namespace weft::test {
namespace {

namespace odeint = boost::numeric::odeint;

/// odeint's state: all positions, then all velocities, each in Vec3Array's (column-major)
/// storage order (x coordinates of every particle, then y, then z).
using OdeState = std::vector<double>;

OdeState pack(const State<double>& s) {
  const Index m = static_cast<Index>(s.x.size());
  OdeState y(2 * static_cast<std::size_t>(m));
  std::copy_n(s.x.data(), m, y.begin());
  std::copy_n(s.v.data(), m, y.begin() + m);
  return y;
}

/// The right-hand side (x, v)' = (v, a(x, v)) with a from weft's ForceField, single
/// threaded. Holds its buffers; odeint copies the system it is given, so pass std::ref.
class ClothRhs {
 public:
  ClothRhs(const Model<double>& model, ForceStrategy strategy, const Vec3d& gravity)
      : forces_(model, strategy, gravity),
        exec_(1),
        x_(model.particleCount(), 3),
        v_(model.particleCount(), 3),
        a_(model.particleCount(), 3) {}

  void operator()(const OdeState& y, OdeState& dydt, double /*t*/) {
    const Index m = static_cast<Index>(x_.size());
    std::copy_n(y.begin(), m, x_.data());
    std::copy_n(y.begin() + m, m, v_.data());
    forces_.accelerations(x_, v_, a_, exec_);
    std::copy_n(v_.data(), m, dydt.begin());
    std::copy_n(a_.data(), m, dydt.begin() + m);
    ++evaluations_;
  }

  long evaluations() const { return evaluations_; }

 private:
  ForceField<double> forces_;
  Executor exec_;
  Vec3Array<double> x_, v_, a_;
  long evaluations_ = 0;
};

struct Difference {
  double x = 0;  // max |x_weft - x_odeint|, m
  double v = 0;  // max |v_weft - v_odeint|, m/s
};

Difference maxDifference(const State<double>& s, const OdeState& y) {
  const Index m = static_cast<Index>(s.x.size());
  Difference d;
  for (Index k = 0; k < m; ++k) {
    d.x = std::max(d.x, std::abs(s.x.data()[k] - y[static_cast<std::size_t>(k)]));
    d.v = std::max(d.v, std::abs(s.v.data()[k] - y[static_cast<std::size_t>(m + k)]));
  }
  return d;
}

/// Records a measured value in the --gtest_output=xml report and prints it.
void record(const std::string& name, double value) {
  std::ostringstream text;
  text.precision(3);
  text << std::scientific << value;
  ::testing::Test::RecordProperty(name, text.str());
  std::printf("[ measured ] %s = %s\n", name.c_str(), text.str().c_str());
}

/// Expects two integrations of `model` that differ by rounding only to agree.
///
/// Positions must agree to 1e-12 m (a few ulps of the 1 m cloth are measured, ~1e-15 m).
/// Velocities cannot agree as tightly in absolute terms: a rounding difference dx in a
/// position is turned by the stiffest springs into a velocity difference of order
/// omega_max dx (omega_max ~ 1800 rad/s for the 16 x 16 flag), so two runs that differ by
/// rounding differ by ~1e-12 m/s in velocity. Measured for rk4 after 100 steps:
/// 0.9 ... 1.4e-12 m/s over seeds 1 ... 12, and two odeint runs whose initial positions
/// differ by a single ulp differ by 8.5e-13 m/s. A flat 1e-12 m/s would sit on that floor;
/// the velocity difference is bounded in the phase-space unit of test_integrate instead
/// (|dv| / omega_max, in m): 1e-14 m, about 50 ulps of a 1 m position, i.e. ~1.8e-11 m/s.
void expectRoundingAgreement(const Model<double>& model, const State<double>& weft, const OdeState& y,
                             const std::string& label) {
  const double omegaMax = maxAngularFrequency(model);
  const Difference d = maxDifference(weft, y);
  record(label + "_max_dx", d.x);
  record(label + "_max_dv", d.v);
  record(label + "_max_dv_over_omega_max", d.v / omegaMax);
  EXPECT_LE(d.x, 1e-12);
  EXPECT_LE(d.v, 1e-14 * omegaMax) << "omega_max " << omegaMax << " rad/s";
}

/// The 16 x 16 flag with seeded perturbations of its free particles (positions by +-2 mm,
/// velocities by +-0.3 m/s), so every spring is stretched or compressed and moving from
/// the first step on.
ModelAndState<double> perturbedFlag() {
  ModelAndState<double> flag = makeFlag<double>(16);
  perturbFree(flag.model, flag.state, 0.002, 0.3, 1234);
  return flag;
}

constexpr ForceStrategy kStrategy = ForceStrategy::Gather;  // the same on both sides

// ---------------------------------------------------------------------------------------
// RK4
// ---------------------------------------------------------------------------------------

TEST(OdeintCloth, Rk4MatchesRungeKutta4) {
  const double dt = defaultTimeStep(BuiltinScene::Flag, 16);
  const int steps = 100;
  const ModelAndState<double> flag = perturbedFlag();
  const SimulationOptions options = flagOptions(IntegratorKind::Rk4, kStrategy, 1, dt);
  Simulation<double> sim(ModelAndState<double>{flag.model, flag.state}, options);
  ASSERT_EQ(sim.forceStrategy(), kStrategy);
  const StepStatus status = sim.run(steps);
  ASSERT_TRUE(status.ok()) << status.message();

  ClothRhs rhs(sim.model(), kStrategy, options.gravity);
  OdeState y = pack(flag.state);
  odeint::runge_kutta4<OdeState> stepper;
  for (int k = 0; k < steps; ++k) stepper.do_step(std::ref(rhs), y, k * dt, dt);
  EXPECT_EQ(rhs.evaluations(), 4 * steps);

  // The same formula, with the final weighted sum formed in a different order (weft:
  // x0 + h/6 (k1 + 2 k2 + 2 k3 + k4); odeint: x0 + h/6 k1 + h/3 k2 + h/3 k3 + h/6 k4):
  // the two differ by rounding only.
  expectRoundingAgreement(sim.model(), sim.state(), y, "rk4");

  // Not vacuous: the cloth moved (cm) and has velocities of the order of the perturbation.
  const double moved = (sim.state().x - flag.state.x).cwiseAbs().maxCoeff();
  record("rk4_max_displacement", moved);
  EXPECT_GT(moved, 1e-3);
  EXPECT_GT(sim.state().v.cwiseAbs().maxCoeff(), 0.05);
}

// ---------------------------------------------------------------------------------------
// Dormand-Prince
// ---------------------------------------------------------------------------------------

TEST(OdeintCloth, FixedStepRk45MatchesDopri5) {
  const double dt = defaultTimeStep(BuiltinScene::Flag, 16);
  const int steps = 100;
  const ModelAndState<double> flag = perturbedFlag();
  SimulationOptions options = flagOptions(IntegratorKind::Rk45, kStrategy, 1, dt);
  options.integration.adaptive = false;
  Simulation<double> sim(ModelAndState<double>{flag.model, flag.state}, options);
  const StepStatus status = sim.run(steps);
  ASSERT_TRUE(status.ok()) << status.message();
  // One substep per step, six evaluations each (first same as last), plus A_1 once.
  EXPECT_EQ(sim.totalWork().substeps, steps);
  EXPECT_EQ(sim.forceEvaluationCount(), 6 * steps + 1);

  // odeint's dopri5 as a plain fixed stepper (it is FSAL too: do_step keeps the last
  // derivative for the next step).
  ClothRhs rhs(sim.model(), kStrategy, options.gravity);
  OdeState y = pack(flag.state);
  odeint::runge_kutta_dopri5<OdeState> stepper;
  for (int k = 0; k < steps; ++k) stepper.do_step(std::ref(rhs), y, k * dt, dt);
  EXPECT_EQ(rhs.evaluations(), 6 * steps + 1);

  // Same tableau, same coefficient expressions (h * (35 / 384) etc.), same summation order
  // (x0 + w1 k1 + w3 k3 + ...): bitwise equal in the Release build here, but the compiler
  // may contract (FMA) or vectorise the two differently (it does under the sanitizers),
  // so the check is agreement to rounding.
  expectRoundingAgreement(sim.model(), sim.state(), y, "rk45_fixed");
}

TEST(OdeintCloth, AdaptiveRk45AgreesWithATightDopri5Reference) {
  const double frame = 0.01;  // s: 50 times the flag's fixed step; weft substeps within it
  const int frames = 5;       // 0.05 s simulated
  const double tol = 1e-8;
  const ModelAndState<double> flag = perturbedFlag();
  SimulationOptions options = flagOptions(IntegratorKind::Rk45, kStrategy, 1, frame);
  options.integration.relativeTolerance = tol;
  options.integration.absoluteTolerance = tol;
  Simulation<double> sim(ModelAndState<double>{flag.model, flag.state}, options);
  const StepStatus status = sim.run(frames);
  ASSERT_TRUE(status.ok()) << status.message();
  const StepWork& work = sim.totalWork();
  ASSERT_FALSE(work.failed);
  EXPECT_LE(work.errorEstimate, 1.0);
  EXPECT_GT(work.substeps, frames) << "the error control did not substep";

  // Reference: odeint's controlled dopri5 at 1e-12 (10^4 times tighter), ending exactly
  // at 0.05 s.
  const double reference = 1e-12;
  ClothRhs rhs(sim.model(), kStrategy, options.gravity);
  OdeState y = pack(flag.state);
  double largest = 0;  // max |y| over the reference's trajectory, m or m/s
  const auto observe = [&](const OdeState& state, double /*t*/) {
    for (const double c : state) largest = std::max(largest, std::abs(c));
  };
  const std::size_t referenceSteps =
      odeint::integrate_adaptive(odeint::make_controlled(reference, reference, odeint::runge_kutta_dopri5<OdeState>()),
                                 std::ref(rhs), y, 0.0, frames * frame, 1e-5, observe);

  const Difference d = maxDifference(sim.state(), y);
  record("rk45_adaptive_max_dx", d.x);
  record("rk45_adaptive_max_dv", d.v);
  record("rk45_adaptive_substeps", static_cast<double>(work.substeps));
  record("rk45_adaptive_rejected", static_cast<double>(work.rejectedSubsteps));
  record("rk45_reference_steps", static_cast<double>(referenceSteps));

  // The bound. Every accepted substep of weft keeps its estimated local error, in every
  // coordinate, within atol + rtol max(|y0|, |y1|) <= tol (1 + max|y|) (a max norm over
  // all coordinates). Local errors add up to at most substeps times that if the flow does
  // not amplify them, which holds for this damped cloth over 0.05 s up to a modest factor;
  // the estimate is the embedded fourth-order error while the fifth-order solution is
  // propagated, so the true local error is usually far below it. Allow a factor 2 for
  // propagation. Measured: ~7 tol in velocity, ~5e-3 tol in position, a few hundred times
  // inside the bound. The reference's own error is negligible beside it (against a 1e-13
  // reference: ~1e-11 m/s, ~1e-14 m).
  const double bound = 2.0 * static_cast<double>(work.substeps) * tol * (1.0 + largest);
  record("rk45_adaptive_bound", bound);
  EXPECT_LE(d.x, bound);
  EXPECT_LE(d.v, bound);
}

// ---------------------------------------------------------------------------------------
// The damped oscillator against the closed-form ODE
// ---------------------------------------------------------------------------------------

TEST(OdeintOscillator, Rk4MatchesRungeKutta4OnTheLinearOde) {
  const Oscillator osc;
  const double T = 2.0;  // about two periods
  const int steps = 400;
  const double dt = T / steps;
  Simulation<double> sim(osc.build<double>(), osc.options(IntegratorKind::Rk4, dt));
  const StepStatus status = sim.run(steps);
  ASSERT_TRUE(status.ok()) << status.message();

  // m x'' = -ks (x - rest) - kd x', written out directly (not through weft's ForceField).
  using Pair = std::array<double, 2>;
  const double k = osc.stiffness(), c = osc.damping, m = osc.mass, rest = osc.rest;
  const auto rhs = [&](const Pair& y, Pair& dydt, double /*t*/) {
    dydt[0] = y[1];
    dydt[1] = (-k * (y[0] - rest) - c * y[1]) / m;
  };
  Pair y{rest + osc.amplitude, 0.0};
  odeint::runge_kutta4<Pair> stepper;
  for (int n = 0; n < steps; ++n) stepper.do_step(rhs, y, n * dt, dt);

  const State<double>& s = sim.state();
  const double dx = std::abs(s.x(1, 0) - y[0]);
  const double dv = std::abs(s.v(1, 0) - y[1]);
  record("oscillator_rk4_dx", dx);
  record("oscillator_rk4_dv", dv);
  EXPECT_LE(dx, 1e-13);
  EXPECT_LE(dv, 1e-13);
  // The motion stayed on the x axis and both are close to the exact solution (RK4 at
  // omega dt = 0.03: ~1e-9 of the amplitude), so they agree on the right problem.
  EXPECT_EQ(s.x(1, 1), 0.0);
  EXPECT_EQ(s.x(1, 2), 0.0);
  const auto [xe, ve] = osc.exact(T);
  EXPECT_NEAR(y[0], xe, 1e-7);
  EXPECT_NEAR(y[1], ve, 1e-6);
}

}  // namespace
}  // namespace weft::test
