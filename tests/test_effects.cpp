// tests/test_effects.cpp — the damped spring force law and the ForceField strategies.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "support/sanitizers.hpp"
#include "support/test_support.hpp"
#include "weft/effects/force_field.hpp"
#include "weft/effects/spring_force.hpp"

namespace weft::test {
namespace {

template <class S>
class SpringForce : public ::testing::Test {};
TYPED_TEST_SUITE(SpringForce, ScalarTypes);

template <class S>
struct SpringInput {
  S dx[3], dv[3];
  S rest, ks, kd;
};

template <class S>
std::array<S, 3> force(const SpringInput<S>& in) {
  std::array<S, 3> f{};
  dampedSpringForce<S>(in.dx[0], in.dx[1], in.dx[2], in.dv[0], in.dv[1], in.dv[2], in.rest, in.ks, in.kd, f[0], f[1],
                       f[2]);
  return f;
}

/// Witkin/Baraff, written out independently in long double from the (rounded) S inputs:
/// f_a = -[ks (|dx| - r) + kd (dv . dx) / |dx|] dx / |dx|.
template <class S>
std::array<long double, 3> referenceForce(const SpringInput<S>& in) {
  long double d[3], v[3];
  for (int c = 0; c < 3; ++c) d[c] = in.dx[c], v[c] = in.dv[c];
  const long double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  const long double dvDotDx = v[0] * d[0] + v[1] * d[1] + v[2] * d[2];
  const long double magnitude =
      static_cast<long double>(in.ks) * (len - in.rest) + static_cast<long double>(in.kd) * dvDotDx / len;
  std::array<long double, 3> f{};
  for (int c = 0; c < 3; ++c) f[c] = -magnitude * d[c] / len;
  return f;
}

/// Random springs: lengths around the rest length (stretched and compressed), arbitrary
/// directions and relative velocities.
template <class S>
std::vector<SpringInput<S>> randomSprings(int count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1, 1), rest(0.01, 2), ks(0, 1000), kd(0, 5), stretch(0.2, 3);
  std::vector<SpringInput<S>> out;
  for (int k = 0; k < count; ++k) {
    SpringInput<S> in{};
    double d[3];
    double n2 = 0;
    do {
      for (double& c : d) c = unit(rng);
      n2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    } while (n2 < 1e-4 || n2 > 1);
    const double r = rest(rng), len = r * stretch(rng);
    for (int c = 0; c < 3; ++c) {
      in.dx[c] = static_cast<S>(d[c] / std::sqrt(n2) * len);
      in.dv[c] = static_cast<S>(3 * unit(rng));
    }
    in.rest = static_cast<S>(r);
    in.ks = static_cast<S>(ks(rng));
    in.kd = static_cast<S>(kd(rng));
    out.push_back(in);
  }
  return out;
}

/// Size of the terms the force is made of: a bound for its rounding error is a few eps of it.
template <class S>
long double forceScale(const SpringInput<S>& in) {
  long double len2 = 0, dv2 = 0;
  for (int c = 0; c < 3; ++c) len2 += (long double)in.dx[c] * in.dx[c], dv2 += (long double)in.dv[c] * in.dv[c];
  return in.ks * (std::sqrt(len2) + in.rest) + in.kd * std::sqrt(dv2);
}

TYPED_TEST(SpringForce, MatchesWitkinBaraffInLongDouble) {
  using S = TypeParam;
  for (const SpringInput<S>& in : randomSprings<S>(2000, 1)) {
    const auto f = force(in);
    const auto ref = referenceForce(in);
    const long double tol = 16 * eps<S>() * forceScale(in);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(static_cast<long double>(f[c]), ref[c], tol) << "component " << c;
  }
}

TYPED_TEST(SpringForce, ForceOnBIsExactlyMinusForceOnA) {
  using S = TypeParam;
  for (const SpringInput<S>& in : randomSprings<S>(500, 2)) {
    SpringInput<S> swapped = in;  // the same spring seen from b: dx and dv change sign
    for (int c = 0; c < 3; ++c) swapped.dx[c] = -in.dx[c], swapped.dv[c] = -in.dv[c];
    const auto fa = force(in);
    const auto fb = force(swapped);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(fb[c], -fa[c]) << "component " << c;
  }
}

TYPED_TEST(SpringForce, UndampedForceIsMinusEnergyGradient) {
  using S = TypeParam;
  using LD = long double;
  for (SpringInput<S> in : randomSprings<S>(500, 3)) {
    in.kd = 0;
    const auto f = force(in);
    // E(dx) = ks (|dx| - r)^2 / 2, with dx = x_a - x_b, so the force on a is -dE/dx.
    const auto energy = [&](const LD* d) {
      return springEnergy<LD>(std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), in.rest, in.ks);
    };
    LD len = 0;
    for (int c = 0; c < 3; ++c) len += (LD)in.dx[c] * in.dx[c];
    len = std::sqrt(len);
    const LD h = 1e-6L * len;
    for (int c = 0; c < 3; ++c) {
      LD plus[3] = {in.dx[0], in.dx[1], in.dx[2]}, minus[3] = {in.dx[0], in.dx[1], in.dx[2]};
      plus[c] += h;
      minus[c] -= h;
      const LD gradient = (energy(plus) - energy(minus)) / (2 * h);
      EXPECT_NEAR(static_cast<LD>(f[c]), -gradient, 16 * eps<S>() * forceScale(in) + 1e-9L * in.ks * len)
          << "component " << c;
    }
  }
}

TYPED_TEST(SpringForce, SpringEnergyIsHalfKsStretchSquared) {
  using S = TypeParam;
  EXPECT_EQ(springEnergy<S>(S(3), S(1), S(10)), S(20));
  EXPECT_EQ(springEnergy<S>(S(1), S(3), S(10)), S(20));
  EXPECT_EQ(springEnergy<S>(S(2), S(2), S(10)), S(0));
}

