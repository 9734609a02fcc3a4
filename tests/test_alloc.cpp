// tests/test_alloc.cpp — a step never allocates.
//
// This program links the counting global operator new / delete of tests/support/alloc_counter.cpp
// (every operator new / new[]: plain, nothrow, aligned, aligned nothrow, counted in a thread-safe
// atomic and forwarded to malloc / aligned_alloc). Eigen's heap does not go through operator
// new but through std::malloc, so the build also links this program with `--wrap` for the
// malloc family (WEFT_TEST_WRAP_MALLOC): every malloc, calloc, realloc, aligned_alloc and
// posix_memalign made by code linked statically into it (weft, and the Eigen and TBB template
// code instantiated in weft, and the counting operator new itself) is counted as well.
// Allocations inside shared libraries (libtbb's scheduler, libstdc++) are not seen by the
// wrappers; any of them made through operator new still is.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <new>

#include "support/alloc_counter.hpp"
#include "support/test_support.hpp"

namespace {
std::atomic<long> gMallocCalls{0};
}  // namespace

// ---- the malloc family, via the linker's --wrap -----------------------------------------

#ifdef WEFT_TEST_WRAP_MALLOC
extern "C" {
void* __real_malloc(std::size_t);
void* __real_calloc(std::size_t, std::size_t);
void* __real_realloc(void*, std::size_t);
void* __real_aligned_alloc(std::size_t, std::size_t);
int __real_posix_memalign(void**, std::size_t, std::size_t);

void* __wrap_malloc(std::size_t size) {
  gMallocCalls.fetch_add(1, std::memory_order_relaxed);
  return __real_malloc(size);
}
void* __wrap_calloc(std::size_t count, std::size_t size) {
  gMallocCalls.fetch_add(1, std::memory_order_relaxed);
  return __real_calloc(count, size);
}
void* __wrap_realloc(void* p, std::size_t size) {
  gMallocCalls.fetch_add(1, std::memory_order_relaxed);
  return __real_realloc(p, size);
}
void* __wrap_aligned_alloc(std::size_t alignment, std::size_t size) {
  gMallocCalls.fetch_add(1, std::memory_order_relaxed);
  return __real_aligned_alloc(alignment, size);
}
int __wrap_posix_memalign(void** p, std::size_t alignment, std::size_t size) {
  gMallocCalls.fetch_add(1, std::memory_order_relaxed);
  return __real_posix_memalign(p, alignment, size);
}
}
constexpr bool kMallocCounted = true;
#else
constexpr bool kMallocCounted = false;
#endif

