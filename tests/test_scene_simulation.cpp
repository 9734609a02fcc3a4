// tests/test_scene_simulation.cpp — Simulation: bitwise determinism across thread counts and
// arenas, the stability check and failure handling, option validation, agreement with
// the textbook RK4 baseline.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <oneapi/tbb/task_arena.h>

#include <cmath>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "support/sanitizers.hpp"
#include "support/test_support.hpp"
#include "textbook.hpp"

namespace weft::test {
namespace {

// ---------------------------------------------------------------------------------------
// Bitwise determinism
// ---------------------------------------------------------------------------------------

template <class C>
class Determinism : public ::testing::Test {};
TYPED_TEST_SUITE(Determinism, AllConfigs, ConfigNames);

/// Side of the flag for the determinism runs: 40 x 40 = 1600 particles and ~9 000 springs
/// give every pass several blocks (kParticleGrain 1024, kSpringGrain 4096) and the grid
/// stencil several chunks, so two threads really split the work.
constexpr Index kFlagSize = 40;
constexpr int kSteps = 200;

struct RunResult {
  std::uint64_t hash = 0;
  StepStatus status;
  Index steps = 0;
  int threads = 0;
};

template <class S>
RunResult runFlag(const ModelAndState<S>& scene, IntegratorKind kind, ForceStrategy strategy, int threads,
                  tbb::task_arena* arena) {
  SimulationOptions options = flagOptions(kind, strategy, threads, defaultTimeStep(BuiltinScene::Flag, kFlagSize));
  if (kind == IntegratorKind::ExplicitEuler) options.dt /= 4;  // keep explicit Euler stable for the whole run
  options.arena = arena;
  Simulation<S> sim(ModelAndState<S>{scene.model, scene.state}, options);
  RunResult r;
  // rk45 (several substeps of 6 evaluations per step) and implicit Euler (tens of CG
  // iterations per step) do far more work per step: fewer steps keep the sanitizer runs short.
  const int steps = integratorIsExplicit(kind) && kind != IntegratorKind::Rk45 ? kSteps : kSteps / 4;
  r.status = sim.run(steps);
  r.steps = sim.stepCount();
  r.hash = stateHash(sim.state());
  r.threads = sim.threadCount();
  EXPECT_EQ(sim.forceStrategy(), strategy);
  return r;
}

TYPED_TEST(Determinism, StateHashIsTheSameForOneAndTwoThreadsAndAnExternalArena) {
  using S = typename TypeParam::Scalar;
  constexpr IntegratorKind kind = TypeParam::kIntegrator;
  ModelAndState<S> flag = makeFlag<S>(kFlagSize);
  perturbFree(flag.model, flag.state, 0.0, 0.05, 41);  // break the left-right symmetry
  tbb::task_arena arena(2);
  for (const ForceStrategy strategy : kGridStrategies) {
    SCOPED_TRACE(forceStrategyName(strategy));
    const RunResult one = runFlag(flag, kind, strategy, 1, nullptr);
    const RunResult two = runFlag(flag, kind, strategy, 2, nullptr);
    const RunResult external = runFlag(flag, kind, strategy, 0, &arena);
    ASSERT_TRUE(one.status.ok()) << one.status.message();
    EXPECT_EQ(one.steps, integratorIsExplicit(kind) && kind != IntegratorKind::Rk45 ? kSteps : kSteps / 4);
    EXPECT_EQ(one.threads, 1);
    EXPECT_EQ(two.threads, 2);
    EXPECT_EQ(external.threads, 2);
    EXPECT_TRUE(two.status.ok()) << two.status.message();
    EXPECT_TRUE(external.status.ok()) << external.status.message();
    EXPECT_EQ(one.hash, two.hash) << "threads 1 vs 2";
    EXPECT_EQ(one.hash, external.hash) << "threads 1 vs an external arena of 2";
  }
}

TYPED_TEST(Determinism, LargeFlagWithEveryPassSplitIntoBlocks) {
  using S = typename TypeParam::Scalar;
  constexpr IntegratorKind kind = TypeParam::kIntegrator;
  // Above 4096 particles the stability check (kGrain) has more than one block too, and
  // every force strategy several blocks and chunks; fewer steps keep it quick.
  constexpr Index size = 72;
  ASSERT_GT(size * size, StabilityCheck<S>::kGrain);
  ModelAndState<S> flag = makeFlag<S>(size);
  perturbFree(flag.model, flag.state, 0.0, 0.05, 42);
  for (const ForceStrategy strategy : {ForceStrategy::Gather, ForceStrategy::GridStencil}) {
    SCOPED_TRACE(forceStrategyName(strategy));
    SimulationOptions options = flagOptions(kind, strategy, 1, defaultTimeStep(BuiltinScene::Flag, size));
    if (kind == IntegratorKind::ExplicitEuler) options.dt /= 4;
    std::uint64_t hash[2] = {0, 0};
    for (const int threads : {1, 2}) {
      options.threads = threads;
      Simulation<S> sim(ModelAndState<S>{flag.model, flag.state}, options);
      const StepStatus status = sim.run(30);
      ASSERT_TRUE(status.ok()) << status.message();
      hash[threads - 1] = stateHash(sim.state());
    }
    EXPECT_EQ(hash[0], hash[1]);
  }
}

TYPED_TEST(Determinism, RepeatedRunsAreIdentical) {
  using S = typename TypeParam::Scalar;
  constexpr IntegratorKind kind = TypeParam::kIntegrator;
  // The default strategy, two threads, twice: no dependence on scheduling.
  const ModelAndState<S> flag = makeFlag<S>(kFlagSize);
  SimulationOptions options = flagOptions(kind, ForceStrategy::Auto, 2, defaultTimeStep(BuiltinScene::Flag, kFlagSize));
  if (kind == IntegratorKind::ExplicitEuler) options.dt /= 4;
  Simulation<S> a(ModelAndState<S>{flag.model, flag.state}, options);
  Simulation<S> b(ModelAndState<S>{flag.model, flag.state}, options);
  for (int k = 0; k < 5; ++k) {
    ASSERT_TRUE(a.run(10).ok());
    ASSERT_TRUE(b.run(10).ok());
    ASSERT_EQ(stateHash(a.state()), stateHash(b.state())) << "after " << a.stepCount() << " steps";
  }
}

// ---------------------------------------------------------------------------------------
// Stability check and failure handling
// ---------------------------------------------------------------------------------------

template <class S>
class SimulationTest : public ::testing::Test {};
TYPED_TEST_SUITE(SimulationTest, ScalarTypes);

/// Steps until the first failure (at most maxSteps); `before` is the state before the
/// failing step.
template <class S>
StepStatus stepUntilFailure(Simulation<S>& sim, int maxSteps, State<S>& before) {
  for (int k = 0; k < maxSteps; ++k) {
    before = sim.state();
    const StepStatus status = sim.step();
    if (!status.ok()) return status;
  }
  return StepStatus{};
}

template <class S>
void expectFailureHandled(Simulation<S>& sim, const StepStatus& failure, const State<S>& before) {
  const Model<S>& model = sim.model();
  ASSERT_FALSE(failure.ok()) << "the unstable run did not fail";
  EXPECT_TRUE(failure.code == StepCode::NonFinite || failure.code == StepCode::Overstretched)
      << stepCodeName(failure.code);
  EXPECT_GE(failure.particle, 0);
  EXPECT_LT(failure.particle, model.particleCount());
  if (failure.code == StepCode::Overstretched) {
    ASSERT_GE(failure.spring, 0);
    ASSERT_LT(failure.spring, model.springCount());
    const Index a = model.springs().a[failure.spring], b = model.springs().b[failure.spring];
    // The free endpoint (a pinned one is where the spring is held), else the lower index.
    const bool pa = model.isPinned(a), pb = model.isPinned(b);
    EXPECT_EQ(failure.particle, pa != pb ? (pa ? b : a) : std::min(a, b));
    EXPECT_GT(failure.value, sim.options().stability.maxStretch);
  } else {
    EXPECT_FALSE(std::isfinite(failure.value)) << failure.value;
  }
  EXPECT_EQ(failure.time, before.time);
  EXPECT_FALSE(failure.message().empty());
  EXPECT_EQ(sim.status().code, failure.code);

  // The state is the last good one: finite, and exactly what it was before the step.
  EXPECT_TRUE(allFinite(sim.state()));
  EXPECT_EQ(stateHash(sim.state()), stateHash(before));
  EXPECT_EQ(sim.state().time, before.time);

  // Further steps return the same failure without advancing (or evaluating anything).
  const Index steps = sim.stepCount();
  const std::int64_t evaluations = sim.forceEvaluationCount();
  for (int k = 0; k < 3; ++k) {
    const StepStatus again = sim.step();
    EXPECT_EQ(again.code, failure.code);
    EXPECT_EQ(again.particle, failure.particle);
    EXPECT_EQ(again.spring, failure.spring);
    EXPECT_EQ(again.time, failure.time);
  }
  EXPECT_EQ(sim.run(10).code, failure.code);
  EXPECT_EQ(sim.stepCount(), steps);
  EXPECT_EQ(sim.forceEvaluationCount(), evaluations);
  EXPECT_EQ(stateHash(sim.state()), stateHash(before));

  // setTimeStep clears the failure and stepping resumes.
  sim.setTimeStep(sim.timeStep() / 100);
  EXPECT_TRUE(sim.status().ok());
  (void)sim.step();
  EXPECT_GT(sim.forceEvaluationCount(), evaluations);
}

TYPED_TEST(SimulationTest, ExplicitEulerPastItsLimitOverstretchesAndStops) {
  using S = TypeParam;
  ModelAndState<S> flag = makeUndampedFlag<S>(16);
  const State<S> initial = flag.state;
  SimulationOptions options = flagOptions(IntegratorKind::ExplicitEuler, ForceStrategy::Auto, 2, 2e-3);
  Simulation<S> sim(std::move(flag), options);
  State<S> before;
  const StepStatus failure = stepUntilFailure(sim, 2000, before);
  // Springs stretch past 10x their rest length long before anything overflows.
  EXPECT_EQ(failure.code, StepCode::Overstretched) << failure.message();
  expectFailureHandled(sim, failure, before);
  // A good state brings it back to life.
  sim.setState(initial);
  sim.setTimeStep(1e-4);
  EXPECT_TRUE(sim.status().ok());
  EXPECT_TRUE(sim.step().ok());
}

TYPED_TEST(SimulationTest, WithoutTheStretchCheckTheFailureIsNonFinite) {
  using S = TypeParam;
  // The oscillator, undamped, far past explicit Euler's limit: the amplitude grows by
  // ~omega dt per step until it overflows; with the stretch check off, the finiteness
  // check must catch it. The overflowing spring force is NaN on both ends and the pinned
  // particle 0 gets 0 * NaN, but the report names where the instability is: the free
  // particle 1.
  Oscillator osc;
  osc.damping = 0;
  SimulationOptions options = osc.options(IntegratorKind::ExplicitEuler, 20.0 / osc.omega);
  options.stability.maxStretch = 0;
  Simulation<S> sim(osc.build<S>(), options);
  State<S> before;
  const StepStatus failure = stepUntilFailure(sim, 2000, before);
  ASSERT_EQ(failure.code, StepCode::NonFinite) << failure.message();
  EXPECT_EQ(failure.particle, 1) << failure.message();
  expectFailureHandled(sim, failure, before);
}

TYPED_TEST(SimulationTest, EveryIntegratorFailsCleanlyAtAHugeStep) {
  using S = TypeParam;
  for (const IntegratorKind kind : kAllIntegrators) {
    // Implicit Euler and projective dynamics are meant not to fail at any step
    // (ImplicitEuler.*, Projective.* tests), and adaptive
    // rk45 would substep its way through: here rk45 takes fixed steps.
    if (!integratorIsExplicit(kind)) continue;
    SCOPED_TRACE(integratorName(kind));
    ModelAndState<S> flag = makeFlag<S>(12);
    perturbFree(flag.model, flag.state, 0.0, 0.5, 51);
    SimulationOptions options = flagOptions(kind, ForceStrategy::Auto, 1, 1.0);
    options.integration.adaptive = false;
    Simulation<S> sim(std::move(flag), options);
    State<S> before;
    const StepStatus failure = stepUntilFailure(sim, 50, before);
    expectFailureHandled(sim, failure, before);
  }
}

// Implicit Euler past the precision's range: its right-hand side is not a number, and its
// CG, which stops when |r| <= tol |b|, would stop at once and leave the particles where
// they were, a step reported fine. It must fail as non-finite, as the explicit methods do,
// (or as overstretched, where a length overflows first) with every preconditioner, the same
// on 1 and 2 threads.
TYPED_TEST(SimulationTest, AnImplicitSolveOfNumbersPastTheRangeFails) {
  using S = TypeParam;
  const double dt = std::is_same_v<S, float> ? 1e19 : 1e100;
  for (const Preconditioner p :
       {Preconditioner::Jacobi, Preconditioner::BlockJacobi, Preconditioner::Multigrid, Preconditioner::Auto}) {
    std::uint64_t hash[2] = {0, 0};
    for (const int threads : {1, 2}) {
      SCOPED_TRACE(std::string(preconditionerName(p)) + ", " + std::to_string(threads) + " thread(s)");
      ModelAndState<S> flag = makeFlag<S>(12);
      SimulationOptions options = flagOptions(IntegratorKind::ImplicitEuler, ForceStrategy::Auto, threads, dt);
      options.integration.preconditioner = p;
      Simulation<S> sim(std::move(flag), options);
      const State<S> before = sim.state();
      const StepStatus failure = sim.step();
      ASSERT_FALSE(failure.ok()) << "the step past the range was taken for a good one";
      expectFailureHandled(sim, failure, before);  // non-finite or overstretched, and where
      hash[threads - 1] = stateHash(sim.state());
    }
    EXPECT_EQ(hash[0], hash[1]);
  }
}

TYPED_TEST(SimulationTest, FailureReportIsTheSameForAnyThreadCount) {
  using S = TypeParam;
  // Several blocks in both checks (5184 particles, ~30 000 springs): the report names the
  // lowest failing index whichever block found it first.
  const ModelAndState<S> flag = makeUndampedFlag<S>(72);
  StepStatus failure[2];
  Index steps[2] = {0, 0};
  std::uint64_t hash[2] = {0, 0};
  for (const int threads : {1, 2}) {
    Simulation<S> sim(ModelAndState<S>{flag.model, flag.state},
                      flagOptions(IntegratorKind::ExplicitEuler, ForceStrategy::Auto, threads, 5e-4));
    State<S> before;
    failure[threads - 1] = stepUntilFailure(sim, 500, before);
    steps[threads - 1] = sim.stepCount();
    hash[threads - 1] = stateHash(sim.state());
  }
  ASSERT_FALSE(failure[0].ok());
  EXPECT_EQ(failure[0].code, failure[1].code);
  EXPECT_EQ(failure[0].particle, failure[1].particle);
  EXPECT_EQ(failure[0].spring, failure[1].spring);
  EXPECT_EQ(failure[0].value, failure[1].value);
  EXPECT_EQ(failure[0].time, failure[1].time);
  EXPECT_EQ(steps[0], steps[1]);
  EXPECT_EQ(hash[0], hash[1]);
}

TYPED_TEST(SimulationTest, DisabledStabilityCheckNeverFails) {
  using S = TypeParam;
  Oscillator osc;
  osc.damping = 0;
  SimulationOptions options = osc.options(IntegratorKind::ExplicitEuler, 20.0 / osc.omega);
  options.stability.enabled = false;
  Simulation<S> sim(osc.build<S>(), options);
  EXPECT_TRUE(sim.run(500).ok());
  EXPECT_EQ(sim.stepCount(), 500);
  EXPECT_FALSE(allFinite(sim.state()));  // which is what the check is there to prevent
}

TYPED_TEST(SimulationTest, SetStateRejectsNonFiniteAndMismatchedStates) {
  using S = TypeParam;
  Simulation<S> sim(makeFlag<S>(8), flagOptions(IntegratorKind::Rk4, ForceStrategy::Auto, 1, 1e-4));
  ASSERT_TRUE(sim.run(3).ok());
  const std::uint64_t hash = stateHash(sim.state());

  const auto refusal = [&](const State<S>& state) -> std::string {
    try {
      sim.setState(state);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "accepted";
  };
  State<S> bad = sim.state();
  bad.x(5, 1) = std::numeric_limits<S>::quiet_NaN();
  EXPECT_EQ(refusal(bad), "Simulation::setState: state.x(5, 1) must be finite, got nan");
  bad = sim.state();
  bad.v(7, 2) = std::numeric_limits<S>::infinity();
  EXPECT_EQ(refusal(bad), "Simulation::setState: state.v(7, 2) must be finite, got inf");
  bad = sim.state();  // finite in float and double, but faster than light
  bad.v(4, 0) = S(1e30);
  EXPECT_THAT(refusal(bad), ::testing::StartsWith("Simulation::setState: state.v(4) must be a speed of at most "
                                                  "299792458 m/s (the speed of light), got (1"));
  // Positions beyond what the precision simulates: squares of distances that overflow, and
  // (in float) a cloth moved so far that rounding changes its springs' lengths by more than
  // a tenth: the 8x8 flag's 1/7 m spacing reaches 69 km in float, 3.7e13 m in double).
  bad = sim.state();
  bad.x(3, 2) = S(sizeof(S) == sizeof(float) ? 2e18 : 2e150);
  EXPECT_THAT(refusal(bad), ::testing::StartsWith("Simulation::setState: state.x(3, 2) must be within +-"));
  bad = sim.state();
  for (Index i = 0; i < bad.x.rows(); ++i) bad.x(i, 0) += S(sizeof(S) == sizeof(float) ? 1e5 : 1e14);
  EXPECT_THAT(refusal(bad), ::testing::StartsWith("Simulation::setState: the largest |coordinate| of the ends of "
                                                  "spring ["));
  // The clock drives kinematic pins and the wind: a clock that is not a number is refused too.
  for (const double time : {std::nan(""), std::numeric_limits<double>::infinity(), -HUGE_VAL}) {
    bad = sim.state();
    bad.time = time;
    EXPECT_THAT(refusal(bad), ::testing::StartsWith("Simulation::setState: state.time must be finite (s), got "));
  }
  State<S> small;
  small.x = Vec3Array<S>::Zero(3, 3);
  small.v = Vec3Array<S>::Zero(3, 3);
  try {
    sim.setState(small);
    FAIL() << "a state of the wrong size was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("3"), std::string::npos) << e.what();
  }
  EXPECT_EQ(stateHash(sim.state()), hash) << "a rejected state must leave the simulation alone";
  EXPECT_TRUE(sim.step().ok());
  State<S> moved = sim.state();  // far, but within the reach
  for (Index i = 0; i < moved.x.rows(); ++i) moved.x(i, 0) += S(sizeof(S) == sizeof(float) ? 1e3 : 1e11);
  EXPECT_EQ(refusal(moved), "accepted");
  EXPECT_TRUE(sim.step().ok());
}

// Between a hundredth and a tenth of a spring's rest length of rounding, a run goes on but
// warnings() says how much (the 8x8 flag's 1/7 m spacing: 1 % at 6.9 km from the origin in
// float, 3.7e12 m in double).
TYPED_TEST(SimulationTest, WarnsOfSpringsRoundingChangesByMoreThanAPercent) {
  using S = TypeParam;
  const bool single = sizeof(S) == sizeof(float);
  Simulation<S> sim(makeFlag<S>(8), flagOptions(IntegratorKind::Rk4, ForceStrategy::Auto, 1, 1e-4));
  EXPECT_TRUE(sim.warnings().empty());
  const State<S> start = sim.state();
  const auto movedBy = [&](double offset) {
    State<S> moved = start;
    for (Index i = 0; i < moved.x.rows(); ++i) moved.x(i, 0) += S(offset);
    sim.setState(moved);
    EXPECT_TRUE(sim.step().ok());
    return sim.warnings();
  };
  EXPECT_TRUE(movedBy(single ? 6e3 : 3e12).empty());
  const double far = single ? 2e4 : 1e13;
  State<S> moved = start;
  for (Index i = 0; i < moved.x.rows(); ++i) moved.x(i, 0) += S(far);
  sim.setState(moved);
  const std::vector<std::string> before = sim.warnings();
  EXPECT_TRUE(sim.step().ok());
  const std::vector<std::string> w = sim.warnings();
  EXPECT_EQ(w, before);
  ASSERT_EQ(w.size(), 1u);
  // The worst spring: a structural one (the shortest) at the far end of the flag.
  const double share = std::sqrt(3.0) * static_cast<double>(std::numeric_limits<S>::epsilon()) * 7 *
                       static_cast<double>(sim.state().x.col(0).cwiseAbs().maxCoeff());
  EXPECT_GT(share, 0.01);
  EXPECT_LT(share, 0.1);
  EXPECT_THAT(w[0], ::testing::StartsWith("spring "));
  // (The run stayed where its start was: the start's line, as before the step, so that a
  // caller comparing the lines before and after a run sees nothing new.)
  EXPECT_THAT(w[0], ::testing::HasSubstr(std::string(" m from the origin at the start, where rounding to ") +
                                         (single ? "float" : "double") + " can change its length by "));
  EXPECT_THAT(w[0], ::testing::HasSubstr(" % of its rest length (more than 1 %): lengths, stretches and forces are "
                                         "that much less accurate; use double precision or build the model nearer "
                                         "the origin"));
  const std::string by = "can change its length by ";
  const size_t at = w[0].find(by);
  ASSERT_NE(at, std::string::npos);
  EXPECT_NEAR(std::stod(w[0].substr(at + by.size())), 100 * share, 1e-4 * 100 * share) << w[0];
  // Back near the origin: nothing to say.
  EXPECT_TRUE(movedBy(0).empty());

  // A spring that starts short of a percent and is carried past it: said as it is now; one
  // that starts past it and is carried a quarter further: both.
  const auto carried = [&](double x0) {
    ModelBuilder<S> b;
    const double speed = single ? 1e5 : 1e8, dt = single ? 1e-3 : 250;
    b.addParticle({x0, 0, 0}, 1, {speed, 0, 0});
    b.addParticle({x0 + 0.1, 0, 0}, 1, {speed, 0, 0});
    b.addSpring(0, 1, {1e-6, 0});
    SimulationOptions options;
    options.integrator = IntegratorKind::SymplecticEuler;
    options.dt = dt;
    options.gravity = {0, 0, 0};
    options.threads = 1;
    Simulation<S> flying(b.build(), options);
    const std::vector<std::string> before = flying.warnings();
    for (int k = 0; k < 40; ++k) EXPECT_TRUE(flying.step().ok());  // 4 km in float, 1e12 m in double
    return std::pair(before, flying.warnings());
  };
  const auto [shortBefore, shortAfter] = carried(single ? 4e3 : 2.5e12);
  EXPECT_TRUE(shortBefore.empty());
  ASSERT_EQ(shortAfter.size(), 1u);
  EXPECT_THAT(shortAfter[0], ::testing::StartsWith("spring 0 (particles 0 and 1, rest length 0.1"));
  EXPECT_THAT(shortAfter[0], ::testing::HasSubstr(" m from the origin, where rounding to "));
  EXPECT_THAT(shortAfter[0], ::testing::Not(::testing::HasSubstr("at the start")));
  const auto [pastBefore, pastAfter] = carried(single ? 6e3 : 3e12);
  ASSERT_EQ(pastBefore.size(), 1u);
  EXPECT_THAT(pastBefore[0], ::testing::HasSubstr(" m from the origin at the start, where rounding to "));
  ASSERT_EQ(pastAfter.size(), 1u);
  EXPECT_THAT(pastAfter[0], ::testing::HasSubstr(" of its rest length; and spring 0 (particles 0 and 1"));
  EXPECT_THAT(pastAfter[0], ::testing::HasSubstr(") is "));
}

// A spring pulled past twice its rest length (short of the check's 10x, so the run goes on)
// is said after a step, naming the longest and the likelier cause for the integrator; not
// before any step, and not for a flag that hangs as it should.
TYPED_TEST(SimulationTest, WarnsOfASpringPulledPastTwiceItsRestLength) {
  using S = TypeParam;
  for (const IntegratorKind kind : {IntegratorKind::Rk4, IntegratorKind::Projective, IntegratorKind::ImplicitEuler}) {
    SCOPED_TRACE(integratorName(kind));
    Simulation<S> sim(makeFlag<S>(8), flagOptions(kind, ForceStrategy::Auto, 1, 1e-4));
    for (int k = 0; k < 10; ++k) ASSERT_TRUE(sim.step().ok());
    EXPECT_TRUE(sim.warnings().empty());
    // The free corner moved 0.5 m off the flag's plane: its springs are 3-5x their rest length.
    State<S> pulled = sim.state();
    const Index corner = pulled.x.rows() - 1;
    ASSERT_FALSE(sim.model().isPinned(corner));
    pulled.x(corner, 2) += S(0.5);
    sim.setState(pulled);
    EXPECT_TRUE(sim.warnings().empty());  // (no step since: the start is the user's)
    ASSERT_TRUE(sim.step().ok());
    const std::vector<std::string> w = sim.warnings();
    ASSERT_EQ(w.size(), 1u);
    EXPECT_THAT(w[0], ::testing::StartsWith("spring "));
    const std::string named = "and " + std::to_string(corner) + ") is ";
    const size_t at = w[0].find(named);
    ASSERT_NE(at, std::string::npos) << w[0];
    const double ratio = std::stod(w[0].substr(at + named.size()));
    EXPECT_GT(ratio, 3);
    EXPECT_LT(ratio, 10);
    EXPECT_THAT(w[0], ::testing::HasSubstr(" x its rest length now (the longest; more than 2 x)"));
    // (Projective dynamics converged here: the iterations are not blamed.)
    EXPECT_THAT(w[0],
                ::testing::HasSubstr(kind == IntegratorKind::Rk4 ? "explicit method" : "reduce dt (now 0.0001 s)"));
    if (kind != IntegratorKind::Rk4) {
      EXPECT_THAT(w[0], ::testing::Not(::testing::HasSubstr("iterations")));
    }
    // Put back: nothing to say after a step.
    pulled.x(corner, 2) -= S(0.5);
    sim.setState(pulled);
    ASSERT_TRUE(sim.step().ok());
    EXPECT_TRUE(sim.warnings().empty());
  }
  // Projective dynamics far from converged (one iteration: its correction is all of the
  // step's displacement): the iterations are named, with the last one's change.
  SimulationOptions o = flagOptions(IntegratorKind::Projective, ForceStrategy::Auto, 1, 1e-4);
  o.integration.projectiveIterations = 1;
  Simulation<S> sim(makeFlag<S>(8), o);
  State<S> pulled = sim.state();
  pulled.x(pulled.x.rows() - 1, 2) += S(0.5);
  sim.setState(pulled);
  ASSERT_TRUE(sim.step().ok());
  const std::vector<std::string> w = sim.warnings();
  ASSERT_EQ(w.size(), 1u);
  EXPECT_GT(sim.lastWork().linearResidual, Simulation<S>::kUnconvergedProjective);
  EXPECT_THAT(w[0],
              ::testing::HasSubstr("projective dynamics with 1 iterations leaves a stiff cloth softer than it is"));
  EXPECT_THAT(w[0],
              ::testing::HasSubstr("raise the iterations (IntegratorOptions::projectiveIterations, --pd-iterations)"));
}

// A chain of ten 1 g beads 10 cm apart on springs of `stiffness` N/m, the first pinned,
// stepped by rk45 (adaptive or not) at dt, on one thread.
template <class S>
Simulation<S> rk45BeadChain(double stiffness, bool adaptive, double dt) {
  ModelBuilder<S> b;
  for (int i = 0; i < 10; ++i) b.addParticle({0.1 * i, 0, 0}, 1e-3);
  for (int i = 0; i + 1 < 10; ++i) b.addSpring(i, i + 1, {stiffness, 0});
  b.pin(0);
  SimulationOptions options;
  options.integrator = IntegratorKind::Rk45;
  options.integration.adaptive = adaptive;
  options.dt = dt;
  options.threads = 1;
  return Simulation<S>(b.build(), options);
}

// Adaptive rk45 on a stiff model says so: the chain on springs of 1e6 N/m (the stiffest
// mode near 6e4 rad/s, a stable substep near 5e-5 s) stepped by 10 ms takes some 450
// substeps a step; the same chain on springs of 10 N/m takes a few, and says nothing.
TYPED_TEST(SimulationTest, Rk45OnAStiffModelSaysSo) {
  using S = TypeParam;
  const auto run = [](double stiffness, bool adaptive) {
    Simulation<S> sim = rk45BeadChain<S>(stiffness, adaptive, adaptive ? 1e-2 : 1e-5);
    // (Before the first step only the forecast can be said: the test below.)
    for (const std::string& w : sim.warnings()) EXPECT_THAT(w, ::testing::StartsWith("rk45 will take at least "));
    for (int k = 0; k < 5; ++k) EXPECT_TRUE(sim.step().ok()) << sim.status().message();
    const double perStep = static_cast<double>(sim.totalWork().substeps) / 5;
    return std::pair(perStep, sim.warnings());
  };
  const auto [stiffSubsteps, stiff] = run(1e6, true);
  EXPECT_GE(stiffSubsteps, Simulation<S>::kStiffSubsteps);
  ASSERT_EQ(stiff.size(), 1u);
  EXPECT_THAT(stiff[0], ::testing::StartsWith("rk45 took "));
  EXPECT_THAT(stiff[0], ::testing::HasSubstr(" substeps a step on average (a mean substep of "));
  EXPECT_THAT(stiff[0], ::testing::HasSubstr("within 4x of its stability limit on the stiffest spring, "));
  EXPECT_THAT(stiff[0], ::testing::HasSubstr("implicit Euler (integrator implicit) or projective dynamics"));
  const auto [softSubsteps, soft] = run(10, true);
  EXPECT_LT(softSubsteps, Simulation<S>::kStiffSubsteps);
  EXPECT_TRUE(soft.empty()) << soft.front();
  // Fixed steps (no error control) choose nothing: nothing to say.
  EXPECT_TRUE(run(1e6, false).second.empty());
}

TYPED_TEST(SimulationTest, Rk45OnAVeryStiffModelSaysSoBeforeTheFirstStep) {
  using S = TypeParam;
  const auto simulation = [](double stiffness, bool adaptive) { return rk45BeadChain<S>(stiffness, adaptive, 1e-2); };
  // At 1e7 N/m a step needs at least dt / (4 x the stability limit) substeps: said before
  // the first step, with that count, which the step then takes (about 3.3x as many here).
  Simulation<S> sim = simulation(1e7, true);
  const double limit = estimateStableTimeStep(sim.model(), IntegratorKind::Rk45);
  const double least = std::floor(1e-2 / (4 * limit));
  ASSERT_GE(least, Simulation<S>::kStiffSubsteps);
  const std::vector<std::string> before = sim.warnings();
  ASSERT_EQ(before.size(), 1u);
  std::ostringstream count;
  count << "rk45 will take at least " << least << " substeps a step (dt 0.01 s against a stability limit";
  EXPECT_THAT(before[0], ::testing::StartsWith(count.str()));
  EXPECT_THAT(before[0], ::testing::HasSubstr("implicit Euler (integrator implicit) or projective dynamics"));
  ASSERT_TRUE(sim.step().ok()) << sim.status().message();
  EXPECT_GE(static_cast<double>(sim.totalWork().substeps), least);
  // After a step the line says what the steps took instead.
  const std::vector<std::string> after = sim.warnings();
  ASSERT_EQ(after.size(), 1u);
  EXPECT_THAT(after[0], ::testing::StartsWith("rk45 took "));
  // A model the bound does not call stiff, or fixed steps: nothing before the first step.
  EXPECT_TRUE(simulation(1e5, true).warnings().empty());
  EXPECT_TRUE(simulation(1e7, false).warnings().empty());
}

TYPED_TEST(SimulationTest, RunCountsStepsTimeAndWork) {
  using S = TypeParam;
  for (const IntegratorKind kind : kAllIntegrators) {
    SCOPED_TRACE(integratorName(kind));
    Simulation<S> sim(makeFlag<S>(8), flagOptions(kind, ForceStrategy::Auto, 1, 1e-4));
    EXPECT_EQ(sim.integrator(), kind);
    EXPECT_EQ(sim.forceStrategy(), ForceStrategy::GridStencil);  // Auto on a grid
    ASSERT_TRUE(sim.run(25).ok());
    EXPECT_EQ(sim.stepCount(), 25);
    EXPECT_NEAR(sim.state().time, 25 * 1e-4, 1e-15);
    const StepWork& last = sim.lastWork();
    const StepWork& total = sim.totalWork();
    if (kind == IntegratorKind::Rk45) {
      // Six evaluations per trial substep; the first substep of the run also evaluates A_1.
      EXPECT_EQ(last.forceEvaluations, 6 * (last.substeps + last.rejectedSubsteps));
      EXPECT_EQ(total.forceEvaluations, 6 * (total.substeps + total.rejectedSubsteps) + 1);
      EXPECT_GE(total.substeps, 25);
    } else {
      EXPECT_EQ(last.forceEvaluations, integratorForceEvaluations(kind));
      // Verlet evaluates a0 once on its first step.
      EXPECT_EQ(sim.forceEvaluationCount(),
                25 * last.forceEvaluations + (kind == IntegratorKind::VelocityVerlet ? 1 : 0));
      EXPECT_EQ(total.substeps, 25);
    }
    EXPECT_EQ(total.linearIterations > 0, !integratorIsExplicit(kind));
    if (kind == IntegratorKind::Projective) {
      // One global solve per iteration; the matrix factorised once for the run's step.
      EXPECT_EQ(total.linearIterations, 25 * IntegratorOptions{}.projectiveIterations);
      EXPECT_EQ(total.factorizations, 1);
    } else {
      EXPECT_EQ(total.factorizations, 0);
    }
    // Gravity pulls the free particles down; the pinned corners stay.
    EXPECT_LT(sim.state().x.col(1).minCoeff(), S(0));
    EXPECT_EQ(sim.state().x(0, 1), S(0));
  }
}

TYPED_TEST(SimulationTest, SharesItsModel) {
  using S = TypeParam;
  ModelAndState<S> flag = makeFlag<S>(8);
  auto model = std::make_shared<const Model<S>>(std::move(flag.model));
  SimulationOptions options = flagOptions(IntegratorKind::Rk4, ForceStrategy::Auto, 1, 1e-4);
  Simulation<S> a(model, flag.state, options);
  Simulation<S> b(model, flag.state, options);
  EXPECT_EQ(&a.model(), &b.model());
  ASSERT_TRUE(a.run(5).ok());
  ASSERT_TRUE(b.run(5).ok());
  EXPECT_EQ(stateHash(a.state()), stateHash(b.state()));
  EXPECT_THROW(Simulation<S>(std::shared_ptr<const Model<S>>(), flag.state, options), std::invalid_argument);
}

TYPED_TEST(SimulationTest, ASecondSimulationOnTheSameModelDerivesNothing) {
  using S = TypeParam;
  // A cloth grid after a lone particle: its triangles are no grid's, so wind gathers
  // through the particle -> triangle lists; gather and coloured forces and implicit
  // Euler's Jacobian read the spring lists and the colouring.
  ModelBuilder<S> builder;
  builder.addParticle({0, 2, 0}, 0.1);
  ClothGridSpec spec;
  spec.width = spec.height = 8;
  spec.spacing = 0.05;
  addClothGrid(builder, spec);
  ModelAndState<S> built = builder.build();
  auto model = std::make_shared<const Model<S>>(std::move(built.model));
  std::vector<SimulationOptions> variants;
  for (ForceStrategy strategy : {ForceStrategy::Gather, ForceStrategy::Coloured})
    for (IntegratorKind integrator : {IntegratorKind::Rk4, IntegratorKind::ImplicitEuler}) {
      SimulationOptions o;
      o.dt = 1e-3;
      o.threads = 1;
      o.forceStrategy = strategy;
      o.integrator = integrator;
      o.effects.wind.enabled = true;
      o.effects.wind.velocity = {3, 0, 1};
      variants.push_back(o);
    }
  std::vector<std::uint64_t> hashes;
  for (const SimulationOptions& o : variants) {
    Simulation<S> sim(model, built.state, o);
    ASSERT_TRUE(sim.run(3).ok());
    hashes.push_back(stateHash(sim.state()));
  }
  const int derived = model->derivedBuildCount();
  EXPECT_GE(derived, 4) << "spring and triangle lists, colouring, grid check";
  for (size_t k = 0; k < variants.size(); ++k) {
    Simulation<S> again(model, built.state, variants[k]);
    EXPECT_EQ(model->derivedBuildCount(), derived) << "variant " << k << " derived something again";
    ASSERT_TRUE(again.run(3).ok());
    EXPECT_EQ(stateHash(again.state()), hashes[k]) << "variant " << k;
  }
}

// ---------------------------------------------------------------------------------------
// Bad options
// ---------------------------------------------------------------------------------------

template <class S>
void expectBadOptions(const SimulationOptions& options, const std::string& field, const std::string& value) {
  try {
    Simulation<S> sim(makeFlag<S>(4), options);
    ADD_FAILURE() << "accepted bad " << field << " = " << value;
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(field), std::string::npos) << what;
    EXPECT_NE(what.find(value), std::string::npos) << what;
  }
}

TYPED_TEST(SimulationTest, BadOptionsThrowNamingTheField) {
  using S = TypeParam;
  SimulationOptions o;
  o.threads = 1;
  o.dt = 0;
  expectBadOptions<S>(o, "dt", "0");
  o.dt = -1;
  expectBadOptions<S>(o, "dt", "-1");
  o.dt = std::numeric_limits<double>::quiet_NaN();
  expectBadOptions<S>(o, "dt", "nan");
  o.dt = std::numeric_limits<double>::infinity();
  expectBadOptions<S>(o, "dt", "inf");
  o.dt = -1e-9;  // (written as the value the user gave, not "-0.000000")
  expectBadOptions<S>(o, "dt", "got -1e-09");
  // A step the model's precision cannot hold: in float, 1e39 would step by infinity and
  // 1e-46 by zero.
  if constexpr (sizeof(S) == sizeof(float)) {
    o.dt = 1e39;
    expectBadOptions<S>(o, "SimulationOptions.dt must be within the range of float precision", "got 1e+39");
    o.dt = 1e-46;
    expectBadOptions<S>(o, "SimulationOptions.dt must be within the range of float precision", "got 1e-46");
  }
  o.dt = 1e-3;
  o.threads = -1;
  expectBadOptions<S>(o, "threads", "-1");
  o.threads = 1;
  o.gravity = {0, std::numeric_limits<double>::quiet_NaN(), 0};
  expectBadOptions<S>(o, "gravity", "got (0, nan, 0)");
  o.gravity = {0, -9.81, 0};
  o.stability.maxStretch = std::numeric_limits<double>::quiet_NaN();
  expectBadOptions<S>(o, "SimulationOptions.stability.maxStretch", "got nan");
  o.stability.maxStretch = 0.5;  // (a spring at rest would fail every step)
  expectBadOptions<S>(o, "SimulationOptions.stability.maxStretch", "got 0.5");
}

TYPED_TEST(SimulationTest, BadTimeStepIsRejectedAndKeepsTheOldOne) {
  using S = TypeParam;
  Simulation<S> sim(makeFlag<S>(4), flagOptions(IntegratorKind::Rk4, ForceStrategy::Auto, 1, 1e-4));
  for (const double dt : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                          sizeof(S) == 4 ? 1e39 : std::numeric_limits<double>::infinity()}) {
    try {
      sim.setTimeStep(dt);
      ADD_FAILURE() << "accepted dt " << dt;
    } catch (const std::invalid_argument& e) {
      EXPECT_THAT(e.what(), ::testing::StartsWith("Simulation::setTimeStep: dt must be "));
    }
  }
  EXPECT_EQ(sim.timeStep(), 1e-4);
}

TYPED_TEST(SimulationTest, GridStencilOnARopeIsRejected) {
  using S = TypeParam;
  EXPECT_THROW(Simulation<S>(makeRope<S>(8), flagOptions(IntegratorKind::Rk4, ForceStrategy::GridStencil, 1, 1e-4)),
               std::invalid_argument);
}

TYPED_TEST(SimulationTest, ExternalArenaIsUsed) {
  using S = TypeParam;
  tbb::task_arena arena(2);
  SimulationOptions options = flagOptions(IntegratorKind::Rk4, ForceStrategy::Auto, 1, 1e-4);
  options.arena = &arena;  // `threads` is then ignored
  Simulation<S> sim(makeFlag<S>(8), options);
  EXPECT_EQ(sim.threadCount(), 2);
  EXPECT_TRUE(sim.run(5).ok());
}

// ---------------------------------------------------------------------------------------
// Agreement with the textbook RK4 baseline
// ---------------------------------------------------------------------------------------

struct TextbookCase {
  Index size;
  ForceStrategy strategy;
  double tolerance;  // on positions (m) and velocities (m/s)
};

class TextbookAgreement : public ::testing::TestWithParam<TextbookCase> {};

TEST_P(TextbookAgreement, Rk4MatchesTheTextbookClothInDouble) {
  const TextbookCase c = GetParam();
  if (c.size >= 128) WEFT_SKIP_UNDER_TSAN("the smaller sizes run the same passes on the same threads");
  const Vec3d gravity{0, -9.81, 0};
  const double dt = defaultTimeStep(BuiltinScene::Flag, c.size);
  const int steps = 100;
  ModelAndState<double> flag = makeFlag<double>(c.size);
  textbook::Cloth cloth(flag.model, flag.state, gravity);
  SimulationOptions options = flagOptions(IntegratorKind::Rk4, c.strategy, 2, dt);
  options.gravity = gravity;
  Simulation<double> sim(std::move(flag), options);
  ASSERT_TRUE(sim.run(steps).ok());
  for (int k = 0; k < steps; ++k) cloth.stepRk4(dt);

  double dx = 0, dv = 0, moved = 0;
  const State<double>& s = sim.state();
  for (Index i = 0; i < s.particleCount(); ++i) {
    const textbook::Particle& p = cloth.particles()[i];
    dx = std::max({dx, std::abs(s.x(i, 0) - p.x.x), std::abs(s.x(i, 1) - p.x.y), std::abs(s.x(i, 2) - p.x.z)});
    dv = std::max({dv, std::abs(s.v(i, 0) - p.v.x), std::abs(s.v(i, 1) - p.v.y), std::abs(s.v(i, 2) - p.v.z)});
    moved = std::max(moved, std::abs(s.x(i, 1)));
  }
  EXPECT_LE(dx, c.tolerance) << "max |x_weft - x_textbook|";
  EXPECT_LE(dv, c.tolerance) << "max |v_weft - v_textbook|";
  EXPECT_GT(moved, 1e-4) << "the flag did not fall: the comparison would be vacuous";
}

INSTANTIATE_TEST_SUITE_P(Flag, TextbookAgreement,
                         // Both take |dx| as the correctly rounded sqrt, so they differ only by
                         // the rounding of the remaining products (weft multiplies by 1/|dx|,
                         // the textbook divides). 128 is the benchmark's size.
                         ::testing::Values(TextbookCase{16, ForceStrategy::Gather, 1e-12},
                                           TextbookCase{16, ForceStrategy::Coloured, 1e-12},
                                           TextbookCase{16, ForceStrategy::GridStencil, 1e-12},
                                           TextbookCase{64, ForceStrategy::Auto, 1e-12},
                                           TextbookCase{128, ForceStrategy::Auto, 1e-12}),
                         [](const auto& info) {
                           std::string name = std::string("size") + std::to_string(info.param.size) + "_" +
                                              forceStrategyName(info.param.strategy);
                           for (char& ch : name)
                             if (ch == '-') ch = '_';
                           return name;
                         });

}  // namespace
}  // namespace weft::test