TYPED_TEST(SpringForce, StretchedSpringPullsCompressedSpringPushes) {
  using S = TypeParam;
  S fx, fy, fz;
  // a at +x of b, stretched: force on a points to b (-x).
  dampedSpringForce<S>(S(2), S(0), S(0), S(0), S(0), S(0), S(1), S(10), S(0), fx, fy, fz);
  EXPECT_EQ(fx, S(-10));
  EXPECT_EQ(fy, S(0));
  EXPECT_EQ(fz, S(0));
  // Compressed: pushes a away (+x).
  dampedSpringForce<S>(S(0.5), S(0), S(0), S(0), S(0), S(0), S(1), S(10), S(0), fx, fy, fz);
  EXPECT_EQ(fx, S(5));
  // Damping opposes the relative velocity along the spring (a moving away from b).
  dampedSpringForce<S>(S(1), S(0), S(0), S(2), S(7), S(0), S(1), S(10), S(0.5), fx, fy, fz);
  EXPECT_EQ(fx, S(-1));
  EXPECT_EQ(fy, S(0));  // the perpendicular part of dv is not damped
}

TYPED_TEST(SpringForce, ZeroLengthSpringGivesZeroForceNotNaN) {
  using S = TypeParam;
  S f[3] = {S(1), S(1), S(1)};
  dampedSpringForce<S>(S(0), S(0), S(0), S(1), S(-2), S(3), S(0.5), S(100), S(2), f[0], f[1], f[2]);
  for (int c = 0; c < 3; ++c) {
    EXPECT_TRUE(std::isfinite(f[c])) << "component " << c;
    EXPECT_EQ(f[c], S(0)) << "component " << c;
  }
  // Also with rest length 0 (no force wanted at all) and without velocity.
  dampedSpringForce<S>(S(0), S(0), S(0), S(0), S(0), S(0), S(0), S(100), S(2), f[0], f[1], f[2]);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(f[c], S(0)) << "component " << c;
}

TYPED_TEST(SpringForce, TinyLengthsGiveFiniteBoundedForce) {
  using S = TypeParam;
  const S rest = S(0.5), ks = S(100), kd = S(2);
  const S dv[3] = {S(1), S(-2), S(3)};
  const long double bound = (long double)ks * rest + (long double)kd * std::sqrt(14.0L);
  const double tinies[] = {std::is_same_v<S, float> ? 1e-20 : 1e-30,   // the required tiny lengths
                           std::is_same_v<S, float> ? 1e-18 : 1e-150,  // still has a direction
                           static_cast<double>(std::numeric_limits<S>::denorm_min())};
  for (const double tiny : tinies) {
    for (const auto& dir :
         {std::array<double, 3>{1, 0, 0}, std::array<double, 3>{0.6, -0.8, 0}, std::array<double, 3>{1, 1, 1}}) {
      SCOPED_TRACE(::testing::Message() << "length " << tiny << ", direction " << dir[0] << " " << dir[1] << " "
                                        << dir[2]);
      S f[3];
      const S d[3] = {static_cast<S>(tiny * dir[0]), static_cast<S>(tiny * dir[1]), static_cast<S>(tiny * dir[2])};
      dampedSpringForce<S>(d[0], d[1], d[2], dv[0], dv[1], dv[2], rest, ks, kd, f[0], f[1], f[2]);
      long double norm2 = 0;
      for (int c = 0; c < 3; ++c) {
        EXPECT_TRUE(std::isfinite(f[c])) << "component " << c << " = " << f[c];
        norm2 += (long double)f[c] * f[c];
      }
      // |f| = |ks (len - r) + kd dv.dx/|dx|| <= ks r + kd |dv| for len <= r.
      EXPECT_LE(std::sqrt(norm2), bound * (1 + 8 * eps<S>()));
    }
  }
  // A length whose square is still normal keeps its direction: a compressed spring
  // pushes a away from b with about ks r.
  S fx, fy, fz;
  const S len = std::is_same_v<S, float> ? S(1e-18) : S(1e-30);
  dampedSpringForce<S>(len, S(0), S(0), S(0), S(0), S(0), rest, ks, S(0), fx, fy, fz);
  EXPECT_NEAR(fx, ks * rest, 4 * eps<S>() * ks * rest);
  EXPECT_EQ(fy, S(0));
  EXPECT_EQ(fz, S(0));
}

// ---------------------------------------------------------------------------------------
// ForceField
// ---------------------------------------------------------------------------------------

template <class S>
class ForceFieldTest : public ::testing::Test {};
TYPED_TEST_SUITE(ForceFieldTest, ScalarTypes);

/// Accelerations computed naively in long double, and per particle the sum of the
/// magnitudes of the terms (the scale of the rounding error of any summation order).
template <class S>
struct Reference {
  std::vector<std::array<long double, 3>> a;
  std::vector<long double> scale;
};

template <class S>
Reference<S> referenceAccelerations(const Model<S>& model, const State<S>& state, const Vec3d& g) {
  const Index n = model.particleCount();
  Reference<S> r;
  r.a.assign(n, {0, 0, 0});
  r.scale.assign(n, 0);
  const Springs<S>& sp = model.springs();
  for (Index s = 0; s < sp.count(); ++s) {
    SpringInput<S> in{};
    for (int c = 0; c < 3; ++c) {
      // dx rounded to S as the kernel does, then the law in long double.
      in.dx[c] = state.x(sp.a[s], c) - state.x(sp.b[s], c);
      in.dv[c] = state.v(sp.a[s], c) - state.v(sp.b[s], c);
    }
    in.rest = sp.restLength[s];
    in.ks = sp.stiffness[s];
    in.kd = sp.damping[s];
    const auto f = referenceForce(in);
    const long double scale = forceScale(in);
    for (int c = 0; c < 3; ++c) {
      r.a[sp.a[s]][c] += f[c];
      r.a[sp.b[s]][c] -= f[c];
    }
    r.scale[sp.a[s]] += scale;
    r.scale[sp.b[s]] += scale;
  }
  const long double gv[3] = {g.x, g.y, g.z};
  for (Index i = 0; i < n; ++i) {
    const long double w = model.inverseMass()[i];
    for (int c = 0; c < 3; ++c) r.a[i][c] = w * r.a[i][c] + (w > 0 ? gv[c] : 0.0L);
    r.scale[i] = w * r.scale[i] + std::sqrt(gv[0] * gv[0] + gv[1] * gv[1] + gv[2] * gv[2]);
  }
  return r;
}

