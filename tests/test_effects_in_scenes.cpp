// tests/test_effects_in_scenes.cpp — wind, universal repulsion and kinematic pins: the force
// laws against independent formulas, the gust field's statistics, the neighbour search
// against all pairs, pins on their paths, and bitwise determinism for 1 and 2 threads
// with every effect on.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "support/test_support.hpp"
#include "weft/effects/force_field.hpp"
#include "weft/io/scene.hpp"
#include "weft/weft.hpp"

namespace weft::test {
namespace {

constexpr double kPi = 3.14159265358979323846;

// One free triangle (three particles of 1 kg) in the plane spanned by e1, e2 at the origin.
ModelAndState<double> triangle(const Vec3d& e1, const Vec3d& e2) {
  ModelBuilder<double> b;
  b.addParticle({0, 0, 0}, 1);
  b.addParticle(e1, 1);
  b.addParticle(e2, 1);
  b.addTriangle(0, 1, 2);
  return b.build();
}

Vec3d totalForce(const ModelAndState<double>& m, const ParticleEffects& effects, const Vec3Array<double>* v = nullptr) {
  ForceField<double> field(m.model, ForceStrategy::Gather, {0, 0, 0}, effects);
  Vec3Array<double> a(m.model.particleCount(), 3);
  const Executor exec(1);
  field.accelerations(m.state.x, v ? *v : m.state.v, a, exec);
  Vec3d f;
  for (Index i = 0; i < m.model.particleCount(); ++i) {
    const double mass = m.model.mass()[i];
    f.x += mass * a(i, 0);
    f.y += mass * a(i, 1);
    f.z += mass * a(i, 2);
  }
  return f;
}

ParticleEffects steadyWind(const Vec3d& u, double cd, double cl) {
  ParticleEffects e;
  e.wind.enabled = true;
  e.wind.velocity = u;
  e.wind.airDensity = 1.2;
  e.wind.dragCoefficient = cd;
  e.wind.liftCoefficient = cl;
  return e;
}

TEST(Wind, HeadOnIsPureDragAlongTheNormal) {
  // Triangle in the x-z plane (area 0.5 m^2), wind 5 m/s along -y, which is (e1 x e2)'s
  // opposite: f = 1/2 rho C_D A |u|^2 along the wind, no lift (u is along n).
  const ModelAndState<double> m = triangle({1, 0, 0}, {0, 0, 1});
  const Vec3d f = totalForce(m, steadyWind({0, -5, 0}, 1.1, 0.7));
  const double expected = 0.5 * 1.2 * 1.1 * 0.5 * 25;
  EXPECT_NEAR(f.y, -expected, 1e-12);
  EXPECT_NEAR(f.x, 0, 1e-12);
  EXPECT_NEAR(f.z, 0, 1e-12);
}

TEST(Wind, ObliqueFlowMatchesTheFlatPlateFormulas) {
  // Plate in the x-z plane, flow at angle of attack alpha in the x-y plane. Independent
  // formulas: drag along the windward normal 1/2 rho C_D A |u|^2 sin(alpha); lift
  // 1/2 rho C_L A |u|^2 sin(alpha) cos(alpha), perpendicular to u, on the windward side.
  const ModelAndState<double> m = triangle({1, 0, 0}, {0, 0, 1});
  const double A = 0.5, rho = 1.2, cd = 1.1, cl = 0.7, speed = 7;
  for (const double alpha : {0.1, 0.5, kPi / 4, 1.2}) {
    SCOPED_TRACE(alpha);
    const Vec3d u{speed * std::cos(alpha), -speed * std::sin(alpha), 0};
    const Vec3d f = totalForce(m, steadyWind(u, cd, cl));
    const double q = 0.5 * rho * A * speed * speed;
    // Windward normal: (0, -1, 0) (the flow goes towards -y). Lift direction: perpendicular
    // to u in the x-y plane, with a negative y component.
    const Vec3d nw{0, -1, 0};
    const Vec3d lift{-std::sin(alpha), -std::cos(alpha), 0};
    const double fd = q * cd * std::sin(alpha), fl = q * cl * std::sin(alpha) * std::cos(alpha);
    EXPECT_NEAR(f.x, fd * nw.x + fl * lift.x, 1e-11);
    EXPECT_NEAR(f.y, fd * nw.y + fl * lift.y, 1e-11);
    EXPECT_NEAR(f.z, 0, 1e-12);
    // The lift part alone (C_D = 0) is perpendicular to the flow.
    const Vec3d l = totalForce(m, steadyWind(u, 0, cl));
    EXPECT_NEAR(l.x * u.x + l.y * u.y + l.z * u.z, 0, 1e-11);
  }
}

TEST(Wind, ClothMovingWithTheAirFeelsNothingAndEdgeOnFlowNothing) {
  const ModelAndState<double> m = triangle({1, 0, 0}, {0, 0, 1});
  Vec3Array<double> v(3, 3);
  for (int i = 0; i < 3; ++i) v.row(i) << 3, -2, 1;
  const Vec3d still = totalForce(m, steadyWind({3, -2, 1}, 1, 1), &v);
  EXPECT_EQ(still.x, 0);
  EXPECT_EQ(still.y, 0);
  EXPECT_EQ(still.z, 0);
  const Vec3d edgeOn = totalForce(m, steadyWind({4, 0, 2}, 1, 1));  // in the plate's plane
  EXPECT_EQ(edgeOn.x, 0);
  EXPECT_EQ(edgeOn.y, 0);
  EXPECT_EQ(edgeOn.z, 0);
}

TEST(Wind, ParticlesOnNoTriangleGetQuadraticDrag) {
  ModelAndState<double> rope = makeRope<double>(5);
  ParticleEffects e = steadyWind({2, 0, -1}, 0.9, 0.5);
  e.wind.particleArea = 0.01;
  ForceField<double> field(rope.model, ForceStrategy::Gather, {0, 0, 0}, e);
  ForceField<double> bare(rope.model, ForceStrategy::Gather, {0, 0, 0});
  rope.state.v.col(1).setConstant(0.5);
  Vec3Array<double> a(5, 3), a0(5, 3);
  const Executor exec(1);
  field.accelerations(rope.state.x, rope.state.v, a, exec);
  bare.accelerations(rope.state.x, rope.state.v, a0, exec);
  for (Index i = 1; i < 5; ++i) {
    const double ux = 2, uy = -0.5, uz = -1, speed = std::sqrt(ux * ux + uy * uy + uz * uz);
    const double k = 0.5 * 1.2 * 0.9 * 0.01 * speed / rope.model.mass()[i];
    EXPECT_NEAR(a(i, 0) - a0(i, 0), k * ux, 1e-12);
    EXPECT_NEAR(a(i, 1) - a0(i, 1), k * uy, 1e-12);
    EXPECT_NEAR(a(i, 2) - a0(i, 2), k * uz, 1e-12);
  }
  EXPECT_EQ(a(0, 0), 0) << "pinned";
}

ParticleEffects gusty(std::uint64_t seed);

TEST(Wind, TheGridPathMatchesTheGeneralPath) {
  // A cloth grid's triangles take a stencil path (contiguous loads); the same cloth behind
  // one extra particle has no grid layout and takes the index-list path. Same forces up to
  // the summation order.
  ClothGridSpec spec = flagSpec(9);
  spec.height = 7;
  ModelBuilder<double> gridBuilder, offsetBuilder;
  addClothGrid(gridBuilder, spec);
  offsetBuilder.addParticle({5, 5, 5}, 1);
  addClothGrid(offsetBuilder, spec);
  ModelAndState<double> grid = gridBuilder.build(), offset = offsetBuilder.build();
  ASSERT_TRUE(grid.model.grid().has_value());
  ASSERT_FALSE(offset.model.grid().has_value());
  perturbFree(grid.model, grid.state, 0.02, 0.5, 5);
  offset.state.x.bottomRows(63) = grid.state.x;
  offset.state.v.bottomRows(63) = grid.state.v;
  ParticleEffects e = steadyWind({3, 1, -2}, 1.1, 0.6);
  e.wind.gustStrength = 1;
  ForceField<double> a(grid.model, ForceStrategy::Gather, {0, 0, 0}, e),
      b(offset.model, ForceStrategy::Gather, {0, 0, 0}, e);
  ForceField<double> a0(grid.model, ForceStrategy::Gather, {0, 0, 0}),
      b0(offset.model, ForceStrategy::Gather, {0, 0, 0});
  Vec3Array<double> ga(63, 3), ga0(63, 3), oa(64, 3), oa0(64, 3);
  const Executor exec(2);
  a.accelerations(grid.state.x, grid.state.v, ga, exec);
  a0.accelerations(grid.state.x, grid.state.v, ga0, exec);
  b.accelerations(offset.state.x, offset.state.v, oa, exec);
  b0.accelerations(offset.state.x, offset.state.v, oa0, exec);
  double largest = 0;
  for (Index i = 0; i < 63; ++i)
    for (int c = 0; c < 3; ++c) {
      const double wg = ga(i, c) - ga0(i, c), wo = oa(i + 1, c) - oa0(i + 1, c);
      largest = std::max(largest, std::abs(wg));
      ASSERT_NEAR(wg, wo, 1e-12 * (1 + std::abs(wo))) << "particle " << i << " axis " << c;
    }
  EXPECT_GT(largest, 1.0) << "the wind should matter";
}

ParticleEffects gusty(std::uint64_t seed) {
  ParticleEffects e = steadyWind({4, 0, 0}, 1, 0.5);
  e.wind.gustStrength = 1.5;
  e.wind.gustScale = 2;
  e.wind.gustPeriod = 1;
  e.wind.seed = seed;
  return e;
}

TEST(Wind, GustsAreSeededSmoothAndHaveTheRequestedStrength) {
  const ModelAndState<double> m = triangle({1, 0, 0}, {0, 0, 1});
  ForceField<double> a(m.model, ForceStrategy::Gather, {0, 0, 0}, gusty(7));
  ForceField<double> b(m.model, ForceStrategy::Gather, {0, 0, 0}, gusty(7));
  ForceField<double> c(m.model, ForceStrategy::Gather, {0, 0, 0}, gusty(8));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> pos(-10, 10), time(0, 100);
  double sum[3] = {0, 0, 0}, sumSq = 0, largestSlope = 0;
  bool seedsDiffer = false;
  const int samples = 4000;
  for (int k = 0; k < samples; ++k) {
    const Vec3d x{pos(rng), pos(rng), pos(rng)};
    const double t = time(rng);
    const Vec3d u = a.airVelocity(x, t), same = b.airVelocity(x, t), other = c.airVelocity(x, t);
    ASSERT_EQ(u.x, same.x);
    ASSERT_EQ(u.y, same.y);
    ASSERT_EQ(u.z, same.z);
    seedsDiffer = seedsDiffer || other.x != u.x;
    const double g[3] = {u.x - 4, u.y, u.z};
    for (int d = 0; d < 3; ++d) sum[d] += g[d];
    sumSq += g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
    // Smooth: a 1 mm or 1 ms move changes the air velocity by O(1 mm / scale x strength).
    const Vec3d dx = a.airVelocity({x.x + 1e-3, x.y, x.z}, t), dt = a.airVelocity(x, t + 1e-3);
    largestSlope = std::max({largestSlope, std::abs(dx.x - u.x) / 1e-3, std::abs(dt.x - u.x) / 1e-3});
  }
  EXPECT_TRUE(seedsDiffer);
  const double rms = std::sqrt(sumSq / samples);
  EXPECT_NEAR(rms, 1.5, 0.25) << "rms gust speed";
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(sum[d] / samples, 0, 0.15) << "mean gust, axis " << d;
  // The steepest plane wave: amplitude 1.5 sqrt(2/8) times k <= 2 pi / (0.5 * 2), plus the
  // advection and period terms: bounded by a few tens, far from a discontinuity's 1/1e-3.
  EXPECT_LT(largestSlope, 60.0);
}

TEST(Wind, AFlagOnAPoleStreamsDownwind) {
  // The flag-wind scene, small: after 1.5 s the free edge is far downwind of the pole and
  // the cloth moves (flutters) rather than hanging still.
  SceneSpec spec = builtinSceneSpec("flag-wind", 12);
  spec.simulation.threads = 2;
  spec.simulation.integrator = IntegratorKind::SymplecticEuler;
  AssembledScene<double> scene = assembleScene<double>(spec);
  Simulation<double> sim(std::move(scene.built), scene.options);
  const double dt = sim.timeStep();
  ASSERT_TRUE(sim.run(static_cast<Index>(1.5 / dt)).ok()) << sim.status().message();
  const Index n = 12;
  double tipX = 0, tipY = 0;
  for (Index r = 0; r < n; ++r) {
    tipX += sim.state().x(r * n + n - 1, 0) / n;
    tipY += sim.state().x(r * n + n - 1, 1) / n;
  }
  EXPECT_GT(tipX, 0.6) << "the free edge (1 m from the pole) should be blown out downwind";
  EXPECT_GT(tipY, 0.0) << "and held up against gravity";
  EXPECT_GT(sim.state().v.norm(), 0.05) << "a flag in gusty wind keeps moving";
}

// ---------------------------------------------------------------------------------------
// Repulsion
// ---------------------------------------------------------------------------------------

ParticleEffects repulsion(double r, double k) {
  ParticleEffects e;
  e.repulsion.radius = r;
  e.repulsion.stiffness = k;
  return e;
}

TEST(Repulsion, TwoParticlesPushApartWithinTheRadiusOnly) {
  for (const double d : {0.0, 0.01, 0.05, 0.0999, 0.1, 0.2}) {
    SCOPED_TRACE(d);
    ModelBuilder<double> b;
    b.addParticle({0.3, 0.2, -0.1}, 2);
    b.addParticle({0.3 + d * 0.6, 0.2 + d * 0.8, -0.1}, 2);
    const ModelAndState<double> m = b.build();
    ForceField<double> field(m.model, ForceStrategy::Gather, {0, 0, 0}, repulsion(0.1, 50));
    Vec3Array<double> a(2, 3);
    field.accelerations(m.state.x, m.state.v, a, Executor(1));
    const double f = (d > 0 && d < 0.1) ? 50 * (0.1 - d) : 0.0;  // N, along the separation
    EXPECT_NEAR(a(1, 0) * 2, f * 0.6, 1e-12);
    EXPECT_NEAR(a(1, 1) * 2, f * 0.8, 1e-12);
    EXPECT_EQ(a(0, 0), -a(1, 0));
    EXPECT_EQ(a(0, 1), -a(1, 1));
  }
}

TEST(Repulsion, MatchesAllPairsOnARandomCloudAndIsBitwiseTheSameOnTwoThreads) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  ModelBuilder<double> b;
  const Index n = 3000;
  for (Index i = 0; i < n; ++i) b.addParticle({u(rng), 0.2 * u(rng), u(rng)}, 0.5 + u(rng));
  b.pin(17);
  const ModelAndState<double> m = b.build();
  const double r = 0.04, k = 30;
  ForceField<double> field(m.model, ForceStrategy::Gather, {0, 0, 0}, repulsion(r, k));
  Vec3Array<double> a1(n, 3), a2(n, 3);
  field.accelerations(m.state.x, m.state.v, a1, Executor(1));
  field.accelerations(m.state.x, m.state.v, a2, Executor(2));
  EXPECT_TRUE((a1.array() == a2.array()).all()) << "1 vs 2 threads";
  Index pairs = 0;
  for (Index i = 0; i < n; ++i) {
    double f[3] = {0, 0, 0};
    for (Index j = 0; j < n; ++j) {
      if (j == i) continue;
      const Eigen::RowVector3d e = m.state.x.row(i) - m.state.x.row(j);
      const double d = e.norm();
      if (d >= r || d == 0) continue;
      ++pairs;
      for (int c = 0; c < 3; ++c) f[c] += k * (r - d) / d * e[c];
    }
    for (int c = 0; c < 3; ++c)
      ASSERT_NEAR(a1(i, c), m.model.inverseMass()[i] * f[c], 1e-10) << "particle " << i << " axis " << c;
  }
  EXPECT_GT(pairs, 2 * n) << "the cloud should be dense enough to test the search";
}

TEST(Repulsion, AParticleComesToRestOnAPinnedOneAtTheForceBalance) {
  // A free particle above a pinned one, exactly aligned: it settles where k (r - d) = m g.
  ModelBuilder<double> b;
  b.addParticle({0.1, 0.2, 0.3}, 1);
  b.addParticle({0.1, 0.2 + 0.09, 0.3}, 0.01);
  b.pin(0);
  SimulationOptions options;
  options.threads = 1;
  options.dt = 1e-3;
  options.effects = repulsion(0.1, 5);
  options.effects.drag = 0.02;
  Simulation<double> sim(b.build(), options);
  ASSERT_TRUE(sim.run(12000).ok());  // 12 decay times of the damped bounce
  const double d = sim.state().x(1, 1) - sim.state().x(0, 1);
  EXPECT_NEAR(d, 0.1 - 0.01 * 9.81 / 5, 1e-6);
}

// ---------------------------------------------------------------------------------------
// Kinematic pins
// ---------------------------------------------------------------------------------------

ModelAndState<double> hangingGrid(Index n) {
  ClothGridSpec spec = flagSpec(n);
  spec.origin = {0, 1, 0};
  spec.rowAxis = {1, 0, 0};
  spec.columnAxis = {0, -1, 0};
  ModelBuilder<double> b;
  addClothGrid(b, spec);
  for (Index c = 0; c < n; ++c) b.pin(c);
  return b.build();
}

TEST(KinematicPins, PinnedParticlesFollowTheirPathExactlyAndDragTheCloth) {
  const Index n = 10;
  const ModelAndState<double> cloth = hangingGrid(n);
  KinematicPins bar;
  for (Index c = 0; c < n; ++c) bar.particles.push_back(c);
  bar.path.velocity = {0.2, 0, 0.1};
  bar.path.center = {0.5, 1, 0};
  bar.path.axis = {0, 2, 0};  // normalised on use
  bar.path.angularVelocity = 1.5;
  bar.path.startTime = 0.05;
  bar.path.endTime = 0.3;
  SimulationOptions options;
  options.threads = 1;
  options.dt = defaultTimeStep(BuiltinScene::Flag, n);
  options.kinematicPins.push_back(bar);
  Simulation<double> sim(ModelAndState<double>{cloth.model, cloth.state}, options);
  for (int k = 0; k < 2000; ++k) {  // 0.4 s: before, during and after the motion
    ASSERT_TRUE(sim.step().ok()) << sim.status().message();
    const double t = sim.state().time;
    for (Index c = 0; c < n; ++c) {
      const Vec3d p0{cloth.state.x(c, 0), cloth.state.x(c, 1), cloth.state.x(c, 2)};
      const Vec3d p = kinematicPosition(bar.path, p0, t);
      ASSERT_EQ(sim.state().x(c, 0), p.x) << "step " << k << " particle " << c;
      ASSERT_EQ(sim.state().x(c, 1), p.y);
      ASSERT_EQ(sim.state().x(c, 2), p.z);
    }
  }
  // After endTime the bar holds: turned by 1.5 * 0.25 rad and moved by 0.25 * velocity.
  const double angle = 1.5 * 0.25;
  const Vec3d end = kinematicPosition(bar.path, {0, 1, 0}, 10.0);
  EXPECT_NEAR(end.x, 0.5 + 0.05 - 0.5 * std::cos(angle), 1e-12);
  EXPECT_NEAR(end.z, 0.025 + 0.5 * std::sin(angle), 1e-12);
  EXPECT_NEAR(end.y, 1, 1e-12);
  // The row below the bar was dragged along (it started at z = 0).
  EXPECT_GT(std::abs(sim.state().x(n, 2)), 0.01);
}

TEST(KinematicPins, BadPinsAreRejectedByName) {
  const ModelAndState<double> cloth = hangingGrid(4);
  const auto expectRejected = [&](KinematicPins pins, const std::string& needle) {
    SimulationOptions options;
    options.threads = 1;
    options.kinematicPins.push_back(std::move(pins));
    try {
      Simulation<double> sim(ModelAndState<double>{cloth.model, cloth.state}, options);
      ADD_FAILURE() << "accepted; expected an error containing '" << needle << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("kinematicPins[0]"), std::string::npos) << e.what();
    }
  };
  expectRejected({{5}, {}}, "not pinned");
  expectRejected({{16}, {}}, "got 16");
  expectRejected({{-1}, {}}, "got -1");
  expectRejected({{1, 1}, {}}, "already moved");
  KinematicPins nanPath{{0}, {}};
  nanPath.path.velocity.y = std::nan("");
  expectRejected(nanPath, "velocity");
  KinematicPins fastPath{{0}, {}};  // finite, but faster than light
  fastPath.path.velocity.x = 1e300;
  expectRejected(fastPath, "path.velocity must be a speed of at most 299792458 m/s (the speed of light), got (1e+300");
  KinematicPins backwards{{0}, {}};
  backwards.path.startTime = 2;
  backwards.path.endTime = 1;
  expectRejected(backwards, "endTime");
  KinematicPins noAxis{{0}, {}};
  noAxis.path.axis = {0, 0, 0};
  noAxis.path.angularVelocity = 1;
  expectRejected(noAxis, "axis");
  // A spin that drives a pin faster than light: particle 0 turned about a centre 1e6 m away.
  KinematicPins spin{{0}, {}};
  spin.path.center = {1e6, 0, 0};
  spin.path.angularVelocity = 1e3;
  expectRejected(spin, "path.angularVelocity must be at most 299.");
  expectRejected(spin, "rad/s in size (its farthest particle, 1");
  spin.path.angularVelocity = 200;  // 2e8 m/s: within the limit
  SimulationOptions options;
  options.threads = 1;
  options.kinematicPins.push_back(spin);
  EXPECT_NO_THROW(Simulation<double>(ModelAndState<double>{cloth.model, cloth.state}, options));
}