namespace weft::test {
namespace {

struct Counts {
  std::int64_t news = 0;
  std::int64_t mallocs = 0;
};

Counts now() { return {operatorNewCalls(), gMallocCalls.load()}; }

/// Allocation calls made while f() runs (on any thread, for operator new).
template <class F>
Counts countDuring(F&& f) {
  const Counts before = now();
  f();
  const Counts after = now();
  return {after.news - before.news, after.mallocs - before.mallocs};
}

/// Twenty steps (after the caller's warm-up): all succeed, and none calls operator new or
/// the malloc family.
template <class S>
void expectTwentyStepsDoNotAllocate(Simulation<S>& sim) {
  StepStatus status;
  const Counts steps = countDuring([&] {
    for (int k = 0; k < 20; ++k) status = sim.step();
  });
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(steps.news, 0) << "operator new calls during 20 steps";
  EXPECT_EQ(steps.mallocs, 0) << "malloc-family calls during 20 steps";
}

TEST(AllocationCounter, SeesOperatorNewAndMalloc) {
  // The counters must work, or the zero counts below would prove nothing.
  // (The pointers go through a volatile so that the new/delete pairs are not elided.)
  static void* volatile sink = nullptr;
  struct alignas(128) Wide {
    char bytes[128];
  };
  const Counts c = countDuring([] {
    sink = new int(3);
    delete static_cast<int*>(sink);
    sink = new double[10];
    delete[] static_cast<double*>(sink);
    sink = new Wide;
    delete static_cast<Wide*>(sink);
    sink = new (std::nothrow) int(4);
    delete static_cast<int*>(sink);
  });
  EXPECT_EQ(c.news, 4);
  if (kMallocCounted) {
    double sum = -1;
    const Counts m = countDuring([&] {
      Eigen::VectorXd v(1000);  // Eigen's heap: std::malloc, not operator new
      sink = v.data();
      v.setZero();
      sum = v.sum();
    });
    EXPECT_EQ(sum, 0.0);
    EXPECT_GE(m.mallocs, 1);
    EXPECT_EQ(m.news, 0);
    // ... and inside the weft library: building a model and a simulation sizes Eigen
    // buffers there.
    const Counts w = countDuring([] {
      SimulationOptions options;
      options.threads = 1;
      Simulation<double> sim(makeFlag<double>(8), options);
      (void)sim;
    });
    EXPECT_GE(w.mallocs, 10);
  }
}

/// A new step size factorises the prefactored matrix once (that allocates); the two most
/// recent sizes are kept, so going back and forth between two of them (the collision
/// pipeline's halved chunks) allocates nothing. For projective dynamics and implicit Euler's
/// projective preconditioner.
template <class S>
void expectTwoCachedStepSizesAllocateNothing(Simulation<S>& sim) {
  const double dt = sim.timeStep();
  sim.setTimeStep(dt / 2);
  ASSERT_TRUE(sim.step().ok());
  EXPECT_EQ(sim.lastWork().factorizations, 1);
  StepStatus status;
  const Counts alternating = countDuring([&] {
    for (int k = 0; k < 4; ++k) {
      sim.setTimeStep(k % 2 == 0 ? dt : dt / 2);
      status = sim.step();
    }
  });
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(sim.totalWork().factorizations, 2);
  EXPECT_EQ(alternating.news, 0) << "operator new calls alternating two cached step sizes";
  EXPECT_EQ(alternating.mallocs, 0) << "malloc-family calls alternating two cached step sizes";
}

template <class C>
class StepAllocation : public ::testing::Test {};
TYPED_TEST_SUITE(StepAllocation, AllConfigs, ConfigNames);

/// Flag side: big enough for several parallel blocks per pass with two threads.
constexpr Index kFlagSize = 40;

TYPED_TEST(StepAllocation, StepsDoNotAllocate) {
  using S = typename TypeParam::Scalar;
  constexpr IntegratorKind kind = TypeParam::kIntegrator;
  const ModelAndState<S> flag = makeFlag<S>(kFlagSize);
  for (const ForceStrategy strategy : kGridStrategies)
    for (const int threads : {1, 2}) {
      SCOPED_TRACE(::testing::Message() << forceStrategyName(strategy) << ", " << threads << " thread(s)");
      SimulationOptions options = flagOptions(kind, strategy, threads, defaultTimeStep(BuiltinScene::Flag, kFlagSize));
      if (kind == IntegratorKind::ExplicitEuler) options.dt /= 4;
      // rk45 substeps through a 10 s step instead of failing it; with a cap on substeps the
      // step fails quickly, through the error control's own failure path.
      options.integration.maxSubsteps = 200;
      Simulation<S> sim(ModelAndState<S>{flag.model, flag.state}, options);
      ASSERT_TRUE(sim.run(3).ok());  // warm-up: TBB workers join the arena

      StepStatus status;
      const Counts steps = countDuring([&] {
        for (int k = 0; k < 50; ++k) status = sim.step();
      });
      ASSERT_TRUE(status.ok()) << status.message();
      ASSERT_EQ(sim.stepCount(), 53);
      EXPECT_EQ(steps.news, 0) << "operator new calls during 50 steps";
      EXPECT_EQ(steps.mallocs, 0) << "malloc-family calls during 50 steps";
      // Resetting a run is not a step, but a caller may reset thousands of times: setState
      // checks every particle and spring without allocating (it once made a string per
      // spring).
      const State<S> kept = sim.state();
      const Counts reset = countDuring([&] { sim.setState(kept); });
      EXPECT_EQ(reset.news, 0) << "operator new calls in setState";
      EXPECT_EQ(reset.mallocs, 0) << "malloc-family calls in setState";

      if (kind == IntegratorKind::Projective) {
        // Projective dynamics does not fail at a large step.
        expectTwoCachedStepSizesAllocateNothing(sim);
        continue;
      }
      // A failing step (the stability check stops it) and the refused steps after it.
      sim.setTimeStep(10.0);
      StepStatus first, again;
      const Counts failing = countDuring([&] {
        first = sim.step();
        again = sim.step();
      });
      ASSERT_FALSE(first.ok()) << "the step at dt = 10 s did not fail";
      EXPECT_EQ(again.code, first.code);
      EXPECT_EQ(failing.news, 0) << "operator new calls during a failing step";
      EXPECT_EQ(failing.mallocs, 0) << "malloc-family calls during a failing step";
    }
}

TEST(ImplicitAllocation, EveryPreconditionerStepsWithoutAllocating) {
  // (StepAllocation covers the default, auto, with a failing step too.)
  const ModelAndState<double> flag = makeFlag<double>(kFlagSize);
  for (const Preconditioner p : kAllPreconditioners)
    for (const int threads : {1, 2}) {
      SCOPED_TRACE(::testing::Message() << preconditionerName(p) << ", " << threads << " thread(s)");
      SimulationOptions options = flagOptions(IntegratorKind::ImplicitEuler, ForceStrategy::Auto, threads,
                                              defaultTimeStep(BuiltinScene::Flag, kFlagSize));
      options.integration.preconditioner = p;
      Simulation<double> sim(ModelAndState<double>{flag.model, flag.state}, options);
      ASSERT_TRUE(sim.run(3).ok());  // warm-up: TBB workers, the projective factorisation
      expectTwentyStepsDoNotAllocate(sim);
      if (p != Preconditioner::Projective) continue;
      expectTwoCachedStepSizesAllocateNothing(sim);
    }
}

TEST(ImplicitAllocation, ReserveMakesTheJacobiansStencilWindowsForEveryThread) {
  // The 64^2 flag's products run in two chunks, one window per thread: reserve() makes
  // them, and a first product then allocates nothing; without it, the first product makes
  // them (the counter sees it, so the zero above is not vacuous).
  const ModelAndState<double> flag = makeFlag<double>(64);
  const Executor exec(2);
  for (int k = 0; k < 4; ++k) exec.parallelFor(1 << 16, 1, [](Index, Index) {});  // TBB workers join
  Vec3Array<double> y(flag.model.particleCount(), 3);
  auto store = [&](Index b, Index m, const double* yx, const double* yy, const double* yz) {
    for (Index t = 0; t < m; ++t) y.row(b + t) << yx[t], yy[t], yz[t];
  };
  for (const bool reserve : {true, false}) {
    SCOPED_TRACE(reserve ? "reserved" : "not reserved");
    SpringJacobian<double> jacobian(flag.model);
    if (reserve) jacobian.reserve(exec);
    jacobian.linearize(flag.state.x * 1.01, 1.0 / 60, exec);
    const Counts first = countDuring([&] {
      jacobian.systemProduct(flag.state.v, makeSink<double>(store), exec);
      jacobian.stiffnessProduct(flag.state.x, makeSink<double>(store), exec);
    });
    if (reserve) {
      EXPECT_EQ(first.news, 0);
      EXPECT_EQ(first.mallocs, 0);
    } else {
      EXPECT_GT(first.news + first.mallocs, 0);
    }
  }
}

TEST(ImplicitAllocation, TheFirstStepOnOneThreadAllocatesNothing) {
  // The Simulation reserves what its integrator needs per thread when it is built (the 64^2
  // flag's products and projective dynamics' passes run in two chunks): on one thread (no
  // TBB workers to join) even the first implicit Euler step allocates nothing.
  for (const Preconditioner p : {Preconditioner::BlockJacobi, Preconditioner::Multigrid}) {
    SCOPED_TRACE(preconditionerName(p));
    SimulationOptions options = flagOptions(IntegratorKind::ImplicitEuler, ForceStrategy::Auto, 1, 1.0 / 60);
    options.integration.preconditioner = p;
    Simulation<double> sim(makeFlag<double>(64), options);
    StepStatus status;
    const Counts first = countDuring([&] { status = sim.step(); });
    ASSERT_TRUE(status.ok()) << status.message();
    EXPECT_EQ(first.news, 0);
    EXPECT_EQ(first.mallocs, 0);
  }
}

TEST(ImplicitAllocation, AutoMovesToTheMultigridWithoutAllocating) {
  // The 32^2 flag at 1/60 s: the first step (free fall from the flat cloth) takes one
  // iteration; block-Jacobi's solves pass the threshold within the next few, inside the
  // twenty counted steps, and the multigrid, built at construction, takes over.
  for (const int threads : {1, 2}) {
    SCOPED_TRACE(::testing::Message() << threads << " thread(s)");
    SimulationOptions options = flagOptions(IntegratorKind::ImplicitEuler, ForceStrategy::Auto, threads, 1.0 / 60);
    options.integration.preconditioner = Preconditioner::Auto;
    Simulation<double> sim(makeFlag<double>(32), options);
    ASSERT_TRUE(sim.run(1).ok());  // warm-up: TBB workers
    ASSERT_EQ(sim.totalWork().multigridSolves, 0);
    expectTwentyStepsDoNotAllocate(sim);
    EXPECT_GT(sim.totalWork().multigridSolves, 10);
  }
}

TEST(EffectAllocation, StepsWithEveryEffectDoNotAllocate) {
  // Drag, gusty wind, repulsion and a kinematic bar, with effect profiling on, for an
  // explicit, an adaptive and the implicit method on 1 and 2 threads.
  ClothGridSpec spec = flagSpec(kFlagSize);
  spec.columnAxis = {0, -1, 0};
  ModelBuilder<double> b;
  addClothGrid(b, spec);
  KinematicPins bar;
  for (Index c = 0; c < kFlagSize; ++c) {
    b.pin(c);
    bar.particles.push_back(c);
  }
  bar.path.angularVelocity = 2;
  bar.path.center = {0.5, 0, 0};
  const ModelAndState<double> cloth = b.build();
  for (const IntegratorKind kind : {IntegratorKind::Rk4, IntegratorKind::Rk45, IntegratorKind::ImplicitEuler})
    for (const int threads : {1, 2}) {
      SCOPED_TRACE(::testing::Message() << integratorName(kind) << ", " << threads << " thread(s)");
      SimulationOptions options =
          flagOptions(kind, ForceStrategy::Auto, threads, defaultTimeStep(BuiltinScene::Flag, kFlagSize));
      options.effects.drag = 1e-3;
      options.effects.wind.enabled = true;
      options.effects.wind.velocity = {3, 0, 2};
      options.effects.wind.gustStrength = 1;
      options.effects.repulsion.radius = 0.5 * spec.spacing;
      options.effects.repulsion.stiffness = 100;
      options.kinematicPins.push_back(bar);
      options.profileEffects = true;
      Simulation<double> sim(ModelAndState<double>{cloth.model, cloth.state}, options);
      ASSERT_TRUE(sim.run(3).ok());  // warm-up: TBB workers join the arena
      expectTwentyStepsDoNotAllocate(sim);
      EXPECT_GT(sim.effectTimes().forces.wind, 0);
      EXPECT_GT(sim.effectTimes().forces.repulsion, 0);
    }
}

TEST(CollisionAllocation, StepsWithObstaclesRollbackAndMeshesDoNotAllocate) {
  // A cloth falling fast onto a floor (rollbacks), a sphere, a capsule, a box and a moving
  // icosphere mesh, continuous detection on, cloth edges against every mesh edge, collision
  // profiling on, 1 and 2 threads.
  ClothGridSpec spec = flagSpec(kFlagSize);
  spec.origin = {-0.5, 0.02, -0.5};
  ModelBuilder<double> b;
  addClothGrid(b, spec);
  ModelAndState<double> cloth = b.build();
  cloth.state.v.col(1).setConstant(-4.0);
  for (const IntegratorKind kind : {IntegratorKind::SymplecticEuler, IntegratorKind::Rk4})
    for (const int threads : {1, 2}) {
      SCOPED_TRACE(::testing::Message() << integratorName(kind) << ", " << threads << " thread(s)");
      SimulationOptions options =
          flagOptions(kind, ForceStrategy::Auto, threads, defaultTimeStep(BuiltinScene::Flag, kFlagSize));
      options.profileEffects = true;
      CollisionOptions& c = options.collision;
      c.obstacles.push_back(Obstacle::plane({0, 0, 0}, {0, 1, 0}));
      c.obstacles.push_back(Obstacle::sphere({0.2, 0, 0.1}, 0.1));
      c.obstacles.push_back(Obstacle::capsule({-0.3, 0, -0.2}, {0.3, 0, -0.2}, 0.03));
      c.obstacles.push_back(Obstacle::box({-0.2, 0, 0.3}, {0.1, 0.05, 0.1}));
      MeshObstacle mesh;
      mesh.mesh = makeIcosphere({0, 0, 0}, 0.08, 3);
      mesh.path = KinematicPath{};
      mesh.path->velocity = {0.5, 0, 0};
      mesh.path->angularVelocity = 1;
      c.meshes.push_back(mesh);
      c.featureAngle = 0;  // every mesh edge is a feature, every vertex a corner: the edge and corner passes run
      Simulation<double> sim(ModelAndState<double>{cloth.model, cloth.state}, options);
      ASSERT_TRUE(sim.run(3).ok());  // warm-up: TBB workers join the arena
      expectTwentyStepsDoNotAllocate(sim);
      EXPECT_GT(sim.totalCollision().contacts, 0);
      EXPECT_GT(sim.totalCollision().rollbacks, 0);
      EXPECT_GT(sim.totalCollision().edgeContacts, 0);
      EXPECT_GT(sim.totalCollision().cornerContacts, 0);
      EXPECT_GT(sim.effectTimes().collision, 0);
    }
}

TEST(SelfCollisionAllocation, StepsWithClothOnClothDoNotAllocate) {
  // A small cloth dropped onto a larger one on a floor, self-collision on (contacts every
  // step once they touch), 1 and 2 threads; counted after 0.3 s, when they rest.
  ModelBuilder<double> b;
  ClothGridSpec spec = flagSpec(12);
  spec.origin = {0, 0.01, 0};
  addClothGrid(b, spec);
  spec.width = spec.height = 8;
  spec.origin = {2.5 * spec.spacing, 0.02, 1.5 * spec.spacing};
  addClothGrid(b, spec);
  const ModelAndState<double> cloths = b.build();
  for (const int threads : {1, 2}) {
    SCOPED_TRACE(::testing::Message() << threads << " thread(s)");
    SimulationOptions options;
    options.dt = defaultTimeStep(BuiltinScene::Flag, 12);
    options.threads = threads;
    options.profileEffects = true;
    options.collision.obstacles.push_back(Obstacle::plane({0, 0, 0}, {0, 1, 0}));
    options.selfCollision.enabled = true;
    Simulation<double> sim(ModelAndState<double>{cloths.model, cloths.state}, options);
    ASSERT_TRUE(sim.run(static_cast<Index>(0.3 / options.dt)).ok());
    expectTwentyStepsDoNotAllocate(sim);
    EXPECT_GT(sim.lastSelfCollision().contacts, 0);
    EXPECT_GT(sim.effectTimes().selfCollision, 0);
    // Back to a kept state (the start the warnings compare with is recorded again).
    const State<double> kept = sim.state();
    const Counts reset = countDuring([&] { sim.setState(kept); });
    EXPECT_EQ(reset.news, 0) << "operator new calls in setState";
    EXPECT_EQ(reset.mallocs, 0) << "malloc-family calls in setState";
    expectTwentyStepsDoNotAllocate(sim);
  }
}

TEST(RigidAllocation, StepsWithRigidBodiesDoNotAllocate) {
  // A pile of 120 convex bodies landing in a bin beside a hanging flag, each narrow phase,
  // 1 and 2 threads; counted once the bodies touch (pairs, manifolds, warm starting busy).
  for (const NarrowPhaseMethod method : {NarrowPhaseMethod::Exact, NarrowPhaseMethod::Ofg, NarrowPhaseMethod::Witness})
    for (const int threads : {1, 2}) {
      SCOPED_TRACE(::testing::Message() << narrowPhaseMethodName(method) << ", " << threads << " thread(s)");
      SimulationOptions options;
      options.integrator = IntegratorKind::SymplecticEuler;
      options.threads = threads;
      options.dt = 1.0 / 600;
      options.profileEffects = true;
      options.rigid = pileScene(120);
      options.rigid.narrowPhase.method = method;
      // Rollback (chunks cut and taken back) with the witness, speculative with the others.
      if (method == NarrowPhaseMethod::Witness) options.rigid.timeOfImpact = RigidTimeOfImpact::Rollback;
      Simulation<double> sim(makeFlag<double>(8), options);
      ASSERT_TRUE(sim.run(200).ok());  // warm-up: the bodies fall into contact
      expectTwentyStepsDoNotAllocate(sim);
      EXPECT_GT(sim.rigidWorld()->lastStats().contacts, 50);
      EXPECT_GT(sim.effectTimes().rigidBodies, 0);
    }
}

TEST(RigidAllocation, ClothCarryingBodiesDoesNotAllocate) {
  // The tablecloth trick: particle contacts and support contacts every step.
  for (const int threads : {1, 2}) {
    SCOPED_TRACE(::testing::Message() << threads << " thread(s)");
    const std::unique_ptr<Simulation<double>> made = makeTablecloth(4.0, threads, 16);
    Simulation<double>& sim = *made;
    ASSERT_TRUE(sim.run(50).ok());  // warm-up: the pull starts, warm starting fills
    expectTwentyStepsDoNotAllocate(sim);
    EXPECT_GT(sim.rigidWorld()->lastStats().supportContacts, 10);
  }
}

TEST(RigidAllocation, HammockHoldingItsBallDoesNotAllocate) {
  // The ball resting in the sag, below the pinned corners: inside the box of the cloth, so
  // every step takes the crossing check's pass over the particles and the triangles.
  for (const int threads : {1, 2}) {
    SCOPED_TRACE(::testing::Message() << threads << " thread(s)");
    const Index n = 16;
    ModelBuilder<double> builder;
    addClothGrid(builder, hammockCloth(n));
    for (const Index i : hammockPins(n)) builder.pin(i);
    SimulationOptions options;
    options.integrator = IntegratorKind::SymplecticEuler;
    options.dt = defaultTimeStep(BuiltinScene::Flag, n);
    options.threads = threads;
    options.effects.drag = 0.03;
    options.rigid = hammockBall();
    options.rigid.bodies[0].position.y() = 0.5 + 0.12 + 0.01;  // 1 cm above the cloth
    Simulation<double> sim(builder.build(), options);
    ASSERT_TRUE(sim.run(static_cast<Index>(0.8 / options.dt)).ok());  // warm-up: the ball lands and sags
    ASSERT_LT(sim.rigidWorld()->state().x[0].y(), 0.45) << "the ball should be below the pinned corners";
    expectTwentyStepsDoNotAllocate(sim);
    EXPECT_GT(sim.lastParticleBodyContacts().contacts, 0);
    EXPECT_EQ(sim.totalParticleBodyContacts().crossings, 0);
  }
}

TEST(ClockAllocation, AdvancingAndInterpolatingDoNotAllocate) {
  SimulationOptions options;
  options.threads = 2;
  options.dt = defaultTimeStep(BuiltinScene::Flag, kFlagSize);
  Simulation<double> sim(makeFlag<double>(kFlagSize), options);
  FixedStepClock<double> clock(sim);
  Vec3Array<double> shown(sim.model().particleCount(), 3);
  ASSERT_TRUE(clock.advance(0.002).ok());  // warm-up: TBB workers join the arena
  const Counts c = countDuring([&] {
    for (int k = 0; k < 30; ++k) {
      ASSERT_TRUE(clock.advance(k % 3 == 0 ? 0.0007 : 0.0016).ok());  // a few steps per frame
      clock.interpolatedPositions(shown);
    }
  });
  EXPECT_GT(sim.stepCount(), 50);
  EXPECT_EQ(c.news, 0);
  EXPECT_EQ(c.mallocs, 0);
}

}  // namespace
}  // namespace weft::test