template <class S>
Vec3Array<S> accelerations(const Model<S>& model, const State<S>& state, ForceStrategy strategy, const Vec3d& g,
                           int threads) {
  ForceField<S> field(model, strategy, g);
  const Executor exec(threads);
  Vec3Array<S> a = Vec3Array<S>::Constant(model.particleCount(), 3, std::numeric_limits<S>::quiet_NaN());
  field.accelerations(state.x, state.v, a, exec);
  return a;
}

/// Each strategy against the long-double reference, and the strategies against each other.
template <class S>
void expectStrategiesAgree(const Model<S>& model, const State<S>& state, const Vec3d& g,
                           std::initializer_list<ForceStrategy> strategies, int threads) {
  const Reference<S> ref = referenceAccelerations(model, state, g);
  std::vector<Vec3Array<S>> results;
  for (const ForceStrategy strategy : strategies) {
    SCOPED_TRACE(forceStrategyName(strategy));
    results.push_back(accelerations(model, state, strategy, g, threads));
    const Vec3Array<S>& a = results.back();
    ASSERT_TRUE(a.allFinite());
    for (Index i = 0; i < model.particleCount(); ++i)
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(static_cast<long double>(a(i, c)), ref.a[i][c], 32 * eps<S>() * ref.scale[i])
            << "particle " << i << ", component " << c;
  }
  for (size_t k = 1; k < results.size(); ++k)
    for (Index i = 0; i < model.particleCount(); ++i)
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(results[k](i, c), results[0](i, c), 64 * eps<S>() * ref.scale[i])
            << forceStrategyName(*(strategies.begin() + k)) << " vs " << forceStrategyName(*strategies.begin())
            << ", particle " << i << ", component " << c;
}

const Vec3d kGravity{0, -9.81, 0};

TYPED_TEST(ForceFieldTest, AllStrategiesAgreeOnAPerturbedFlag) {
  using S = TypeParam;
  ModelAndState<S> flag = makeFlag<S>(16);
  perturbFree(flag.model, flag.state, 0.2 / 15, 0.5, 7);
  expectStrategiesAgree(flag.model, flag.state, kGravity,
                        {ForceStrategy::Gather, ForceStrategy::Coloured, ForceStrategy::GridStencil}, 1);
}

TYPED_TEST(ForceFieldTest, AllStrategiesAgreeOnALargerFlagWithTwoThreads) {
  using S = TypeParam;
  // Large enough for several blocks in every pass (springs > kSpringGrain, particles >
  // kParticleGrain), so the parallel paths of each strategy run.
  ModelAndState<S> flag = makeFlag<S>(48);
  ASSERT_GT(flag.model.springCount(), 2 * ForceField<S>::kSpringGrain);
  ASSERT_GT(flag.model.particleCount(), 2 * ForceField<S>::kParticleGrain);
  perturbFree(flag.model, flag.state, 0.2 / 47, 0.5, 8);
  expectStrategiesAgree(flag.model, flag.state, kGravity,
                        {ForceStrategy::Gather, ForceStrategy::Coloured, ForceStrategy::GridStencil}, 2);
}

TYPED_TEST(ForceFieldTest, AllStrategiesAgreeOnAGridWithoutShearOrBendSprings) {
  using S = TypeParam;
  for (const bool shear : {false, true}) {
    ClothGridSpec spec = flagSpec(9);
    spec.width = 5;  // not square: catches a width/height mix-up
    spec.shearSprings = shear;
    spec.bendSprings = !shear;
    ModelBuilder<S> builder;
    addClothGrid(builder, spec);
    builder.pin(3);
    ModelAndState<S> grid = builder.build();
    perturbFree(grid.model, grid.state, 0.02, 0.5, 9);
    expectStrategiesAgree(grid.model, grid.state, kGravity,
                          {ForceStrategy::Gather, ForceStrategy::Coloured, ForceStrategy::GridStencil}, 1);
  }
}

TYPED_TEST(ForceFieldTest, AllStrategiesAgreeOnGridsOfEveryShape) {
  using S = TypeParam;
  // Shapes that stress the grid stencil's bookkeeping: the smallest grids, one row or
  // column of bend springs, a width beyond one stencil chunk, a tall narrow grid over
  // several chunks, a height that is not a multiple of the chunk; each with every subset
  // of the optional spring classes (2, 4 or 6 families). Two threads, so chunks run in
  // parallel.
  struct Shape {
    Index w, h;
  };
  for (const Shape shape :
       {Shape{2, 2}, Shape{2, 7}, Shape{7, 2}, Shape{3, 3}, Shape{3, 1000}, Shape{50, 97}, Shape{2100, 3}})
    for (const int classes : {0, 1, 2, 3}) {
      SCOPED_TRACE(::testing::Message() << shape.w << " x " << shape.h << ", shear " << (classes & 1) << ", bend "
                                        << (classes >> 1));
      ClothGridSpec spec = flagSpec(8);
      spec.width = shape.w;
      spec.height = shape.h;
      spec.spacing = 0.05;
      spec.shearSprings = classes & 1;
      spec.bendSprings = classes & 2;
      ModelBuilder<S> builder;
      addClothGrid(builder, spec);
      builder.pin(0);
      ModelAndState<S> grid = builder.build();
      perturbFree(grid.model, grid.state, 0.01, 0.5, 14 + classes);
      expectStrategiesAgree(grid.model, grid.state, kGravity,
                            {ForceStrategy::Gather, ForceStrategy::Coloured, ForceStrategy::GridStencil}, 2);
      if (testing::Test::HasFatalFailure()) return;
    }
}

TYPED_TEST(ForceFieldTest, GridStencilAgreesOnEveryWidthOfAShearOnlyGrid) {
  using S = TypeParam;
  // Without bend springs the halo is one row, and the shear family (1, 1) reaches one slot
  // before its window row for the first particle of a chunk; at some widths the window had no
  // padding there and that slot held another family's force. Every width up to 160, over
  // several chunks, two threads. Under ThreadSanitizer every 7th width: the threads do the
  // same at every width, and the other builds check each one.
  constexpr Index kWidthStep = weft::test::kThreadSanitizer ? 7 : 1;
  for (Index w = 2; w <= 160; w += kWidthStep) {
    SCOPED_TRACE(::testing::Message() << "width " << w);
    ClothGridSpec spec = flagSpec(8);
    spec.width = w;
    spec.height = 4 * std::max<Index>(2, 2048 / w) + 3;  // several stencil chunks and a partial one
    spec.spacing = 0.05;
    spec.shearSprings = true;
    spec.bendSprings = false;
    ModelBuilder<S> builder;
    addClothGrid(builder, spec);
    builder.pin(0);
    ModelAndState<S> grid = builder.build();
    perturbFree(grid.model, grid.state, 0.01, 0.5, 40 + static_cast<std::uint32_t>(w));
    expectStrategiesAgree(grid.model, grid.state, kGravity, {ForceStrategy::Gather, ForceStrategy::GridStencil}, 2);
    if (testing::Test::HasFailure()) return;
  }
}