TEST(KinematicPins, AFailedStepLeavesTheStateAsItWas) {
  const ModelAndState<double> cloth = hangingGrid(6);
  KinematicPins bar;
  for (Index c = 0; c < 6; ++c) bar.particles.push_back(c);
  bar.path.velocity = {0, 0, 3};
  SimulationOptions options;
  options.threads = 1;
  options.integrator = IntegratorKind::ExplicitEuler;
  options.dt = 1e-4;
  options.kinematicPins.push_back(bar);
  Simulation<double> sim(ModelAndState<double>{cloth.model, cloth.state}, options);
  ASSERT_TRUE(sim.run(20).ok());
  const State<double> before = sim.state();
  sim.setTimeStep(5.0);  // explicit Euler at 5 s: the stability check fails the step
  ASSERT_FALSE(sim.step().ok());
  EXPECT_TRUE((sim.state().x.array() == before.x.array()).all());
  EXPECT_TRUE((sim.state().v.array() == before.v.array()).all());
}

// ---------------------------------------------------------------------------------------
// Everything at once: bitwise the same on 1 and 2 threads, for every integrator
// ---------------------------------------------------------------------------------------

class AllEffects : public ::testing::TestWithParam<IntegratorKind> {};

TEST_P(AllEffects, AreBitwiseIdenticalOnOneAndTwoThreads) {
  const IntegratorKind kind = GetParam();
  SceneSpec spec = builtinSceneSpec("hanging-cloth", 24);
  spec.simulation.integrator = kind;
  spec.simulation.effects.wind = gusty(5).wind;
  if (kind == IntegratorKind::ExplicitEuler) spec.simulation.dt /= 8;
  State<double> result[2];
  for (const int threads : {1, 2}) {
    spec.simulation.threads = threads;
    AssembledScene<double> scene = assembleScene<double>(spec);
    Simulation<double> sim(std::move(scene.built), scene.options);
    ASSERT_TRUE(sim.run(12).ok()) << sim.status().message();
    result[threads - 1] = sim.state();
  }
  EXPECT_TRUE((result[0].x.array() == result[1].x.array()).all());
  EXPECT_TRUE((result[0].v.array() == result[1].v.array()).all());
  EXPECT_EQ(stateHash(result[0]), stateHash(result[1]));
}