// ---------------------------------------------------------------------------------------
// Fixed-step clock
// ---------------------------------------------------------------------------------------

namespace weft::test {
namespace {

/// Drives the rope with the given frame times until the frame time reaches `total`
/// (the last frame trimmed to land on it); returns the state's hash and step count.
template <class S, class NextFrame>
std::pair<std::uint64_t, Index> driveRope(double total, NextFrame nextFrame) {
  SimulationOptions options;
  options.integrator = IntegratorKind::Rk4;
  options.dt = 1e-3;
  options.threads = 2;
  Simulation<S> sim(makeRope<S>(32), options);
  FixedStepClock<S> clock(sim);
  while (clock.frameTime() < total) {
    const double frame = std::min(nextFrame(), total - clock.frameTime());
    EXPECT_TRUE(clock.advance(frame).ok());
    EXPECT_GE(clock.alpha(), 0.0);
    EXPECT_LT(clock.alpha(), 1.0);
  }
  EXPECT_EQ(clock.stepsTaken(), sim.stepCount());
  EXPECT_EQ(clock.droppedTime(), 0.0);
  return {stateHash(sim.state()), sim.stepCount()};
}

TYPED_TEST(SimulationTest, FixedStepClockGivesTheSameStateForAnyFrameRate) {
  using S = TypeParam;
  // 1 s + half a step: the step count (1000) is then far from a rounding boundary.
  const double total = 1.0 + 0.5e-3;
  const auto at30 = driveRope<S>(total, [] { return 1.0 / 30; });
  const auto at144 = driveRope<S>(total, [] { return 1.0 / 144; });
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(0.0, 0.05);  // 0 to 50 ms (< 64 steps), tiny frames too
  const auto jittery = driveRope<S>(total, [&] { return jitter(rng); });
  EXPECT_EQ(at30.second, 1000);
  EXPECT_EQ(at144.second, 1000);
  EXPECT_EQ(jittery.second, 1000);
  EXPECT_EQ(at30.first, at144.first);
  EXPECT_EQ(at30.first, jittery.first);
  // And it is the state of 1000 plain steps.
  SimulationOptions options;
  options.integrator = IntegratorKind::Rk4;
  options.dt = 1e-3;
  options.threads = 1;
  Simulation<S> plain(makeRope<S>(32), options);
  ASSERT_TRUE(plain.run(1000).ok());
  EXPECT_EQ(stateHash(plain.state()), at30.first);
}

TYPED_TEST(SimulationTest, FixedStepClockInterpolatesBetweenTheLastTwoSteps) {
  using S = TypeParam;
  SimulationOptions options;
  options.dt = 1e-3;
  options.threads = 1;
  Simulation<S> sim(makeRope<S>(16), options);
  FixedStepClock<S> clock(sim);
  Vec3Array<S> shown;
  clock.interpolatedPositions(shown);
  EXPECT_TRUE(shown == sim.state().x) << "before any step: the state itself";
  ASSERT_TRUE(clock.advance(0.0035).ok());  // 3 steps, 0.5 step carried
  EXPECT_EQ(sim.stepCount(), 3);
  EXPECT_NEAR(clock.alpha(), 0.5, 1e-9);
  const State<S> after3 = sim.state();
  ASSERT_TRUE(clock.advance(0.0).ok());
  clock.interpolatedPositions(shown);
  // Halfway between step 2 and step 3.
  SimulationOptions again = options;
  Simulation<S> replay(makeRope<S>(16), again);
  ASSERT_TRUE(replay.run(2).ok());
  const Vec3Array<S> expected = S(0.5) * replay.state().x + S(0.5) * after3.x;
  EXPECT_LT((shown - expected).cwiseAbs().maxCoeff(), 4 * eps<S>());
  ASSERT_TRUE(clock.advance(0.0005).ok());  // the carried half step completes one more
  EXPECT_EQ(sim.stepCount(), 4);
  EXPECT_NEAR(clock.alpha(), 0.0, 1e-9);
}

TYPED_TEST(SimulationTest, FixedStepClockDropsTimeInsteadOfSpiralling) {
  using S = TypeParam;
  SimulationOptions options;
  options.dt = 1e-3;
  options.threads = 1;
  Simulation<S> sim(makeRope<S>(16), options);
  FixedStepClock<S> clock(sim, 8);
  ASSERT_TRUE(clock.advance(1.0).ok());  // a 1 s hitch: 1000 steps due, 8 taken
  EXPECT_EQ(sim.stepCount(), 8);
  // Dropped + simulated + carried = the frame (1 s / 1e-3 s is 999.99... in binary: 999 due).
  EXPECT_NEAR(clock.droppedTime() + 8e-3 + clock.alpha() * 1e-3, 1.0, 1e-9);
  EXPECT_GT(clock.droppedTime(), 0.99);
  ASSERT_TRUE(clock.advance(0.002).ok());  // back to normal: 2 steps
  EXPECT_EQ(sim.stepCount(), 10);
  try {
    clock.advance(-0.1);
    FAIL() << "negative frame time accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("frameTime"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("-0.1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(clock.advance(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  EXPECT_THROW(FixedStepClock<S>(sim, 0), std::invalid_argument);
  EXPECT_EQ(sim.stepCount(), 10);
}

}  // namespace
}  // namespace weft::test