TYPED_TEST(ForceFieldTest, RepeatedCallsGiveTheSameResult) {
  using S = TypeParam;
  // Scratch buffers are reused between calls: a second call (after one at other
  // positions) must not see anything left over from the first.
  ModelAndState<S> flag = makeFlag<S>(48);
  ModelAndState<S> other = makeFlag<S>(48);
  perturbFree(flag.model, flag.state, 0.004, 0.5, 15);
  perturbFree(other.model, other.state, 0.004, 0.5, 16);
  const Executor exec(2);
  for (const ForceStrategy strategy : kGridStrategies) {
    SCOPED_TRACE(forceStrategyName(strategy));
    ForceField<S> field(flag.model, strategy, kGravity);
    Vec3Array<S> first(flag.model.particleCount(), 3), scratch(flag.model.particleCount(), 3),
        second(flag.model.particleCount(), 3);
    field.accelerations(flag.state.x, flag.state.v, first, exec);
    field.accelerations(other.state.x, other.state.v, scratch, exec);
    field.accelerations(flag.state.x, flag.state.v, second, exec);
    EXPECT_TRUE(first == second);
  }
}

TYPED_TEST(ForceFieldTest, SinkSeesEveryParticleOnceWithTheSameAccelerations) {
  using S = TypeParam;
  // The block interface the integrators use: each particle handed over exactly once per
  // evaluation, in blocks of at most kSinkBlock, with the values of the array interface.
  ModelAndState<S> flag = makeFlag<S>(48);
  perturbFree(flag.model, flag.state, 0.004, 0.5, 17);
  ModelAndState<S> rope = makeRope<S>(300);
  perturbFree(rope.model, rope.state, 0.002, 0.5, 18);
  const Executor exec(2);
  for (const ForceStrategy strategy : kGridStrategies)
    for (const ModelAndState<S>* m : {&flag, &rope}) {
      if (strategy == ForceStrategy::GridStencil && !m->model.grid()) continue;
      SCOPED_TRACE(::testing::Message() << forceStrategyName(strategy) << ", " << m->model.particleCount()
                                        << " particles");
      const Index count = m->model.particleCount();
      ForceField<S> field(m->model, strategy, kGravity);
      Vec3Array<S> expected(count, 3);
      field.accelerations(m->state.x, m->state.v, expected, exec);
      Vec3Array<S> got = Vec3Array<S>::Constant(count, 3, S(-12345));
      std::vector<std::atomic<int>> seen(static_cast<size_t>(count));
      std::atomic<int> oversized{0}, outOfRange{0};
      auto consume = [&](Index begin, Index len, const S* ax, const S* ay, const S* az) {
        if (len > ForceField<S>::kSinkBlock) ++oversized;
        if (begin < 0 || len < 0 || begin + len > count) {
          ++outOfRange;
          return;
        }
        for (Index t = 0; t < len; ++t) {
          ++seen[static_cast<size_t>(begin + t)];
          got(begin + t, 0) = ax[t];
          got(begin + t, 1) = ay[t];
          got(begin + t, 2) = az[t];
        }
      };
      field.accelerations(m->state.x, m->state.v, makeSink<S>(consume), exec);
      EXPECT_EQ(oversized.load(), 0);
      ASSERT_EQ(outOfRange.load(), 0);
      for (Index i = 0; i < count; ++i) ASSERT_EQ(seen[static_cast<size_t>(i)].load(), 1) << "particle " << i;
      EXPECT_TRUE(got == expected);
    }
}

TYPED_TEST(ForceFieldTest, GridWithAnExtraSpringKeepsEverySpring) {
  using S = TypeParam;
  // A cloth grid plus one spring of the user's own (a tether across the cloth): whatever
  // strategy Auto picks must include it.
  ModelBuilder<S> builder;
  addClothGrid(builder, flagSpec(6));
  builder.addSpring(0, 35, {300, 0.1}, SpringClass::Structural, 0.5);
  ModelAndState<S> m = builder.build();
  perturbFree(m.model, m.state, 0.02, 0.5, 10);
  expectStrategiesAgree(m.model, m.state, kGravity,
                        {ForceStrategy::Auto, ForceStrategy::Gather, ForceStrategy::Coloured}, 1);
}

TYPED_TEST(ForceFieldTest, GatherAndColouredAgreeOnARope) {
  using S = TypeParam;
  ModelAndState<S> rope = makeRope<S>(40);
  perturbFree(rope.model, rope.state, 0.01, 0.5, 11);
  expectStrategiesAgree(rope.model, rope.state, kGravity, {ForceStrategy::Gather, ForceStrategy::Coloured}, 1);
}

TYPED_TEST(ForceFieldTest, GatherAndColouredAgreeOnAnIrregularModel) {
  using S = TypeParam;
  // Random springs between random particles, including several springs on the same pair.
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_int_distribution<Index> pick(0, 29);
  ModelBuilder<S> builder;
  for (int i = 0; i < 30; ++i)
    builder.addParticle({u(rng), u(rng), u(rng)}, 0.1 + 0.05 * (i % 7), {u(rng), u(rng), u(rng)});
  for (int s = 0; s < 200; ++s) {
    const Index a = pick(rng);
    Index b = pick(rng);
    if (b == a) b = (a + 1) % 30;
    builder.addSpring(a, b, {50 + 50 * u(rng), 0.5 + 0.4 * u(rng)}, SpringClass::Structural, 0.5 + 0.3 * u(rng));
  }
  builder.pin(4);
  ModelAndState<S> m = builder.build();
  expectStrategiesAgree(m.model, m.state, kGravity, {ForceStrategy::Gather, ForceStrategy::Coloured}, 1);
}