INSTANTIATE_TEST_SUITE_P(EveryIntegrator, AllEffects, ::testing::ValuesIn(kAllIntegrators),
                         [](const ::testing::TestParamInfo<IntegratorKind>& info) {
                           return std::string(integratorName(info.param));
                         });

TEST(Effects, BadParametersAreRejectedByName) {
  const auto expectRejected = [](ParticleEffects e, const std::string& field) {
    try {
      validateEffects(e, "effects");
      ADD_FAILURE() << field << " accepted";
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find(field), std::string::npos) << error.what();
    }
  };
  ParticleEffects e;
  e.wind.airDensity = 0;
  expectRejected(e, "effects.wind.airDensity");
  e = {};
  e.wind.velocity.z = INFINITY;
  expectRejected(e, "effects.wind.velocity.z");
  e = {};
  e.wind.gustModes = 0;
  expectRejected(e, "effects.wind.gustModes");
  e = {};
  e.wind.gustScale = -1;
  expectRejected(e, "effects.wind.gustScale");
  e.wind.gustScale = 1e-30;  // (sines of 1e31: NaN at the first step)
  expectRejected(e, "effects.wind.gustScale");
  e = {};
  e.repulsion.radius = NAN;
  expectRejected(e, "effects.repulsion.radius");
  e = {};
  e.repulsion.stiffness = -2;
  expectRejected(e, "effects.repulsion.stiffness");
}

}  // namespace
}  // namespace weft::test
