// tests/test_integrate.cpp — the integrators: order of convergence against an exact
// solution, conservation of momentum, bounded energy of symplectic Euler.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <iterator>
#include <limits>
#include <sstream>
#include <vector>

#include "support/test_support.hpp"

namespace weft::test {
namespace {

template <class C>
class IntegratorTest : public ::testing::Test {};
TYPED_TEST_SUITE(IntegratorTest, AllConfigs, ConfigNames);

// ---------------------------------------------------------------------------------------
// Order of convergence on the damped oscillator
// ---------------------------------------------------------------------------------------

/// Step counts over the end time T (each twice the previous). Chosen per scalar type and
/// integrator so that the error is in the asymptotic regime (dt small enough, far below
/// the stability limit) and far above the rounding error: float RK4 needs large steps,
/// the first-order methods small ones. omega dt goes from 2 pi T / first down by halves.
template <class S>
std::vector<int> stepCounts(IntegratorKind kind) {
  const bool f = std::is_same_v<S, float>;
  int first = 0, count = 0;
  switch (kind) {
    case IntegratorKind::ExplicitEuler:  // error ~ 0.04 ... 0.005 of the amplitude
    case IntegratorKind::SymplecticEuler:
    case IntegratorKind::ImplicitEuler:
    case IntegratorKind::Projective:  // backward Euler too (the oscillator's spring stays on one line)
      first = 1280, count = f ? 3 : 4;
      break;
    case IntegratorKind::Midpoint:  // error ~ 1e-2 ... 1e-4 (float), ... 1e-5 (double)
      first = 160, count = f ? 4 : 5;
      break;
    case IntegratorKind::VelocityVerlet:  // smaller constant than midpoint: float reaches rounding one halving earlier
      first = 160, count = f ? 3 : 5;
      break;
    case IntegratorKind::Rk4:  // error ~ 1e-2 ... 4e-5 (float: omega dt 0.63 ... 0.16), ... 1e-8 (double)
      first = f ? 20 : 40, count = f ? 3 : 5;
      break;
    case IntegratorKind::Rk45:  // fixed steps; smaller constant than RK4
      first = f ? 20 : 20, count = f ? 2 : 4;
      break;
  }
  std::vector<int> counts;
  for (int k = 0; k < count; ++k) counts.push_back(first << k);
  return counts;
}

/// Phase-space error at T, relative to the amplitude: |(x - x*, (v - v*) / omega)| / A.
/// Using both position and velocity keeps the measure away from accidental zeros of one.
/// With fixedStep, rk45 takes one Dormand-Prince step per step (no error control), which
/// is what an order measurement in dt needs; the other integrators ignore it.
template <class S>
double oscillatorError(const Oscillator& osc, IntegratorKind kind, double T, int steps, bool fixedStep = false) {
  SimulationOptions options = osc.options(kind, T / steps);
  options.integration.adaptive = !fixedStep;
  options.integration.linearTolerance = 1e-12;  // implicit: the solve's error far below the method's
  Simulation<S> sim(osc.build<S>(), options);
  const StepStatus status = sim.run(steps);
  EXPECT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(sim.stepCount(), steps);
  const auto [x, v] = osc.exact(T);
  const State<S>& s = sim.state();
  // The motion stays on the x axis and the pinned end does not move.
  EXPECT_EQ(s.x(1, 1), S(0));
  EXPECT_EQ(s.x(1, 2), S(0));
  EXPECT_EQ(s.v(1, 1), S(0));
  EXPECT_EQ(s.v(1, 2), S(0));
  EXPECT_TRUE(s.x.row(0).isZero(0));
  EXPECT_TRUE(s.v.row(0).isZero(0));
  const double dx = static_cast<double>(s.x(1, 0)) - x;
  const double dv = (static_cast<double>(s.v(1, 0)) - v) / osc.omega;
  return std::hypot(dx, dv) / osc.amplitude;
}

TYPED_TEST(IntegratorTest, ConvergesAtItsTheoreticalOrder) {
  using S = typename TypeParam::Scalar;
  constexpr IntegratorKind kind = TypeParam::kIntegrator;
  const Oscillator osc;  // omega = 2 pi, damping ratio ~0.03
  const double T = 2.0;  // about two periods
  const int theory = integratorOrder(kind);
  ASSERT_EQ(theory, kind == IntegratorKind::Rk45                                                 ? 5
                    : kind == IntegratorKind::Rk4                                                ? 4
                    : kind == IntegratorKind::Midpoint || kind == IntegratorKind::VelocityVerlet ? 2
                                                                                                 : 1);

  const std::vector<int> counts = stepCounts<S>(kind);
  std::vector<double> errors;
  for (const int n : counts) errors.push_back(oscillatorError<S>(osc, kind, T, n, /*fixedStep=*/true));

  std::ostringstream table, orders;
  for (size_t k = 0; k < counts.size(); ++k) table << "\n  steps " << counts[k] << ": error " << errors[k];
  for (size_t k = 1; k < counts.size(); ++k) orders << (k > 1 ? " " : "") << std::log2(errors[k - 1] / errors[k]);
  ::testing::Test::RecordProperty("measured_orders", orders.str());  // in the --gtest_output=xml report
  for (size_t k = 1; k < counts.size(); ++k) {
    const double p = std::log2(errors[k - 1] / errors[k]);
    EXPECT_NEAR(p, theory, 0.2) << "order measured between " << counts[k - 1] << " and " << counts[k] << " steps"
                                << table.str();
  }
  // Sanity: errors are small (the range is the asymptotic one), and decrease.
  EXPECT_LT(errors.front(), 0.1) << table.str();
}

TYPED_TEST(IntegratorTest, OscillatorMatchesTheExactSolutionAtAFineStep) {
  using S = typename TypeParam::Scalar;
  constexpr IntegratorKind kind = TypeParam::kIntegrator;
  const Oscillator osc;
  // A direct check of the exact solution used above (and of the sign conventions of the
  // damping): at a fine step every integrator is close to it.
  const int steps = integratorOrder(kind) >= 4 ? 200 : integratorOrder(kind) == 2 ? 1000 : 8000;
  EXPECT_LT(oscillatorError<S>(osc, kind, 1.0, steps), 0.01);
}

// ---------------------------------------------------------------------------------------
// Momentum of a free cloth
// ---------------------------------------------------------------------------------------

TYPED_TEST(IntegratorTest, FreeClothConservesLinearMomentum) {
  using S = typename TypeParam::Scalar;
  constexpr IntegratorKind kind = TypeParam::kIntegrator;
  // The flag's grid without pins, random velocities (with a net drift), no gravity: the
  // spring forces come in +f/-f pairs, so sum m v stays what it was.
  ModelAndState<S> cloth = makeFreeFlag<S>(12);
  ASSERT_EQ(cloth.model.pinnedCount(), 0);
  addNoise<S>(cloth.state.v, 0.5, 21);
  for (Index i = 0; i < cloth.state.v.rows(); ++i) {
    cloth.state.v(i, 0) += S(0.3);
    cloth.state.v(i, 1) -= S(0.2);
    cloth.state.v(i, 2) += S(0.1);
  }
  const Model<S>& model = cloth.model;
  const auto p0 = momentum(model, cloth.state);
  long double scale = 0;  // sum m |v|: the size of the terms of the momentum sum
  for (Index i = 0; i < model.particleCount(); ++i)
    scale += model.mass()[i] * static_cast<long double>(cloth.state.v.row(i).norm());

  SimulationOptions options;
  options.integrator = kind;
  options.dt = 5e-5;  // well inside every method's stability region (explicit Euler grows slowly)
  options.threads = 1;
  options.gravity = {0, 0, 0};
  // Implicit Euler conserves momentum only as well as its linear solve: the sum of the
  // CG residual is the momentum error. Solve to the cap (432 unknowns: CG's exact
  // termination is well within 1000 iterations).
  options.integration.linearTolerance = 0;
  const int steps = 300;
  Simulation<S> sim(ModelAndState<S>{model, cloth.state}, options);
  const StepStatus status = sim.run(steps);
  ASSERT_TRUE(status.ok()) << status.message();

  const auto p1 = momentum(sim.model(), sim.state());
  // Each step adds rounding of the order of eps per force term; over `steps` steps the
  // momentum may drift by a few eps * steps relative to its scale.
  const long double tol = 4 * eps<S>() * steps * scale;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(p1[c], p0[c], tol) << "axis " << c;
  // The cloth did move and deform: the test is not vacuous.
  EXPECT_GT((sim.state().x - cloth.state.x).cwiseAbs().maxCoeff(), S(0.003));
}

// ---------------------------------------------------------------------------------------
// Integrator interface
// ---------------------------------------------------------------------------------------

TYPED_TEST(IntegratorTest, AdvanceLeavesTheInputAloneAndReportsItsWork) {
  using S = typename TypeParam::Scalar;
  constexpr IntegratorKind kind = TypeParam::kIntegrator;
  ModelAndState<S> flag = makeFlag<S>(8);
  perturbFree(flag.model, flag.state, 0.01, 0.3, 31);
  const Executor exec(1);
  ForceField<S> forces(flag.model, ForceStrategy::Gather, {0, -9.81, 0});
  auto integrator = makeIntegrator<S>(kind, flag.model);
  ASSERT_NE(integrator, nullptr);
  EXPECT_EQ(integrator->kind(), kind);
  const Vec3Array<S> x0 = flag.state.x, v0 = flag.state.v;
  Vec3Array<S> x1(x0.rows(), 3), v1(x0.rows(), 3);
  const StepWork work = integrator->advance(forces, x0, v0, S(1e-3), x1, v1, exec);
  EXPECT_FALSE(work.failed);
  if (kind == IntegratorKind::Rk45) {
    // Six evaluations per trial substep, plus A_1 of the first (fresh: no FSAL slope yet).
    EXPECT_GE(work.substeps, 1);
    EXPECT_EQ(work.forceEvaluations, 6 * (work.substeps + work.rejectedSubsteps) + 1);
    EXPECT_LE(work.errorEstimate, 1.0);
  } else {
    // A fresh Verlet has no a0 yet and evaluates it: one more than in steady state.
    EXPECT_EQ(work.forceEvaluations,
              integratorForceEvaluations(kind) + (kind == IntegratorKind::VelocityVerlet ? 1 : 0));
    EXPECT_EQ(work.substeps, 1);
  }
  if (kind == IntegratorKind::ImplicitEuler) {
    EXPECT_GT(work.linearIterations, 0);
    EXPECT_LE(work.linearResidual, IntegratorOptions{}.linearTolerance);
  } else if (kind == IntegratorKind::Projective) {
    EXPECT_EQ(work.linearIterations, IntegratorOptions{}.projectiveIterations);
    EXPECT_EQ(work.factorizations, 1);
    EXPECT_LT(work.linearResidual, 1.0);
  } else {
    EXPECT_EQ(work.linearIterations, 0);
  }
  EXPECT_TRUE(x0 == flag.state.x);
  EXPECT_TRUE(v0 == flag.state.v);
  EXPECT_TRUE(x1.allFinite() && v1.allFinite());
  EXPECT_FALSE(x1 == x0);
  // Pinned particles stay where they are.
  for (Index i = 0; i < flag.model.particleCount(); ++i)
    if (flag.model.isPinned(i)) {
      EXPECT_TRUE(x1.row(i) == x0.row(i)) << "particle " << i;
      EXPECT_TRUE(v1.row(i).isZero(0)) << "particle " << i;
    }
}

TYPED_TEST(IntegratorTest, NameParsesBack) {
  constexpr IntegratorKind kind = TypeParam::kIntegrator;
  EXPECT_EQ(parseIntegrator(integratorName(kind)), kind);
}

TEST(IntegratorNames, UnknownNameThrowsNamingIt) {
  try {
    (void)parseIntegrator("leapfrog");
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("leapfrog"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------
// Symplectic Euler: bounded energy
// ---------------------------------------------------------------------------------------

template <class S>
class SymplecticEnergy : public ::testing::Test {};
TYPED_TEST_SUITE(SymplecticEnergy, ScalarTypes);

struct EnergyRun {
  double maxDeviation = 0;    // max |E - E0| / E0 over the run
  double firstWindowMax = 0;  // max |E - E0| / E0 over the first tenth of the run
  double lastWindowMax = 0;   // ... over the last tenth
  double modifiedDrift = 0;   // max |H~ - H~0| / H~0 (H~: the method's exact invariant, see below)
  StepStatus status;
};

template <class S>
EnergyRun runUndampedOscillator(IntegratorKind kind, double omegaDt, int steps) {
  Oscillator osc;
  osc.damping = 0;
  const double h = omegaDt / osc.omega;
  Simulation<S> sim(osc.build<S>(), osc.options(kind, h));
  const double k = osc.stiffness(), m = osc.mass;
  const auto energy = [&] {
    const double u = static_cast<double>(sim.state().x(1, 0)) - osc.rest;
    const double v = static_cast<double>(sim.state().v(1, 0));
    return 0.5 * m * v * v + 0.5 * k * u * u;
  };
  // For v' = v - h w^2 u, u' = u + h v' the quadratic form v^2 + w^2 u^2 - h w^2 u v is
  // exactly invariant (in exact arithmetic): no drift of it at all is allowed.
  const auto modified = [&] {
    const double u = static_cast<double>(sim.state().x(1, 0)) - osc.rest;
    const double v = static_cast<double>(sim.state().v(1, 0));
    const double w2 = osc.omega * osc.omega;
    return v * v + w2 * u * u - h * w2 * u * v;
  };
  const double e0 = energy(), q0 = modified();
  EnergyRun r;
  const int window = steps / 10;
  for (int n = 1; n <= steps; ++n) {
    r.status = sim.step();
    if (!r.status.ok()) return r;
    const double dev = std::abs(energy() - e0) / e0;
    r.maxDeviation = std::max(r.maxDeviation, dev);
    if (n <= window) r.firstWindowMax = std::max(r.firstWindowMax, dev);
    if (n > steps - window) r.lastWindowMax = std::max(r.lastWindowMax, dev);
    r.modifiedDrift = std::max(r.modifiedDrift, std::abs(modified() - q0) / q0);
  }
  return r;
}

TYPED_TEST(SymplecticEnergy, StaysBoundedOverTenThousandSteps) {
  using S = TypeParam;
  const double omegaDt = 0.1;  // stability limit omega dt < 2
  const EnergyRun r = runUndampedOscillator<S>(IntegratorKind::SymplecticEuler, omegaDt, 10000);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  // The energy oscillates with relative amplitude about omega dt / 2 and does not grow.
  EXPECT_LT(r.maxDeviation, 0.6 * omegaDt);
  EXPECT_GT(r.firstWindowMax, 0.3 * omegaDt) << "the expected O(omega dt) oscillation is missing";
  EXPECT_LT(r.lastWindowMax, r.firstWindowMax * 1.02 + 100 * eps<S>());
  // The method's own invariant only moves by rounding (random walk over 10^4 steps).
  EXPECT_LT(r.modifiedDrift, 2e4 * eps<S>());
}

TYPED_TEST(SymplecticEnergy, ExplicitEulerOnTheSameOscillatorGainsEnergy) {
  using S = TypeParam;
  // The contrast that shows the bound above means something: at the same step, explicit
  // Euler multiplies the energy by (1 + (omega dt)^2) per step.
  // 100 steps: 1.01^100 ~ 2.7, and the amplitude stays below the rest length, so the
  // motion is still the linear oscillator the energy is computed for.
  const EnergyRun r = runUndampedOscillator<S>(IntegratorKind::ExplicitEuler, 0.1, 100);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  EXPECT_GT(r.lastWindowMax, 1.5);
}

// ---------------------------------------------------------------------------------------
// Stability limits on an undamped spring (issue 4): measured against theory, and the
// kernel's estimate against both
// ---------------------------------------------------------------------------------------

/// Whether `kind` keeps the undamped oscillator bounded for `steps` steps at omega h.
bool staysBounded(IntegratorKind kind, double omegaDt, int steps) {
  Oscillator osc;
  osc.damping = 0;
  // A small amplitude: the 1000x growth that counts as unstable must stay short of the
  // pinned point (|x| < rest), where the spring |dx| - r turns into a bounded double well.
  osc.amplitude = 1e-4;
  SimulationOptions options = osc.options(kind, omegaDt / osc.omega);
  options.integration.adaptive = false;  // rk45: the fixed step's limit
  Simulation<double> sim(osc.build<double>(), options);
  double worst = 0;
  for (int k = 0; k < steps; ++k) {
    if (!sim.step().ok()) return false;
    const double u = sim.state().x(1, 0) - osc.rest, v = sim.state().v(1, 0) / osc.omega;
    worst = std::max(worst, std::hypot(u, v) / osc.amplitude);
    if (!(worst < 1e3)) return false;
  }
  // Below the limit the phase-space radius stays within a bounded factor (for symplectic
  // methods it oscillates, growing without bound as omega h -> 2); above, it grows
  // exponentially and passes any factor within the run.
  return worst < 1e3;
}

/// Largest omega h at which the run stays bounded, by bisection between lo (stable) and
/// hi (unstable).
double measuredLimit(IntegratorKind kind, double lo, double hi) {
  for (int k = 0; k < 30; ++k) {
    const double mid = 0.5 * (lo + hi);
    (staysBounded(kind, mid, 20000) ? lo : hi) = mid;
  }
  return lo;
}

TEST(StabilityLimit, MeasuredLimitsMatchTheoryWithinFivePercent) {
  for (const IntegratorKind kind :
       {IntegratorKind::SymplecticEuler, IntegratorKind::VelocityVerlet, IntegratorKind::Rk4}) {
    SCOPED_TRACE(integratorName(kind));
    const double theory = integratorStabilityLimit(kind);
    const double measured = measuredLimit(kind, 0.1, 4.0);
    ::testing::Test::RecordProperty(std::string("limit_") + integratorName(kind), std::to_string(measured));
    EXPECT_NEAR(measured, theory, 0.05 * theory) << "measured omega h limit " << measured;
  }
}

/// Per-step growth factor of the phase-space radius of the undamped oscillator, measured
/// over as many steps as keep it between 1e-4 and 1e3 times its start (the displacement is
/// read from x ~ 0.5 m: below 1e-8 m its rounding would show; above 0.1 m the spring
/// would pass the pinned end). In the coordinates (u, v/omega)
/// the oscillator is a rotation, so a step of a Runge-Kutta or implicit method multiplies
/// the radius exactly by |R(i omega h)|, R the method's stability function.
double measuredAmplification(IntegratorKind kind, double omegaDt, double theory) {
  Oscillator osc;
  osc.damping = 0;
  osc.amplitude = 1e-4;
  SimulationOptions options = osc.options(kind, omegaDt / osc.omega);
  options.integration.adaptive = false;
  options.integration.linearTolerance = 1e-15;
  Simulation<double> sim(osc.build<double>(), options);
  const double decades = std::abs(std::log10(theory));
  const int steps = std::clamp(static_cast<int>((theory < 1 ? 4 : 3) / std::max(decades, 1e-300)), 1, 200);
  EXPECT_TRUE(sim.run(steps).ok()) << sim.status().message();
  const double u = sim.state().x(1, 0) - osc.rest, v = sim.state().v(1, 0) / osc.omega;
  return std::pow(std::hypot(u, v) / osc.amplitude, 1.0 / steps);
}

TEST(StabilityLimit, PerStepAmplificationIsTheStabilityFunction) {
  using C = std::complex<double>;
  const auto rk4 = [](C z) { return 1.0 + z + z * z / 2.0 + z * z * z / 6.0 + z * z * z * z / 24.0; };
  const auto dp5 = [&](C z) { return rk4(z) + std::pow(z, 5) / 120.0 + std::pow(z, 6) / 600.0; };
  const auto implicit = [](C z) { return 1.0 / (1.0 - z); };
  struct Case {
    IntegratorKind kind;
    std::function<C(C)> R;
    std::vector<double> omegaH;
  };
  const Case cases[] = {
      {IntegratorKind::Rk4, rk4, {0.5, 1.5, 2.8, 2.9}},
      // Dormand-Prince's fifth-order solution: |R| <= 1 up to 0.99719, then barely above 1.
      {IntegratorKind::Rk45, dp5, {0.5, 0.95, 0.99, 1.05, 1.5, 2.0}},
      {IntegratorKind::ImplicitEuler, implicit, {0.1, 1, 10, 100, 1000}},
  };
  for (const Case& c : cases)
    for (const double y : c.omegaH) {
      const double theory = std::abs(c.R(C(0, y)));
      const double measured = measuredAmplification(c.kind, y, theory);
      EXPECT_NEAR(measured, theory, 1e-9) << integratorName(c.kind) << " at omega h = " << y;
    }
  // The limit in the traits table is where |R(iy)| crosses 1.
  const double limit = integratorStabilityLimit(IntegratorKind::Rk45);
  EXPECT_LE(std::abs(dp5(C(0, limit * (1 - 1e-9)))), 1.0);
  EXPECT_GT(std::abs(dp5(C(0, limit * (1 + 1e-9)))), 1.0);
}

TEST(StabilityLimit, ImplicitEulerIsStableAtEveryStepTried) {
  // Up to omega h = 1000: the oscillation decays, never grows; the energy only falls.
  EXPECT_EQ(integratorStabilityLimit(IntegratorKind::ImplicitEuler), std::numeric_limits<double>::infinity());
  for (const double omegaDt : {0.01, 0.1, 1.0, 2.0, 2.9, 10.0, 100.0, 1000.0}) {
    SCOPED_TRACE(omegaDt);
    EXPECT_TRUE(staysBounded(IntegratorKind::ImplicitEuler, omegaDt, 2000));
    const EnergyRun r = runUndampedOscillator<double>(IntegratorKind::ImplicitEuler, omegaDt, 200);
    ASSERT_TRUE(r.status.ok()) << r.status.message();
  }
}

TEST(StabilityLimit, ProjectiveDynamicsIsStableAtEveryStepTried) {
  EXPECT_EQ(integratorStabilityLimit(IntegratorKind::Projective), std::numeric_limits<double>::infinity());
  for (const double omegaDt : {0.01, 0.1, 1.0, 2.9, 10.0, 100.0, 1000.0}) {
    SCOPED_TRACE(omegaDt);
    EXPECT_TRUE(staysBounded(IntegratorKind::Projective, omegaDt, 2000));
  }
}

TEST(StabilityLimit, ExplicitEulerAndMidpointGrowAtAnyStep) {
  for (const IntegratorKind kind : {IntegratorKind::ExplicitEuler, IntegratorKind::Midpoint}) {
    SCOPED_TRACE(integratorName(kind));
    EXPECT_EQ(integratorStabilityLimit(kind), 0.0);
    // Even at a small step the amplitude grows without bound (slowly for midpoint:
    // (1 + (omega h)^4 / 4)^(1/2) per step).
    EXPECT_FALSE(staysBounded(kind, kind == IntegratorKind::Midpoint ? 0.5 : 0.1, 200000));
  }
}

TEST(StabilityLimit, EstimateIsExactForOneMassOnAPinnedSpring) {
  Oscillator osc;
  const ModelAndState<double> built = osc.build<double>();
  EXPECT_NEAR(maxAngularFrequency(built.model), osc.omega, 1e-12 * osc.omega);
  for (const IntegratorKind kind : kAllIntegrators) {
    if (!integratorIsExplicit(kind)) {
      EXPECT_EQ(estimateStableTimeStep(built.model, kind), std::numeric_limits<double>::infinity());
      continue;
    }
    EXPECT_NEAR(estimateStableTimeStep(built.model, kind), integratorStabilityLimit(kind) / osc.omega, 1e-15);
  }
}

TEST(StabilityLimit, EstimateBoundsTheFlagFromAboveAndIsUsable) {
  // The bound is an upper bound on omega_max: at the estimated step (times 0.9) every
  // method with a stable region runs the undamped-ish flag for a while without failing,
  // and a free chain's interior (omega_max^2 = 4 k / m) is matched exactly.
  ModelBuilder<double> b;
  RopeSpec rope;
  rope.particleCount = 50;
  rope.bendSprings = false;
  addRope(b, rope);
  const ModelAndState<double> chain = b.build();
  const double k = rope.structural.stiffness, m = rope.totalMass / rope.particleCount;
  EXPECT_NEAR(maxAngularFrequency(chain.model), std::sqrt(4 * k / m), 1e-9 * std::sqrt(4 * k / m));

  for (const IntegratorKind kind :
       {IntegratorKind::SymplecticEuler, IntegratorKind::VelocityVerlet, IntegratorKind::Rk4}) {
    SCOPED_TRACE(integratorName(kind));
    ModelAndState<double> flag = makeFlag<double>(16);
    const double dt = 0.9 * estimateStableTimeStep(flag.model, kind);
    SimulationOptions options;
    options.integrator = kind;
    options.dt = dt;
    options.threads = 1;
    Simulation<double> sim(std::move(flag), options);
    EXPECT_TRUE(sim.run(2000).ok()) << sim.status().message();
  }
}

TEST(VerletEnergy, StaysBoundedOnAnUndampedSpring) {
  const double omegaDt = 0.5;
  const EnergyRun r = runUndampedOscillator<double>(IntegratorKind::VelocityVerlet, omegaDt, 10000);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  // Velocity Verlet's energy oscillates with relative amplitude (omega h)^2 / 4 (its
  // exact invariant is a modified energy) and does not drift.
  EXPECT_LT(r.maxDeviation, 0.3 * omegaDt * omegaDt);
  EXPECT_LT(r.lastWindowMax, 1.5 * r.firstWindowMax + 1e-12);
}

}  // namespace
}  // namespace weft::test

// ---------------------------------------------------------------------------------------
// Adaptive rk45
// ---------------------------------------------------------------------------------------

namespace weft::test {
namespace {

TEST(Rk45Adaptive, GlobalErrorFollowsTheTolerance) {
  // Frames of 0.1 s (omega h = 0.63 for the oscillator): each one is covered by as many
  // substeps as the tolerance asks for.
  const Oscillator osc;
  const double T = 2.0, frame = 0.1;
  double previousError = 1, previousSubsteps = 0;
  for (const double tol : {1e-3, 1e-5, 1e-7, 1e-9}) {
    SCOPED_TRACE(tol);
    SimulationOptions options = osc.options(IntegratorKind::Rk45, frame);
    options.integration.relativeTolerance = tol;
    options.integration.absoluteTolerance = tol;
    Simulation<double> sim(osc.build<double>(), options);
    ASSERT_TRUE(sim.run(20).ok()) << sim.status().message();
    EXPECT_NEAR(sim.state().time, T, 1e-12);
    const auto [x, v] = osc.exact(T);
    const double error = std::hypot(sim.state().x(1, 0) - x, (sim.state().v(1, 0) - v) / osc.omega) / osc.amplitude;
    const StepWork& w = sim.totalWork();
    ::testing::Test::RecordProperty("rk45_tol_" + std::to_string(tol),
                                    std::to_string(error) + " error, " + std::to_string(w.substeps) + " substeps");
    // Local error control: the global error is a modest multiple of the tolerance (the
    // scaled coordinates are ~0.5 m, so rtol and atol act alike here).
    EXPECT_LT(error, 20 * tol);
    EXPECT_LT(error, previousError);
    EXPECT_GT(static_cast<double>(w.substeps), previousSubsteps);
    EXPECT_LE(w.errorEstimate, 1.0);
    EXPECT_EQ(w.forceEvaluations, 6 * (w.substeps + w.rejectedSubsteps) + 1);
    previousError = error;
    previousSubsteps = static_cast<double>(w.substeps);
  }
}

TEST(Rk45Adaptive, FramesOfAStiffClothAreCoveredBySubsteps) {
  // The 16^2 flag at 1/60 s frames: omega_max h ~ 55 times the fixed step's limit.
  ModelAndState<double> flag = makeFlag<double>(16);
  SimulationOptions options = flagOptions(IntegratorKind::Rk45, ForceStrategy::Auto, 1, 1.0 / 60);
  Simulation<double> sim(std::move(flag), options);
  ASSERT_TRUE(sim.run(6).ok()) << sim.status().message();
  const StepWork& w = sim.totalWork();
  EXPECT_GT(w.substeps, 6 * 10);
  EXPECT_LE(w.errorEstimate, 1.0);
  EXPECT_NEAR(sim.state().time, 0.1, 1e-15);
  EXPECT_LT(sim.state().x.col(1).minCoeff(), -0.01);  // it fell
}

/// Substeps of rk45 over two 1/60 s frames of the 64^2 flag at tolerance 1e-6, moved by
/// `offset` m along x and y; the positions at the end (in the flag's own frame).
template <class S>
std::pair<std::int64_t, Vec3Array<double>> rk45FlagFrames(double offset) {
  ModelAndState<S> flag = makeFlag<S>(64);
  flag.state.x.col(0).array() += static_cast<S>(offset);
  flag.state.x.col(1).array() += static_cast<S>(offset);
  SimulationOptions options = flagOptions(IntegratorKind::Rk45, ForceStrategy::Auto, 2, 1.0 / 60);
  options.integration.relativeTolerance = 1e-6;
  options.integration.absoluteTolerance = 1e-6;
  Simulation<S> sim(std::move(flag), options);
  EXPECT_TRUE(sim.run(2).ok()) << sim.status().message();
  Vec3Array<double> x = sim.state().x.template cast<double>();
  x.col(0).array() -= offset;
  x.col(1).array() -= offset;
  return {sim.totalWork().substeps, x};
}

TEST(Rk45Adaptive, FloatDoesNotChaseTheRoundingOfItsPositions) {
  // Float stores a coordinate to eps |x|; a spring's vector keeps that absolute error and
  // the stiffness turns it into noise in the stage accelerations, which the velocity error
  // estimate measures as an error linear in h. Without a floor for it, float took 1562
  // substeps a frame of the 128^2 flag at 1e-6 against double's 80, and the same cloth
  // 10 m from the origin 12x more than at it. Now float takes about as many as double, the
  // offset changes little, and the result stays within a millimetre of double's.
  const auto [doubles, xd] = rk45FlagFrames<double>(0);
  const auto [floats, xf] = rk45FlagFrames<float>(0);
  const auto [shifted, xs] = rk45FlagFrames<float>(10);
  ::testing::Test::RecordProperty("substeps", std::to_string(doubles) + " double, " + std::to_string(floats) +
                                                  " float, " + std::to_string(shifted) + " float 10 m away");
  EXPECT_LE(floats, 2 * doubles);
  EXPECT_LE(shifted, 2 * floats);
  EXPECT_LT((xf - xd).cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_LT((xs - xd).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(Rk45Adaptive, GivingUpIsAStatusAndLeavesTheStateAlone) {
  // (The flat flag's first frames are nearly free fall, smooth enough for big substeps;
  // once the springs engage, the cloth needs substeps of ~1e-4 s.)
  SimulationOptions options = flagOptions(IntegratorKind::Rk45, ForceStrategy::Auto, 1, 1.0 / 60);
  options.integration.minSubstep = 1e-3;  // far above the substep this stiff cloth needs
  Simulation<double> sim(makeFlag<double>(12), options);
  State<double> before;
  StepStatus status;
  for (int k = 0; k < 60 && status.ok(); ++k) {
    before = sim.state();
    status = sim.step();
  }
  ASSERT_EQ(status.code, StepCode::StepSizeUnderflow) << status.message();
  EXPECT_NE(status.message().find("substep"), std::string::npos) << status.message();
  EXPECT_TRUE(sim.lastWork().failed);
  EXPECT_EQ(stateHash(sim.state()), stateHash(before));
  EXPECT_EQ(sim.state().time, before.time);
  EXPECT_EQ(sim.step().code, StepCode::StepSizeUnderflow);  // refuses until something changes

  options.integration.minSubstep = 1e-12;
  options.integration.maxSubsteps = 5;  // the other way to give up
  Simulation<double> capped(makeFlag<double>(12), options);
  status = StepStatus{};
  for (int k = 0; k < 60 && status.ok(); ++k) status = capped.step();
  EXPECT_EQ(status.code, StepCode::StepSizeUnderflow);
  EXPECT_EQ(capped.lastWork().substeps + capped.lastWork().rejectedSubsteps, 5)
      << capped.lastWork().substeps << " accepted, " << capped.lastWork().rejectedSubsteps << " rejected";
}

TEST(Rk45Adaptive, BadOptionsAreRejectedByName) {
  const ModelAndState<double> flag = makeFlag<double>(4);
  const auto expectRejected = [&](IntegratorOptions o, const std::string& field, const std::string& value) {
    SimulationOptions options;
    options.integrator = IntegratorKind::Rk45;
    options.integration = o;
    try {
      Simulation<double> sim(ModelAndState<double>{flag.model, flag.state}, options);
      ADD_FAILURE() << field << " = " << value << " accepted";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(field), std::string::npos) << what;
      EXPECT_NE(what.find(value), std::string::npos) << what;
    }
  };
  IntegratorOptions o;
  o.relativeTolerance = -1;
  expectRejected(o, "relativeTolerance", "-1");
  o = {};
  o.absoluteTolerance = 0;
  expectRejected(o, "absoluteTolerance", "0");
  o = {};
  o.absoluteTolerance = std::numeric_limits<double>::quiet_NaN();
  expectRejected(o, "absoluteTolerance", "nan");
  o = {};
  o.minSubstep = 0;
  expectRejected(o, "minSubstep", "0");
  o = {};
  o.maxSubsteps = 0;
  expectRejected(o, "maxSubsteps", "0");
  o = {};
  o.linearTolerance = 1;
  expectRejected(o, "linearTolerance", "1");
  o = {};
  o.maxLinearIterations = -3;
  expectRejected(o, "maxLinearIterations", "-3");
  o = {};
  o.projectiveIterations = 0;
  expectRejected(o, "projectiveIterations", "0");
  o = {};
  o.preconditioner = static_cast<Preconditioner>(7);
  expectRejected(o, "preconditioner", "7");
}

// ---------------------------------------------------------------------------------------
// Implicit Euler's linear solve
// ---------------------------------------------------------------------------------------

TEST(ImplicitSolve, ResidualMeetsTheToleranceAndIterationsGrowAsItTightens) {
  Index previous = 0;
  for (const double tol : {1e-3, 1e-6, 1e-9}) {
    SCOPED_TRACE(tol);
    SimulationOptions options = flagOptions(IntegratorKind::ImplicitEuler, ForceStrategy::Auto, 1, 1.0 / 60);
    options.integration.linearTolerance = tol;
    options.integration.preconditioner = Preconditioner::BlockJacobi;  // (auto would change with the tolerance)
    Simulation<double> sim(makeFlag<double>(16), options);
    ASSERT_TRUE(sim.run(3).ok()) << sim.status().message();
    const StepWork& w = sim.totalWork();
    EXPECT_LE(w.linearResidual, tol);
    EXPECT_EQ(w.linearUnconverged, 0);
    EXPECT_GT(w.linearIterations, previous);
    previous = w.linearIterations;
  }
}

TEST(ImplicitSolve, PreconditionerNamesParseBackAndAnUnknownOneIsNamed) {
  for (const Preconditioner p : kAllPreconditioners) EXPECT_EQ(parsePreconditioner(preconditionerName(p)), p);
  try {
    parsePreconditioner("ilu");
    ADD_FAILURE() << "'ilu' accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'ilu'"), std::string::npos) << e.what();
  }
  EXPECT_EQ(IntegratorOptions{}.preconditioner, Preconditioner::Auto);
}

TEST(ImplicitSolve, EveryPreconditionerMeetsTheToleranceTheSameOnOneAndTwoThreads) {
  // 40^2: several particle blocks and several row chunks of the grid products per pass.
  for (const Preconditioner p : kAllPreconditioners) {
    SCOPED_TRACE(preconditionerName(p));
    std::uint64_t hash[2][2];
    Index iterations[2] = {0, 0};
    for (const int threads : {1, 2}) {
      SimulationOptions options = flagOptions(IntegratorKind::ImplicitEuler, ForceStrategy::Auto, threads, 1.0 / 60);
      options.integration.preconditioner = p;
      Simulation<float> f(makeFlag<float>(40), options);
      Simulation<double> d(makeFlag<double>(40), options);
      ASSERT_TRUE(f.run(20).ok()) << f.status().message();
      ASSERT_TRUE(d.run(20).ok()) << d.status().message();
      EXPECT_EQ(d.totalWork().linearUnconverged, 0);
      EXPECT_LE(d.totalWork().linearResidual, options.integration.linearTolerance);
      EXPECT_EQ(d.totalWork().factorizations, p == Preconditioner::Projective ? 1 : 0);
      hash[0][threads - 1] = stateHash(f.state());
      hash[1][threads - 1] = stateHash(d.state());
      iterations[threads - 1] = d.totalWork().linearIterations;
    }
    EXPECT_EQ(hash[0][0], hash[0][1]) << "float";
    EXPECT_EQ(hash[1][0], hash[1][1]) << "double";
    EXPECT_EQ(iterations[0], iterations[1]);
  }
  // The preconditioners solve the same systems: the states agree to the solver's tolerance.
  constexpr int kCount = static_cast<int>(std::size(kAllPreconditioners));
  State<double> states[kCount];
  Index iterations[kCount];
  int k = 0;
  for (const Preconditioner p : kAllPreconditioners) {
    SimulationOptions options = flagOptions(IntegratorKind::ImplicitEuler, ForceStrategy::Auto, 1, 1.0 / 60);
    options.integration.preconditioner = p;
    options.integration.linearTolerance = 1e-10;
    Simulation<double> sim(makeFlag<double>(24), options);
    ASSERT_TRUE(sim.run(10).ok()) << sim.status().message();
    states[k] = sim.state();
    iterations[k++] = sim.totalWork().linearIterations;
  }
  for (int j = 1; j < kCount; ++j) EXPECT_LT((states[j].x - states[0].x).cwiseAbs().maxCoeff(), 1e-7) << j;
  // Block-Jacobi takes fewer iterations than Jacobi, multigrid far fewer than both. (The
  // projective preconditioner takes more on this small flag, 2095 against 1441, and fewer at
  // 128^2 and 1/60 s: docs/integrators.md.)
  EXPECT_LT(iterations[1], iterations[0]);
  EXPECT_LT(3 * iterations[3], iterations[1]);
}

TEST(ImplicitSolve, AnIterationCapIsReportedAndTheStepStillTaken) {
  SimulationOptions options = flagOptions(IntegratorKind::ImplicitEuler, ForceStrategy::Auto, 1, 1.0 / 60);
  options.integration.maxLinearIterations = 2;
  Simulation<double> sim(makeFlag<double>(16), options);
  // (The first step from the flat, unstretched flag is free fall: A is M there on the
  // gravity direction and one iteration solves it exactly.)
  ASSERT_TRUE(sim.run(3).ok()) << sim.status().message();
  EXPECT_EQ(sim.lastWork().linearUnconverged, 1);
  EXPECT_EQ(sim.lastWork().linearIterations, 2);  // (the warm start's residual product is not an iteration)
  EXPECT_GT(sim.lastWork().linearResidual, options.integration.linearTolerance);
}

TEST(ImplicitSolve, PinnedParticlesStayPutAtAHugeStep) {
  // 0.1 s: omega_max h ~ 180. (At 0.5 s the first step, linearised at the flat unstretched
  // cloth where the springs have no transverse stiffness, is a free fall of 2.45 m and the
  // stability check flags the stretch: one linearised solve per step is not a nonlinear
  // solve.)
  ModelAndState<double> flag = makeFlag<double>(16);
  const State<double> initial = flag.state;
  SimulationOptions options = flagOptions(IntegratorKind::ImplicitEuler, ForceStrategy::Auto, 2, 0.1);
  Simulation<double> sim(std::move(flag), options);
  ASSERT_TRUE(sim.run(10).ok()) << sim.status().message();
  for (Index i = 0; i < sim.model().particleCount(); ++i)
    if (sim.model().isPinned(i)) {
      EXPECT_TRUE(sim.state().x.row(i) == initial.x.row(i)) << i;
      EXPECT_TRUE(sim.state().v.row(i).isZero(0)) << i;
    }
  EXPECT_TRUE(allFinite(sim.state()));
}

// ---------------------------------------------------------------------------------------
// Projective dynamics
// ---------------------------------------------------------------------------------------

/// The largest backward-Euler residual of a step, |(v1 - v0) / h - a(x1, v1)| over free
/// particles and axes (a from the ForceField: springs with their damping along the spring,
/// gravity, drag), relative to the largest |a|.
template <class S>
double backwardEulerResidual(const ModelAndState<S>& scene, const SimulationOptions& options, int iterations) {
  SimulationOptions o = options;
  o.integration.projectiveIterations = iterations;
  Simulation<S> sim(ModelAndState<S>{scene.model, scene.state}, o);
  EXPECT_TRUE(sim.run(1).ok()) << sim.status().message();
  ForceField<S> forces(sim.model(), ForceStrategy::Gather, o.gravity, o.effects);
  Executor exec(1);
  Vec3Array<S> a(sim.model().particleCount(), 3);
  forces.accelerations(sim.state().x, sim.state().v, a, exec);
  const S h = static_cast<S>(o.dt);
  double worst = 0, scale = 0;
  for (Index i = 0; i < sim.model().particleCount(); ++i) {
    if (sim.model().isPinned(i)) continue;
    for (int c = 0; c < 3; ++c) {
      worst = std::max(worst, std::abs(static_cast<double>((sim.state().v(i, c) - scene.state.v(i, c)) / h - a(i, c))));
      scale = std::max(scale, std::abs(static_cast<double>(a(i, c))));
    }
  }
  return worst / scale;
}

// The same model without its grid layout (springs, masses, pins and state copied), so the
// projective step takes its general paths (per-spring endpoints, incidence lists).
ModelAndState<double> withoutGridLayout(const ModelAndState<double>& scene) {
  const Model<double>& model = scene.model;
  ModelBuilder<double> b;
  for (Index i = 0; i < model.particleCount(); ++i)
    b.addParticle(Vec3d(scene.state.x(i, 0), scene.state.x(i, 1), scene.state.x(i, 2)),
                  model.mass()[i] > 0 ? model.mass()[i] : 1.0,
                  Vec3d(scene.state.v(i, 0), scene.state.v(i, 1), scene.state.v(i, 2)));
  const Springs<double>& sp = model.springs();
  for (Index s = 0; s < sp.count(); ++s)
    b.addSpring(sp.a[s], sp.b[s], SpringMaterial{sp.stiffness[s], sp.damping[s]}, SpringClass::Structural,
                sp.restLength[s]);
  for (Index i = 0; i < model.particleCount(); ++i)
    if (model.isPinned(i)) b.pin(i);
  return b.build();
}

TEST(ProjectiveDynamics, TheGridPathsAgreeWithTheGeneralOnes) {
  // A disturbed flag with its grid layout (local step and gather over the grid's spring
  // families, a chunk of particles at a time) and without (per spring and per particle
  // incidence): the same step up to rounding; dropping a family or a side of the stencil,
  // or a row above a chunk, would move it by far more. At 70 wide the chunks of 2048
  // particles start and end inside rows; the narrow grid has many chunks, and the grids
  // without shear or bend springs have other families.
  struct Shape {
    Index width, height;
    bool shear, bend;
  };
  for (const Shape shape : {Shape{70, 70, true, true}, Shape{9, 500, true, true}, Shape{40, 120, false, true},
                            Shape{45, 100, true, false}}) {
    SCOPED_TRACE(std::to_string(shape.width) + " x " + std::to_string(shape.height));
    ClothGridSpec spec = flagSpec(shape.width);
    spec.height = shape.height;
    spec.shearSprings = shape.shear;
    spec.bendSprings = shape.bend;
    // The grid pinned at its first row's corners and disturbed, in precision S.
    const auto build = [&](auto zero) {
      using S = decltype(zero);
      ModelBuilder<S> builder;
      addClothGrid(builder, spec);
      builder.pin(gridIndex(spec, 0, 0));
      builder.pin(gridIndex(spec, 0, spec.width - 1));
      ModelAndState<S> cloth = builder.build();
      perturbFree(cloth.model, cloth.state, 0.01, 0.3, 62);
      return cloth;
    };
    const ModelAndState<double> grid = build(double(0));
    const ModelAndState<double> general = withoutGridLayout(grid);
    ASSERT_TRUE(grid.model.grid().has_value());
    ASSERT_FALSE(general.model.grid().has_value());
    SimulationOptions options = flagOptions(IntegratorKind::Projective, ForceStrategy::Gather, 2, 1.0 / 60);
    options.integration.projectiveIterations = 20;
    Simulation<double> a(ModelAndState<double>{grid.model, grid.state}, options);
    Simulation<double> b(ModelAndState<double>{general.model, general.state}, options);
    ASSERT_TRUE(a.run(3).ok()) << a.status().message();
    ASSERT_TRUE(b.run(3).ok()) << b.status().message();
    double moved = 0;
    for (Index i = 0; i < grid.model.particleCount(); ++i)
      for (int c = 0; c < 3; ++c) moved = std::max(moved, std::abs(a.state().x(i, c) - grid.state.x(i, c)));
    ASSERT_GT(moved, 1e-3);
    EXPECT_LT((a.state().x - b.state().x).cwiseAbs().maxCoeff(), 1e-9 * moved);
    EXPECT_LT((a.state().v - b.state().v).cwiseAbs().maxCoeff(), 1e-9 * moved * 60);
    // The grid path on 1 thread (one window for every chunk) and on 2 gives the same bits,
    // in double and in float.
    options.threads = 1;
    Simulation<double> one(ModelAndState<double>{grid.model, grid.state}, options);
    ASSERT_TRUE(one.run(3).ok()) << one.status().message();
    EXPECT_EQ(stateHash(one.state()), stateHash(a.state()));
    const ModelAndState<float> cloth = build(float(0));
    std::uint64_t hashes[2] = {0, 0};
    for (const int threads : {1, 2}) {
      options.threads = threads;
      Simulation<float> f(ModelAndState<float>{cloth.model, cloth.state}, options);
      ASSERT_TRUE(f.run(3).ok()) << f.status().message();
      hashes[threads - 1] = stateHash(f.state());
    }
    EXPECT_EQ(hashes[0], hashes[1]) << "float, 1 and 2 threads";
  }
}

TEST(ProjectiveDynamics, IterationsConvergeToBackwardEulerWithTheSpringsOwnDamping) {
  // A crumpled 10x10 cloth moving in all directions at a 1/60 s step with drag: the
  // springs are stretched, compressed and turned, and the damping along them is the
  // ForceField's (the matrix's isotropic dashpot is corrected at every iteration).
  ModelAndState<double> cloth = makeFlag<double>(10);
  perturbFree(cloth.model, cloth.state, 0.02, 0.3, 61);
  SimulationOptions options = flagOptions(IntegratorKind::Projective, ForceStrategy::Auto, 1, 1.0 / 60);
  options.effects.drag = 1e-4;
  double previous = std::numeric_limits<double>::infinity();
  for (const int iterations : {1, 10, 100, 1000, 4000}) {
    SCOPED_TRACE(iterations);
    const double residual = backwardEulerResidual(cloth, options, iterations);
    EXPECT_LT(residual, previous);
    previous = residual;
  }
  // (Measured: 0.99, 0.88, 0.18, 1.9e-4 and 1.6e-10 after 1, 10, 100, 1000 and 4000
  // iterations: the local/global iteration converges linearly, slowly on a cloth this
  // disturbed, but to backward Euler itself.)
  EXPECT_LT(previous, 1e-8) << "4000 iterations leave a relative residual of " << previous;
}

TEST(ProjectiveDynamics, StableFlagAtASixtiethIsTheSameOnOneAndTwoThreadsInBothPrecisions) {
  for (const int threads : {1, 2}) {
    SCOPED_TRACE(threads);
    SimulationOptions options = flagOptions(IntegratorKind::Projective, ForceStrategy::Auto, threads, 1.0 / 60);
    Simulation<double> sim(makeFlag<double>(24), options);
    ASSERT_TRUE(sim.run(120).ok()) << sim.status().message();  // two seconds, hanging and swinging
    EXPECT_TRUE(allFinite(sim.state()));
    EXPECT_EQ(sim.totalWork().factorizations, 1);
    EXPECT_LT(sim.lastWork().linearResidual, 0.1);
    // The flag hangs below its pins and has not been torn: the stability check's stretch
    // limit held on every step.
    EXPECT_LT(sim.state().x.col(1).minCoeff(), -0.3);
  }
  std::uint64_t hash[2][2];
  for (const int threads : {1, 2}) {
    SimulationOptions options = flagOptions(IntegratorKind::Projective, ForceStrategy::Auto, threads, 1.0 / 60);
    Simulation<float> f(makeFlag<float>(40), options);
    Simulation<double> d(makeFlag<double>(40), options);
    ASSERT_TRUE(f.run(20).ok() && d.run(20).ok());
    hash[0][threads - 1] = stateHash(f.state());
    hash[1][threads - 1] = stateHash(d.state());
  }
  EXPECT_EQ(hash[0][0], hash[0][1]) << "float";
  EXPECT_EQ(hash[1][0], hash[1][1]) << "double";
}

TEST(ProjectiveDynamics, KinematicPinsMoveAndTheCacheRefactorisesOnlyForNewSteps) {
  ModelAndState<double> flag = makeFlag<double>(12);
  SimulationOptions options = flagOptions(IntegratorKind::Projective, ForceStrategy::Auto, 1, 1.0 / 120);
  // A pin moving at constant velocity: the pinned rows follow it exactly.
  flag.state.v.row(0) << 0.5, 0, 0;
  Simulation<double> sim(std::move(flag), options);
  const double x0 = sim.state().x(0, 0);
  ASSERT_TRUE(sim.run(12).ok()) << sim.status().message();
  EXPECT_NEAR(sim.state().x(0, 0), x0 + 12 * 0.5 / 120, 1e-12);
  EXPECT_EQ(sim.state().v(0, 0), 0.5);
  sim.setTimeStep(1.0 / 240);
  ASSERT_TRUE(sim.run(2).ok());
  sim.setTimeStep(1.0 / 120);
  ASSERT_TRUE(sim.run(2).ok());
  EXPECT_EQ(sim.totalWork().factorizations, 2);  // 1/120 came back from the cache
  sim.setTimeStep(1.0 / 60);
  ASSERT_TRUE(sim.run(1).ok());
  sim.setTimeStep(1.0 / 240);  // evicted by 1/60 (two are kept): factorised again
  ASSERT_TRUE(sim.run(1).ok());
  EXPECT_EQ(sim.totalWork().factorizations, 4);
}

}  // namespace
}  // namespace weft::test