TYPED_TEST(ForceFieldTest, ColouringIsProper) {
  using S = TypeParam;
  const ModelAndState<S> flag = makeFlag<S>(16);
  ForceField<S> coloured(flag.model, ForceStrategy::Coloured, kGravity);
  // A grid particle has up to 12 springs: a greedy edge colouring needs at most 2*12-1.
  EXPECT_GE(coloured.colourCount(), 12);
  EXPECT_LE(coloured.colourCount(), 23);
  ForceField<S> gather(flag.model, ForceStrategy::Gather, kGravity);
  EXPECT_EQ(gather.colourCount(), 0);
}

TYPED_TEST(ForceFieldTest, AutoPicksGridStencilForGridsAndGatherOtherwise) {
  using S = TypeParam;
  const ModelAndState<S> flag = makeFlag<S>(8);
  const ModelAndState<S> rope = makeRope<S>(8);
  EXPECT_EQ(ForceField<S>(flag.model, ForceStrategy::Auto, kGravity).strategy(), ForceStrategy::GridStencil);
  EXPECT_EQ(ForceField<S>(rope.model, ForceStrategy::Auto, kGravity).strategy(), ForceStrategy::Gather);
  EXPECT_EQ(ForceField<S>(flag.model, ForceStrategy::Coloured, kGravity).strategy(), ForceStrategy::Coloured);
}

TYPED_TEST(ForceFieldTest, GridStencilOnARopeThrows) {
  using S = TypeParam;
  const ModelAndState<S> rope = makeRope<S>(8);
  try {
    ForceField<S> field(rope.model, ForceStrategy::GridStencil, kGravity);
    FAIL() << "GridStencil accepted a model without a grid layout";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("grid"), std::string::npos) << e.what();
  }
}

TYPED_TEST(ForceFieldTest, PinnedParticlesGetExactlyZeroAcceleration) {
  using S = TypeParam;
  ModelAndState<S> flag = makeFlag<S>(16);
  perturbFree(flag.model, flag.state, 0.2 / 15, 0.5, 13);
  ASSERT_EQ(flag.model.pinnedCount(), 2);
  for (const ForceStrategy strategy : kGridStrategies) {
    SCOPED_TRACE(forceStrategyName(strategy));
    const Vec3Array<S> a = accelerations(flag.model, flag.state, strategy, kGravity, 1);
    for (Index i = 0; i < flag.model.particleCount(); ++i) {
      if (!flag.model.isPinned(i)) continue;
      for (int c = 0; c < 3; ++c) EXPECT_EQ(a(i, c), S(0)) << "particle " << i << ", component " << c;
    }
  }
}

TYPED_TEST(ForceFieldTest, WithoutSpringsFreeParticlesGetExactlyGravity) {
  using S = TypeParam;
  ModelBuilder<S> builder;
  for (int i = 0; i < 10; ++i) builder.addParticle({double(i), 0.5 * i, -1.0 * i}, 0.1 * (i + 1), {1, 2, 3});
  builder.pin(3);
  const ModelAndState<S> m = builder.build();
  const Vec3d g{0.5, -9.81, 1.25};
  for (const ForceStrategy strategy : kGeneralStrategies) {
    SCOPED_TRACE(forceStrategyName(strategy));
    const Vec3Array<S> a = accelerations(m.model, m.state, strategy, g, 1);
    for (Index i = 0; i < m.model.particleCount(); ++i) {
      const bool pinned = m.model.isPinned(i);
      EXPECT_EQ(a(i, 0), pinned ? S(0) : static_cast<S>(g.x)) << "particle " << i;
      EXPECT_EQ(a(i, 1), pinned ? S(0) : static_cast<S>(g.y)) << "particle " << i;
      EXPECT_EQ(a(i, 2), pinned ? S(0) : static_cast<S>(g.z)) << "particle " << i;
    }
  }
}

TYPED_TEST(ForceFieldTest, RestingFlagWithoutGravityHasZeroAcceleration) {
  using S = TypeParam;
  // At rest length everywhere and with no motion, every spring force is zero (up to the
  // rounding of the rest positions).
  const ModelAndState<S> flag = makeFlag<S>(12);
  for (const ForceStrategy strategy : kGridStrategies) {
    SCOPED_TRACE(forceStrategyName(strategy));
    const Vec3Array<S> a = accelerations(flag.model, flag.state, strategy, Vec3d{0, 0, 0}, 1);
    const double scale = 500.0 / flag.model.mass()[5] * (1.0 / 11);  // ks / m * spacing
    EXPECT_LE(static_cast<double>(a.cwiseAbs().maxCoeff()), 64 * eps<S>() * scale);
  }
}

TEST(ForceStrategyNames, ParseAndName) {
  EXPECT_EQ(parseForceStrategy("auto"), ForceStrategy::Auto);
  EXPECT_EQ(parseForceStrategy("gather"), ForceStrategy::Gather);
  EXPECT_EQ(parseForceStrategy("coloured"), ForceStrategy::Coloured);
  EXPECT_EQ(parseForceStrategy("colored"), ForceStrategy::Coloured);
  EXPECT_EQ(parseForceStrategy("grid"), ForceStrategy::GridStencil);
  EXPECT_EQ(parseForceStrategy("grid-stencil"), ForceStrategy::GridStencil);
  for (const ForceStrategy s :
       {ForceStrategy::Auto, ForceStrategy::Gather, ForceStrategy::Coloured, ForceStrategy::GridStencil})
    EXPECT_EQ(parseForceStrategy(forceStrategyName(s)), s);
  try {
    (void)parseForceStrategy("scatter");
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("scatter"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace weft::test

// ---------------------------------------------------------------------------------------
// Spring Jacobian (implicit Euler's matrix-free products)
// ---------------------------------------------------------------------------------------

namespace weft::test {
namespace {

TEST(SpringJacobian, ProductsMatchFiniteDifferencesOfTheForce) {
  // A free cloth (no pins, no gravity: f = m a) stretched by 20% so every spring is in
  // tension (the clamp c = max(0, 1 - r/L) is inactive and the linearisation exact to
  // first order), with random velocities.
  ModelAndState<double> cloth = makeFreeFlag<double>(6);
  cloth.state.x *= 1.2;
  addNoise<double>(cloth.state.x, 0.002, 5);
  addNoise<double>(cloth.state.v, 0.3, 6);
  const Model<double>& model = cloth.model;
  const Index n = model.particleCount();
  const Executor exec(1);
  ForceField<double> forces(model, ForceStrategy::Gather, {0, 0, 0});
  const auto force = [&](const Vec3Array<double>& x, const Vec3Array<double>& v) {
    Vec3Array<double> a(n, 3);
    forces.accelerations(x, v, a, exec);
    for (Index i = 0; i < n; ++i) a.row(i) *= model.mass()[i];
    return a;
  };
  Vec3Array<double> p = Vec3Array<double>::Zero(n, 3);
  addNoise<double>(p, 1.0, 7);
  const double h = 0.01, eps = 1e-6;

  SpringJacobian<double> jacobian(model);
  jacobian.linearize(cloth.state.x, h, exec);
  const auto collect = [&](auto product) {
    Vec3Array<double> y(n, 3);
    auto store = [&](Index b, Index m, const double* yx, const double* yy, const double* yz) {
      for (Index t = 0; t < m; ++t) y.row(b + t) << yx[t], yy[t], yz[t];
    };
    product(makeSink<double>(store));
    return y;
  };
  const Vec3Array<double> Kp =
      collect([&](const AccelerationSink<double>& s) { jacobian.stiffnessProduct(p, s, exec); });
  const Vec3Array<double> Ap = collect([&](const AccelerationSink<double>& s) { jacobian.systemProduct(p, s, exec); });

  // -h^2 df/dx p by central differences in x (the velocity-dependent term's x derivative
  // is dropped by design: use v = 0 for this one).
  const Vec3Array<double> v0 = Vec3Array<double>::Zero(n, 3);
  const Vec3Array<double> dfdx = (force(cloth.state.x + eps * p, v0) - force(cloth.state.x - eps * p, v0)) / (2 * eps);
  const Vec3Array<double> expectedK = -h * h * dfdx;
  EXPECT_LT((Kp - expectedK).cwiseAbs().maxCoeff(), 1e-6 * expectedK.cwiseAbs().maxCoeff());

  // A p - M p + h^2 df/dx p = -h df/dv p, the damping part, by differences in v.
  const Vec3Array<double> dfdv =
      (force(cloth.state.x, cloth.state.v + eps * p) - force(cloth.state.x, cloth.state.v - eps * p)) / (2 * eps);
  Vec3Array<double> Mp = p;
  for (Index i = 0; i < n; ++i) Mp.row(i) *= model.mass()[i];
  const Vec3Array<double> dampingPart = Ap - Mp - Kp;
  const Vec3Array<double> expectedD = -h * dfdv;
  EXPECT_LT((dampingPart - expectedD).cwiseAbs().maxCoeff(), 1e-6 * expectedD.cwiseAbs().maxCoeff());

  // The diagonal of A is the diagonal of the operator: e_k^T A e_k.
  for (const Index i : {Index(0), Index(7), n - 1})
    for (int c = 0; c < 3; ++c) {
      Vec3Array<double> e = Vec3Array<double>::Zero(n, 3);
      e(i, c) = 1;
      const Vec3Array<double> Ae =
          collect([&](const AccelerationSink<double>& s) { jacobian.systemProduct(e, s, exec); });
      EXPECT_NEAR(jacobian.diagonal()(i, c), Ae(i, c), 1e-12 * Ae(i, c)) << i << ", " << c;
    }
}

TEST(SpringJacobian, BlocksAreEachSpringsCouplingAndSumToTheDiagonalBlocks) {
  // On a grid model (stencil products) and a mesh model (products through the incidence
  // lists), stretched, with a drag: column c of the product with
  // e_(i, c) is column c of A's blocks in row i, so (A e_(a, c))_b = -B_s e_c for a spring
  // s = (a, b) (the only one joining them), and A's diagonal block of i is what
  // diagonal() and offDiagonal() say, and (m_i + h drag) I plus the blocks of i's springs.
  ModelAndState<double> grid = makeFreeFlag<double>(6);
  ModelAndState<double> mesh = makeMeshSheets(6);
  for (ModelAndState<double>* cloth : {&grid, &mesh}) {
    SCOPED_TRACE(cloth == &grid ? "grid" : "mesh");
    ASSERT_EQ(cloth->model.grid().has_value(), cloth == &grid);
    cloth->state.x *= 1.1;
    addNoise<double>(cloth->state.x, 0.002, 11);
    const Model<double>& model = cloth->model;
    const Index n = model.particleCount();
    const Executor exec(2);
    const double h = 0.01, drag = 0.3;
    SpringJacobian<double> jacobian(model);
    jacobian.linearize(cloth->state.x, h, exec, drag);
    const double* blocks = jacobian.blocks();
    const auto column = [&](Index i, int c) {
      Vec3Array<double> e = Vec3Array<double>::Zero(n, 3), y(n, 3);
      e(i, c) = 1;
      auto store = [&](Index b, Index m, const double* yx, const double* yy, const double* yz) {
        for (Index t = 0; t < m; ++t) y.row(b + t) << yx[t], yy[t], yz[t];
      };
      jacobian.systemProduct(e, makeSink<double>(store), exec);
      return y;
    };
    // A symmetric block from its six stored numbers, xx yy zz xy xz yz.
    const auto full = [](const double* k) {
      Eigen::Matrix3d m;
      m << k[0], k[3], k[4], k[3], k[1], k[5], k[4], k[5], k[2];
      return m;
    };
    const Springs<double>& sp = model.springs();
    for (const Index s : {Index(0), Index(5), sp.count() / 2, sp.count() - 1}) {
      const Index a = sp.a[s], b = sp.b[s];
      for (int c = 0; c < 3; ++c) {
        const Vec3Array<double> y = column(a, c);
        for (int r = 0; r < 3; ++r) EXPECT_NEAR(-y(b, r), full(blocks + 6 * s)(r, c), 1e-12) << s << " " << r << c;
      }
    }
    for (const Index i : {Index(0), Index(7), n / 2, n - 1}) {
      Eigen::Matrix3d sum = Eigen::Matrix3d::Identity() * (model.mass()[i] + h * drag);
      for (Index s = 0; s < sp.count(); ++s)
        if (sp.a[s] == i || sp.b[s] == i) sum += full(blocks + 6 * s);
      const double d[6] = {jacobian.diagonal()(i, 0),    jacobian.diagonal()(i, 1),    jacobian.diagonal()(i, 2),
                           jacobian.offDiagonal()(i, 0), jacobian.offDiagonal()(i, 1), jacobian.offDiagonal()(i, 2)};
      const double scale = sum.cwiseAbs().maxCoeff();
      EXPECT_LT((full(d) - sum).cwiseAbs().maxCoeff(), 1e-12 * scale) << i;
      for (int c = 0; c < 3; ++c) {
        const Vec3Array<double> y = column(i, c);
        for (int r = 0; r < 3; ++r) EXPECT_NEAR(y(i, r), full(d)(r, c), 1e-12 * scale) << i << " " << r << c;
      }
    }
  }
}

// One grid's system and stiffness products (SpringJacobian::systemProduct and
// stiffnessProduct) on `threads` threads, with or without reserve(), checked against the
// sums over the springs of +-B_s (p_a - p_b) from blocks() (B_s less h kd d d^T for the
// stiffness), to `tolerance` of the largest entry; returns both, side by side (n x 6).
template <class S>
Eigen::Array<S, Eigen::Dynamic, 6> gridProducts(const ModelAndState<S>& cloth, const Vec3Array<S>& x,
                                                const Vec3Array<S>& p, int threads, bool reserve, double tolerance) {
  const Model<S>& model = cloth.model;
  const Index n = model.particleCount();
  const double h = 0.01, drag = 0.2;
  const Executor exec(threads);
  SpringJacobian<S> jacobian(model);
  if (reserve) jacobian.reserve(exec);
  jacobian.linearize(x, static_cast<S>(h), exec, static_cast<S>(drag));
  Eigen::Array<S, Eigen::Dynamic, 6> y = Eigen::Array<S, Eigen::Dynamic, 6>::Constant(n, 6, std::nan(""));
  for (int product = 0; product < 2; ++product) {
    auto store = [&](Index b, Index m, const S* yx, const S* yy, const S* yz) {
      EXPECT_EQ(b % ForceField<S>::kSinkBlock, 0) << b;  // the CG's per-block sums rely on it
      for (Index t = 0; t < m; ++t) {
        y(b + t, 3 * product) = yx[t];
        y(b + t, 3 * product + 1) = yy[t];
        y(b + t, 3 * product + 2) = yz[t];
      }
    };
    if (product == 0)
      jacobian.systemProduct(p, makeSink<S>(store), exec);
    else
      jacobian.stiffnessProduct(p, makeSink<S>(store), exec);
    const Springs<S>& sp = model.springs();
    Eigen::MatrixXd reference(n, 3);
    for (Index i = 0; i < n; ++i)
      reference.row(i) =
          product == 0
              ? ((static_cast<double>(model.mass()[i]) + h * drag) * p.row(i).matrix().template cast<double>()).eval()
              : Eigen::RowVector3d::Zero();
    for (Index s = 0; s < sp.count(); ++s) {
      const S* k = jacobian.blocks() + 6 * s;
      Eigen::Matrix3d block;
      block << k[0], k[3], k[4], k[3], k[1], k[5], k[4], k[5], k[2];
      if (product == 1) {
        const Eigen::Vector3d d = jacobian.directions().row(s).matrix().template cast<double>().transpose();
        block -= h * static_cast<double>(sp.damping[s]) * d * d.transpose();
      }
      const Eigen::Vector3d u = (p.row(sp.a[s]) - p.row(sp.b[s])).matrix().template cast<double>().transpose();
      const Eigen::Vector3d gs = block * u;
      reference.row(sp.a[s]) += gs.transpose();
      reference.row(sp.b[s]) -= gs.transpose();
    }
    const Eigen::MatrixXd got = y.middleCols(3 * product, 3).matrix().template cast<double>();
    const double scale = reference.cwiseAbs().maxCoeff();
    EXPECT_LT((got - reference).cwiseAbs().maxCoeff(), tolerance * scale)
        << (product == 0 ? "system" : "stiffness") << " product, " << threads << " threads";
  }
  return y;
}

TEST(SpringJacobian, GridProductsAreTheSpringSumsForAnyWidthChunkingAndThreadCount) {
  // The stencil products run per chunk of particles, recomputing the rows above a chunk
  // that its gather reaches: grids of a few columns and many chunks, of rows wider than a
  // chunk's default, with and without shear and bend springs (families of other offsets),
  // in double and float. Each is checked against the sum over the springs, and 1, 2 and 3
  // threads give the same bits, with and without reserve().
  struct Case {
    Index width, height;
    bool shear, bend;
  };
  for (const Case g : {Case{7, 400, true, true}, Case{300, 20, true, true}, Case{64, 70, false, false},
                       Case{33, 90, true, false}, Case{2, 1500, false, true}, Case{130, 3, true, true}}) {
    SCOPED_TRACE(std::to_string(g.width) + " x " + std::to_string(g.height) + (g.shear ? " shear" : "") +
                 (g.bend ? " bend" : ""));
    ClothGridSpec spec;
    spec.width = g.width;
    spec.height = g.height;
    spec.spacing = 0.01;
    spec.shearSprings = g.shear;
    spec.bendSprings = g.bend;
    const auto check = [&](auto zero, double tolerance) {
      using S = decltype(zero);
      ModelBuilder<S> builder;
      addClothGrid(builder, spec);
      const ModelAndState<S> cloth = builder.build();
      ASSERT_TRUE(cloth.model.grid().has_value());
      const Index n = cloth.model.particleCount();
      Vec3Array<S> x = cloth.state.x * S(1.1);
      addNoise<S>(x, 0.001, 21);
      Vec3Array<S> p = Vec3Array<S>::Zero(n, 3);
      addNoise<S>(p, 1.0, 22);
      const auto one = gridProducts<S>(cloth, x, p, 1, true, tolerance);
      for (const int threads : {2, 3})
        for (const bool reserve : {true, false}) {
          const auto other = gridProducts<S>(cloth, x, p, threads, reserve, tolerance);
          EXPECT_EQ(std::memcmp(one.data(), other.data(), sizeof(S) * 6 * static_cast<size_t>(n)), 0)
              << sizeof(S) * 8 << " bits, " << threads << " threads, reserve " << reserve;
        }
    };
    check(double(0), 1e-12);
    check(float(0), 1e-4);
  }
}

TEST(SpringJacobian, CompressedSpringsAddNoNegativeStiffnessAndTheSystemIsPositive) {
  // Compressed to 70%: the transverse term ks (1 - r/L) would be negative; it is clamped,
  // so p^T A p > 0 for any p (A symmetric positive definite on the free particles).
  ModelAndState<double> cloth = makeFreeFlag<double>(6);
  cloth.state.x *= 0.7;
  const Model<double>& model = cloth.model;
  const Index n = model.particleCount();
  const Executor exec(2);
  SpringJacobian<double> jacobian(model);
  jacobian.linearize(cloth.state.x, 0.1, exec);
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    Vec3Array<double> p = Vec3Array<double>::Zero(n, 3), q = Vec3Array<double>::Zero(n, 3);
    addNoise<double>(p, 1.0, seed);
    addNoise<double>(q, 1.0, seed + 100);
    Vec3Array<double> Ap(n, 3), Aq(n, 3);
    auto storeP = [&](Index b, Index m, const double* x, const double* y, const double* z) {
      for (Index t = 0; t < m; ++t) Ap.row(b + t) << x[t], y[t], z[t];
    };
    auto storeQ = [&](Index b, Index m, const double* x, const double* y, const double* z) {
      for (Index t = 0; t < m; ++t) Aq.row(b + t) << x[t], y[t], z[t];
    };
    jacobian.systemProduct(p, makeSink<double>(storeP), exec);
    jacobian.systemProduct(q, makeSink<double>(storeQ), exec);
    EXPECT_GT((p.array() * Ap.array()).sum(), 0.0);
    // Symmetry: q^T A p = p^T A q.
    const double qAp = (q.array() * Ap.array()).sum(), pAq = (p.array() * Aq.array()).sum();
    EXPECT_NEAR(qAp, pAq, 1e-12 * std::abs(qAp) + 1e-15);
  }
}

}  // namespace
}  // namespace weft::test

// ---------------------------------------------------------------------------------------
// Viscous drag (ParticleEffects)
// ---------------------------------------------------------------------------------------

namespace weft::test {
namespace {

TEST(Drag, IsExactlyMinusCWVOnEveryStrategyAndZeroOnPinnedParticles) {
  ModelAndState<double> flag = makeFlag<double>(12);
  perturbFree(flag.model, flag.state, 0.01, 0.5, 77);
  const Index n = flag.model.particleCount();
  const double c = 0.003;
  const Executor exec(2);
  for (const ForceStrategy strategy : kGridStrategies) {
    SCOPED_TRACE(forceStrategyName(strategy));
    ForceField<double> plain(flag.model, strategy, {0, -9.81, 0});
    ParticleEffects effects;
    effects.drag = c;
    ForceField<double> dragged(flag.model, strategy, {0, -9.81, 0}, effects);
    Vec3Array<double> a0(n, 3), a1(n, 3);
    plain.accelerations(flag.state.x, flag.state.v, a0, exec);
    dragged.accelerations(flag.state.x, flag.state.v, a1, exec);
    for (Index i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) {
        const double expected = a0(i, k) - (c * flag.model.inverseMass()[i]) * flag.state.v(i, k);
        ASSERT_EQ(a1(i, k), expected) << "particle " << i << " axis " << k;
      }
  }
}

TEST(Drag, AFallingParticleApproachesItsTerminalVelocity) {
  // m v' = m g - c v: v(t) = (m g / c)(1 - exp(-c t / m)).
  const double m = 0.02, c = 0.05, g = 9.81;
  ModelBuilder<double> b;
  b.addParticle({0, 0, 0}, m);
  SimulationOptions options;
  options.integrator = IntegratorKind::Rk4;
  options.dt = 1e-3;
  options.threads = 1;
  options.effects.drag = c;
  Simulation<double> sim(b.build(), options);
  ASSERT_TRUE(sim.run(2000).ok());
  const double t = 2.0, exact = -(m * g / c) * (1 - std::exp(-c * t / m));
  EXPECT_NEAR(sim.state().v(0, 1), exact, 1e-10);
  EXPECT_NEAR(sim.state().v(0, 1), -m * g / c, 0.01 * m * g / c);  // nearly terminal after 5 time constants
}

TEST(Drag, ImplicitEulerTakesHeavyDragAtStepsWhereExplicitMethodsFail) {
  // c / m = 1000 1/s at dt = 0.01 s: explicit Euler's factor |1 - h c / m| = 9.
  const double m = 0.01, c = 10;
  ModelBuilder<double> b;
  b.addParticle({0, 0, 0}, m);
  b.addParticle({0.1, 0, 0}, m);
  b.addSpring(0, 1, {1.0, 0.0});
  b.pin(0);
  const ModelAndState<double> scene = b.build();
  for (const IntegratorKind kind :
       {IntegratorKind::ExplicitEuler, IntegratorKind::Rk4, IntegratorKind::ImplicitEuler}) {
    SCOPED_TRACE(integratorName(kind));
    SimulationOptions options;
    options.integrator = kind;
    options.dt = 0.01;
    options.threads = 1;
    options.effects.drag = c;
    Simulation<double> sim(ModelAndState<double>{scene.model, scene.state}, options);
    const StepStatus status = sim.run(500);
    if (kind == IntegratorKind::ImplicitEuler) {
      ASSERT_TRUE(status.ok()) << status.message();
      // Terminal fall speed m g / c = 0.00981 m/s (the soft spring barely matters at 5 s).
      EXPECT_NEAR(sim.state().v(1, 1), -m * 9.81 / c, 2e-3);
    } else {
      EXPECT_FALSE(status.ok()) << "an explicit method at h c / m = 10 should be flagged";
    }
  }
}

TEST(Drag, BadCoefficientsAreRejectedByName) {
  for (const double bad : {-1.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    SimulationOptions options;
    options.effects.drag = bad;
    try {
      Simulation<double> sim(makeFlag<double>(4), options);
      ADD_FAILURE() << "drag " << bad << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("effects.drag"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace weft::test
