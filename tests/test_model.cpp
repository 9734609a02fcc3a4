// tests/test_model.cpp — ModelBuilder validation, rope and cloth-grid builders, Model.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <functional>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "core/text.hpp"
#include "support/test_support.hpp"
#include "weft/effects/force_field.hpp"

namespace weft::test {
namespace {

template <class S>
class ModelTest : public ::testing::Test {};
TYPED_TEST_SUITE(ModelTest, ScalarTypes);

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

/// Expects f() to throw std::invalid_argument whose message contains `field` and `value`
/// (the value compared case-insensitively, so "nan" matches "NaN" and "-nan").
void expectInvalid(const std::function<void()>& f, const std::string& field, const std::string& value) {
  try {
    f();
    ADD_FAILURE() << "no std::invalid_argument thrown (expected one naming '" << field << "' and '" << value << "')";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(field), std::string::npos) << "message does not name the field '" << field << "': " << what;
    EXPECT_NE(lower(what).find(lower(value)), std::string::npos)
        << "message does not name the value '" << value << "': " << what;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "threw something other than std::invalid_argument: " << e.what();
  }
}

ClothGridSpec gridSpec(Index w, Index h) {
  ClothGridSpec spec;
  spec.width = w;
  spec.height = h;
  spec.spacing = 0.1;
  return spec;
}

struct GridSize {
  Index w, h;
};
constexpr GridSize kGridSizes[] = {{2, 2}, {3, 5}, {7, 4}, {64, 64}};

// ---------------------------------------------------------------------------------------
// Cloth grid
// ---------------------------------------------------------------------------------------

TYPED_TEST(ModelTest, GridSpringCountsPerClass) {
  using S = TypeParam;
  for (const GridSize g : kGridSizes)
    for (const bool shear : {true, false})
      for (const bool bend : {true, false}) {
        SCOPED_TRACE(::testing::Message() << g.w << " x " << g.h << (shear ? " +shear" : "") << (bend ? " +bend" : ""));
        ClothGridSpec spec = gridSpec(g.w, g.h);
        spec.shearSprings = shear;
        spec.bendSprings = bend;
        ModelBuilder<S> builder;
        addClothGrid(builder, spec);
        const ModelAndState<S> built = builder.build();
        const Model<S>& model = built.model;

        const Index w = g.w, h = g.h;
        const Index structural = (w - 1) * h + w * (h - 1);
        const Index shearCount = shear ? 2 * (w - 1) * (h - 1) : 0;
        const Index bendCount = bend ? (w - 2) * h + w * (h - 2) : 0;
        const std::array<Index, kSpringClassCount> formula{structural, shearCount, bendCount};

        EXPECT_EQ(model.particleCount(), w * h);
        EXPECT_EQ(model.springCountByClass(), formula);
        EXPECT_EQ(model.springCountByClass(), expectedGridSpringCounts(spec));
        EXPECT_EQ(expectedGridSpringCounts(spec), formula);
        EXPECT_EQ(model.springCount(), structural + shearCount + bendCount);
        EXPECT_EQ(model.pinnedCount(), 0);
      }
}

TYPED_TEST(ModelTest, GridSpringsJoinTheRightNeighbours) {
  using S = TypeParam;
  const ClothGridSpec spec = gridSpec(7, 4);
  ModelBuilder<S> builder;
  addClothGrid(builder, spec);
  const ModelAndState<S> built = builder.build();
  const Springs<S>& sp = built.model.springs();
  for (Index s = 0; s < sp.count(); ++s) {
    const Index ra = sp.a[s] / spec.width, ca = sp.a[s] % spec.width;
    const Index rb = sp.b[s] / spec.width, cb = sp.b[s] % spec.width;
    const Index dr = rb - ra, dc = cb - ca;
    switch (sp.kind[s]) {
      case SpringClass::Structural:
        EXPECT_TRUE((dr == 0 && dc == 1) || (dr == 1 && dc == 0)) << "spring " << s;
        break;
      case SpringClass::Shear:
        EXPECT_TRUE(dr == 1 && (dc == 1 || dc == -1)) << "spring " << s;
        break;
      case SpringClass::Bend:
        EXPECT_TRUE((dr == 0 && dc == 2) || (dr == 2 && dc == 0)) << "spring " << s;
        break;
    }
  }
}

TYPED_TEST(ModelTest, GridMaterialsPerClass) {
  using S = TypeParam;
  const ClothGridSpec spec = gridSpec(5, 5);
  ModelBuilder<S> builder;
  addClothGrid(builder, spec);
  const ModelAndState<S> built = builder.build();
  const Springs<S>& sp = built.model.springs();
  for (Index s = 0; s < sp.count(); ++s) {
    const SpringMaterial& m = sp.kind[s] == SpringClass::Structural ? spec.structural
                              : sp.kind[s] == SpringClass::Shear    ? spec.shear
                                                                    : spec.bend;
    EXPECT_EQ(sp.stiffness[s], static_cast<S>(m.stiffness)) << "spring " << s;
    EXPECT_EQ(sp.damping[s], static_cast<S>(m.damping)) << "spring " << s;
  }
  // Mass spread evenly.
  for (Index i = 0; i < built.model.particleCount(); ++i)
    EXPECT_EQ(built.model.mass()[i], static_cast<S>(spec.totalMass / 25)) << "particle " << i;
}

TYPED_TEST(ModelTest, RestLengthsEqualInitialDistances) {
  using S = TypeParam;
  // Orthonormal but not axis-aligned frame, so the check is not trivially exact.
  ClothGridSpec spec = gridSpec(9, 6);
  spec.origin = {0.3, -1.2, 2.0};
  spec.rowAxis = {3, 4, 0};
  spec.columnAxis = {0, 0, -2};
  spec.spacing = 0.07;
  ModelBuilder<S> grid;
  addClothGrid(grid, spec);

  RopeSpec rope;
  rope.particleCount = 11;
  rope.origin = {1, 2, 3};
  rope.direction = {1, -2, 2};
  rope.length = 0.8;
  ModelBuilder<S> chain;
  addRope(chain, rope);

  // A spring added without a rest length takes the current distance.
  ModelBuilder<S> free;
  free.addParticle({0.1, 0.2, 0.3}, 1);
  free.addParticle({-0.4, 0.9, 1.3}, 1);
  free.addParticle({2.0, 0.0, -0.5}, 1);
  free.addSpring(0, 1, {10, 0});
  free.addSpring(2, 1, {10, 0}, SpringClass::Bend);

  for (ModelBuilder<S>* b : {&grid, &chain, &free}) {
    const ModelAndState<S> built = b->build();
    const Springs<S>& sp = built.model.springs();
    const double scale = std::max(1.0, static_cast<double>(built.state.x.cwiseAbs().maxCoeff()));
    ASSERT_GT(sp.count(), 0);
    for (Index s = 0; s < sp.count(); ++s) {
      const double d =
          (built.state.x.row(sp.a[s]).template cast<double>() - built.state.x.row(sp.b[s]).template cast<double>())
              .norm();
      EXPECT_NEAR(static_cast<double>(sp.restLength[s]), d, 16 * eps<S>() * scale) << "spring " << s;
    }
  }
}

TYPED_TEST(ModelTest, GridRecordsItsLayout) {
  using S = TypeParam;
  for (const GridSize g : kGridSizes) {
    SCOPED_TRACE(::testing::Message() << g.w << " x " << g.h);
    ClothGridSpec spec = gridSpec(g.w, g.h);
    ModelBuilder<S> builder;
    addClothGrid(builder, spec);
    const ModelAndState<S> built = builder.build();
    const Model<S>& model = built.model;
    ASSERT_TRUE(model.grid().has_value());
    const GridLayout<S>& layout = *model.grid();
    EXPECT_EQ(layout.width, g.w);
    EXPECT_EQ(layout.height, g.h);
    // Right, down, two diagonals, and the two bend families when the grid is wide/tall enough.
    const size_t expectedFamilies = 4 + (g.w > 2 ? 1 : 0) + (g.h > 2 ? 1 : 0);
    EXPECT_EQ(layout.families.size(), expectedFamilies);
    Index covered = 0;
    for (const GridFamily<S>& f : layout.families) {
      SCOPED_TRACE(::testing::Message() << "family (" << f.rowOffset << ", " << f.columnOffset << ")");
      EXPECT_GT(f.springCount, 0);
      EXPECT_EQ(f.firstSpring, covered);  // families are contiguous and in order
      covered += f.springCount;
      for (Index s = f.firstSpring; s < f.firstSpring + f.springCount; ++s) {
        EXPECT_EQ(model.springs().b[s] - model.springs().a[s], f.rowOffset * g.w + f.columnOffset);
        EXPECT_EQ(model.springs().restLength[s], f.restLength);
        EXPECT_EQ(model.springs().stiffness[s], f.stiffness);
        EXPECT_EQ(model.springs().damping[s], f.damping);
      }
    }
    EXPECT_EQ(covered, model.springCount());
  }
}

TYPED_TEST(ModelTest, GridIndexIsRowMajor) {
  const ClothGridSpec spec = gridSpec(7, 4);
  EXPECT_EQ(gridIndex(spec, 0, 0), 0);
  EXPECT_EQ(gridIndex(spec, 0, 6), 6);
  EXPECT_EQ(gridIndex(spec, 1, 0), 7);
  EXPECT_EQ(gridIndex(spec, 3, 6), 27);
}

// ---------------------------------------------------------------------------------------
// Rope
// ---------------------------------------------------------------------------------------

TYPED_TEST(ModelTest, RopeSpringCounts) {
  using S = TypeParam;
  for (const Index n : {2, 3, 10, 64})
    for (const bool bend : {true, false}) {
      SCOPED_TRACE(::testing::Message() << n << " particles" << (bend ? " +bend" : ""));
      RopeSpec spec;
      spec.particleCount = n;
      spec.bendSprings = bend;
      ModelBuilder<S> builder;
      addRope(builder, spec);
      const ModelAndState<S> built = builder.build();
      const std::array<Index, kSpringClassCount> expected{n - 1, 0, bend ? n - 2 : 0};
      EXPECT_EQ(built.model.particleCount(), n);
      EXPECT_EQ(built.model.springCountByClass(), expected);
      EXPECT_FALSE(built.model.grid().has_value());
      const Springs<S>& sp = built.model.springs();
      for (Index s = 0; s < sp.count(); ++s)
        EXPECT_EQ(sp.b[s] - sp.a[s], sp.kind[s] == SpringClass::Structural ? 1 : 2) << "spring " << s;
    }
}

TYPED_TEST(ModelTest, HandBuiltModelHasNoGrid) {
  using S = TypeParam;
  ModelBuilder<S> builder;
  builder.addParticle({0, 0, 0}, 1);
  builder.addParticle({1, 0, 0}, 1);
  builder.addSpring(0, 1, {1, 0});
  EXPECT_FALSE(builder.build().model.grid().has_value());
}

// ---------------------------------------------------------------------------------------
// Particles, pins, build()
// ---------------------------------------------------------------------------------------

TYPED_TEST(ModelTest, PinZeroesInverseMassAndKeepsMass) {
  using S = TypeParam;
  ModelBuilder<S> builder;
  builder.addParticle({0, 0, 0}, 2.0, {1, 2, 3});
  builder.addParticle({1, 0, 0}, 0.25, {4, 5, 6});
  builder.addParticle({2, 0, 0}, 4.0);
  builder.pin(0);
  builder.pin(0);  // pinning twice is harmless
  builder.pin(2);
  const ModelAndState<S> built = builder.build();
  const Model<S>& model = built.model;
  EXPECT_EQ(model.mass()[0], S(2));
  EXPECT_EQ(model.mass()[1], S(0.25));
  EXPECT_EQ(model.mass()[2], S(4));
  EXPECT_EQ(model.inverseMass()[0], S(0));
  EXPECT_EQ(model.inverseMass()[1], S(4));
  EXPECT_EQ(model.inverseMass()[2], S(0));
  EXPECT_TRUE(model.isPinned(0));
  EXPECT_FALSE(model.isPinned(1));
  EXPECT_TRUE(model.isPinned(2));
  EXPECT_EQ(model.pinnedCount(), 2);
  // A pinned particle does not move: its initial velocity is zero; others keep theirs.
  EXPECT_TRUE(built.state.v.row(0).isZero(0));
  EXPECT_EQ(built.state.v(1, 0), S(4));
  EXPECT_EQ(built.state.v(1, 2), S(6));
  EXPECT_EQ(built.state.x(2, 0), S(2));
  EXPECT_EQ(built.state.time, 0.0);
}

TYPED_TEST(ModelTest, BuildEmptiesTheBuilder) {
  using S = TypeParam;
  ModelBuilder<S> builder;
  builder.addParticle({0, 0, 0}, 1);
  builder.addParticle({1, 0, 0}, 1);
  builder.addSpring(0, 1, {1, 0});
  (void)builder.build();
  EXPECT_EQ(builder.particleCount(), 0);
  EXPECT_EQ(builder.springCount(), 0);
  // Built again, empty: a model without particles (a scene of rigid bodies only).
  const ModelAndState<S> empty = builder.build();
  EXPECT_EQ(empty.model.particleCount(), 0);
  EXPECT_EQ(empty.state.x.rows(), 0);
}

TYPED_TEST(ModelTest, ExplicitRestLengthIsKept) {
  using S = TypeParam;
  ModelBuilder<S> builder;
  builder.addParticle({0, 0, 0}, 1);
  builder.addParticle({3, 4, 0}, 1);
  builder.addSpring(0, 1, {1, 0}, SpringClass::Structural, 2.5);
  builder.addSpring(1, 0, {1, 0}, SpringClass::Structural, 0);  // zero rest length is allowed
  builder.addSpring(0, 1, {1, 0});
  const ModelAndState<S> built = builder.build();
  EXPECT_EQ(built.model.springs().restLength[0], S(2.5));
  EXPECT_EQ(built.model.springs().restLength[1], S(0));
  EXPECT_EQ(built.model.springs().restLength[2], S(5));
}

// ---------------------------------------------------------------------------------------
// Bad input: std::invalid_argument naming the field and the value
// ---------------------------------------------------------------------------------------

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

TYPED_TEST(ModelTest, BadParticlesThrow) {
  using S = TypeParam;
  ModelBuilder<S> b;
  expectInvalid([&] { b.addParticle({0, 0, 0}, 0.0); }, "mass", "0");
  expectInvalid([&] { b.addParticle({0, 0, 0}, -2.5); }, "mass", "-2.5");
  expectInvalid([&] { b.addParticle({0, 0, 0}, kNaN); }, "mass", "nan");
  expectInvalid([&] { b.addParticle({0, 0, 0}, kInf); }, "mass", "inf");
  expectInvalid([&] { b.addParticle({kNaN, 0, 0}, 1.0); }, "position.x", "nan");
  expectInvalid([&] { b.addParticle({0, kInf, 0}, 1.0); }, "position.y", "inf");
  expectInvalid([&] { b.addParticle({0, 0, -kInf}, 1.0); }, "position.z", "-inf");
  expectInvalid([&] { b.addParticle({0, 0, 0}, 1.0, {0, kNaN, 0}); }, "velocity.y", "nan");
  // Finite, but faster than light: its kinetic energy overflows (1e300 m/s), or it is simply
  // not a speed anything the kernel models reaches (each component below c, the speed above).
  expectInvalid([&] { b.addParticle({0, 0, 0}, 1.0, {1e300, 0, 0}); }, "velocity of particle [0]", "(1e+300, 0, 0)");
  expectInvalid(
      [&] {
        b.addParticle({0, 0, 0}, 1.0, {2.5e8, 2.5e8, 0});
      },
      "velocity of particle [0]", "speed of at most 299792458 m/s");
  EXPECT_EQ(b.particleCount(), 0) << "a rejected particle must not be added";
  EXPECT_NO_THROW(b.addParticle({0, 0, 0}, 1.0, {kMaxSpeed, 0, 0}));
}

// ModelBuilder::build holds every spring to the rule the whole-object builders check: its
// ends within rest / (10 sqrt(3) epsilon) of the origin, where rounding to S changes its
// length by at most a tenth. A spring of rest length 0 has no length to keep.
TYPED_TEST(ModelTest, BuildRefusesASpringThePrecisionCannotKeepTheLengthOf) {
  using S = TypeParam;
  const double eps = static_cast<double>(std::numeric_limits<S>::epsilon());
  const double reach = 0.01 / (10 * std::sqrt(3.0) * eps);  // a 1 cm spring
  const auto build = [](double x, double rest) -> std::string {
    ModelBuilder<S> b;
    b.addParticle({0, 0, 0}, 1);
    b.addParticle({x, 0, 0}, 1);
    b.addParticle({x, 0.01, 0}, 1);
    b.addSpring(0, 1, SpringMaterial{10, 0}, SpringClass::Structural, 1.0);
    b.addSpring(1, 2, SpringMaterial{10, 0}, SpringClass::Structural, rest);
    try {
      (void)b.build();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "built";
  };
  EXPECT_EQ(build(0.999 * reach, 0.01), "built");
  const std::string what = build(1.001 * reach, 0.01);
  EXPECT_NE(what.find("ModelBuilder::build: the largest |coordinate| of the ends of spring [1] (particles 1 and 2) "
                      "must be at most " +
                      detail::number(reach) + " m in "),
            std::string::npos)
      << what;
  EXPECT_NE(
      what.find("use double precision or build the model nearer the origin), got " + detail::number(1.001 * reach)),
      std::string::npos)
      << what;
  EXPECT_EQ(build(1.001 * reach, 0), "built");  // rest length 0: nothing to keep
}

TYPED_TEST(ModelTest, BadSpringsThrow) {
  using S = TypeParam;
  ModelBuilder<S> b;
  b.addParticle({0, 0, 0}, 1);
  b.addParticle({1, 0, 0}, 1);
  expectInvalid([&] { b.addSpring(0, 5, {1, 0}); }, "particle index", "5");
  expectInvalid([&] { b.addSpring(-1, 1, {1, 0}); }, "particle index", "-1");
  expectInvalid([&] { b.addSpring(1, 1, {1, 0}); }, "endpoint", "1");
  expectInvalid([&] { b.addSpring(0, 1, {-3, 0}); }, "stiffness", "-3");
  expectInvalid([&] { b.addSpring(0, 1, {kNaN, 0}); }, "stiffness", "nan");
  expectInvalid([&] { b.addSpring(0, 1, {1, kNaN}); }, "damping", "nan");
  expectInvalid([&] { b.addSpring(0, 1, {1, -0.5}); }, "damping", "-0.5");
  expectInvalid([&] { b.addSpring(0, 1, {1, 0}, SpringClass::Structural, kInf); }, "restLength", "inf");
  expectInvalid([&] { b.pin(2); }, "particle index", "2");
  EXPECT_EQ(b.springCount(), 0) << "a rejected spring must not be added";
}

TYPED_TEST(ModelTest, MassTooSmallForThePrecisionThrows) {
  using S = TypeParam;
  // A positive finite mass whose inverse overflows S: 2^-130 in float, 2^-1030 in double.
  const bool isFloat = std::is_same_v<S, float>;
  const double tiny = std::ldexp(1.0, isFloat ? -130 : -1030);
  ModelBuilder<S> b;
  b.addParticle({0, 0, 0}, tiny);
  expectInvalid([&] { (void)b.build(); }, "mass of particle [0]", isFloat ? "e-40" : "e-311");
}

TYPED_TEST(ModelTest, ARefusedBuildLeavesTheBuilderAsItWas) {
  using S = TypeParam;
  // Every value is checked before the builder's arrays are handed over to the model (and
  // released): a refused build loses nothing. Here the last spring's stiffness is beyond
  // float; in double the same builder builds.
  ModelBuilder<S> b;
  ClothGridSpec spec;
  spec.width = 5;
  spec.height = 4;
  addClothGrid(b, spec);
  b.addSpring(0, 19, {1e300, 0});
  const Index springs = b.springCount();
  const Vec3d last = b.position(19);
  if constexpr (std::is_same_v<S, float>) {
    expectInvalid([&] { (void)b.build(); }, "stiffness of spring", "1e+300");
    EXPECT_EQ(b.particleCount(), 20);
    EXPECT_EQ(b.springCount(), springs);
    EXPECT_EQ(b.triangleCount(), 24);
    EXPECT_EQ(b.position(19).x, last.x);
  } else {
    const ModelAndState<S> built = b.build();
    EXPECT_EQ(built.model.springCount(), springs);
    EXPECT_EQ(built.state.x(19, 0), last.x);
    EXPECT_EQ(b.particleCount(), 0) << "a build leaves the builder empty";
  }
}

TYPED_TEST(ModelTest, BadRopeSpecsThrow) {
  using S = TypeParam;
  RopeSpec spec;
  spec.particleCount = 1;
  ModelBuilder<S> b;
  expectInvalid([&] { addRope(b, spec); }, "particleCount", "1");
  spec = RopeSpec{};
  spec.length = 0;
  expectInvalid([&] { addRope(b, spec); }, "length", "0");
  spec = RopeSpec{};
  spec.totalMass = -1;
  expectInvalid([&] { addRope(b, spec); }, "totalMass", "-1");
  spec = RopeSpec{};
  spec.direction = {0, 0, 0};
  expectInvalid([&] { addRope(b, spec); }, "direction", "");
  EXPECT_EQ(b.particleCount(), 0);
}

TYPED_TEST(ModelTest, BadGridSpecsThrow) {
  using S = TypeParam;
  ModelBuilder<S> b;
  ClothGridSpec spec = gridSpec(1, 4);
  expectInvalid([&] { addClothGrid(b, spec); }, "width", "1");
  spec = gridSpec(4, 0);
  expectInvalid([&] { addClothGrid(b, spec); }, "height", "0");
  spec = gridSpec(4, 4);
  spec.spacing = 0;
  expectInvalid([&] { addClothGrid(b, spec); }, "spacing", "0");
  spec.spacing = -0.5;
  expectInvalid([&] { addClothGrid(b, spec); }, "spacing", "-0.5");
  spec.spacing = kNaN;
  expectInvalid([&] { addClothGrid(b, spec); }, "spacing", "nan");
  spec = gridSpec(4, 4);
  spec.totalMass = 0;
  expectInvalid([&] { addClothGrid(b, spec); }, "totalMass", "0");
  spec = gridSpec(4, 4);
  spec.rowAxis = {0, 0, 0};
  expectInvalid([&] { addClothGrid(b, spec); }, "rowAxis", "");
  EXPECT_EQ(b.particleCount(), 0);
}

TYPED_TEST(ModelTest, GridAfterOtherParticlesIsOffsetAndHasNoLayout) {
  using S = TypeParam;
  // A grid added after other particles is indexed from them, with its springs and
  // triangles; it carries no grid layout (the stencil indexes from particle 0), so the
  // model's strategy is the general one.
  ModelBuilder<S> b;
  b.addParticle({5, 5, 5}, 1);
  const ClothGridSpec spec = gridSpec(3, 4);
  addClothGrid(b, spec);
  ASSERT_EQ(b.particleCount(), 1 + 12);
  const auto counts = expectedGridSpringCounts(spec);
  EXPECT_EQ(b.springCount(), counts[0] + counts[1] + counts[2]);
  EXPECT_EQ(b.triangleCount(), 2 * 2 * 3);
  const ModelAndState<S> built = b.build();
  EXPECT_FALSE(built.model.grid().has_value());
  const Springs<S>& sp = built.model.springs();
  for (Index s = 0; s < sp.count(); ++s) {
    EXPECT_GE(sp.a[s], 1);
    EXPECT_GE(sp.b[s], 1);
    EXPECT_NEAR(static_cast<double>((built.state.x.row(sp.a[s]) - built.state.x.row(sp.b[s])).norm()),
                static_cast<double>(sp.restLength[s]), 1e-6);
  }
  const Triangles& tr = built.model.triangles();
  for (Index t = 0; t < tr.count(); ++t) EXPECT_GE(std::min({tr.a[t], tr.b[t], tr.c[t]}), 1);
}

TYPED_TEST(ModelTest, InconsistentGridLayoutIsRejectedAtBuild) {
  using S = TypeParam;
  // A layout that does not describe the springs would make GridStencil compute wrong
  // forces, so build() checks it.
  ModelBuilder<S> c;
  for (int i = 0; i < 6; ++i) c.addParticle({double(i % 3), double(i / 3), 0}, 1);
  c.addSpring(0, 1, {1, 0});
  GridLayout<S> layout;
  layout.width = 3;
  layout.height = 2;
  GridFamily<S> right;
  right.rowOffset = 0;
  right.columnOffset = 1;
  right.restLength = 1;
  right.stiffness = 1;
  right.firstSpring = 0;
  right.springCount = 4;  // claims springs that are not there
  layout.families.push_back(right);
  c.setGridLayout(layout);
  expectInvalid([&] { (void)c.build(); }, "grid layout", "");

  ModelBuilder<S> d;
  d.addParticle({0, 0, 0}, 1);
  GridLayout<S> wrongSize;
  wrongSize.width = 2;
  wrongSize.height = 2;
  d.setGridLayout(wrongSize);
  expectInvalid([&] { (void)d.build(); }, "particle count", "1");
}

TYPED_TEST(ModelTest, GridWithExtraSpringsIsNotARegularGrid) {
  using S = TypeParam;
  // The grid stencil evaluates the families' springs only. A cloth grid with a spring of
  // the user's own (a tether) is a valid model, but not a regular grid: it must not carry
  // a layout, or the GridStencil strategy (Auto's choice for grids) would drop the spring.
  ModelBuilder<S> b;
  addClothGrid(b, gridSpec(4, 3));
  b.addSpring(0, 11, {1, 0});
  const ModelAndState<S> built = b.build();
  EXPECT_EQ(built.model.springCount(), expectedGridSpringCounts(gridSpec(4, 3))[0] +
                                           expectedGridSpringCounts(gridSpec(4, 3))[1] +
                                           expectedGridSpringCounts(gridSpec(4, 3))[2] + 1);
  EXPECT_FALSE(built.model.grid().has_value());

  // The same for a layout that lists one family twice (its springs would count twice).
  ModelBuilder<S> c;
  addClothGrid(c, gridSpec(3, 3));
  ModelBuilder<S> probe;
  addClothGrid(probe, gridSpec(3, 3));
  GridLayout<S> twice = *probe.build().model.grid();
  twice.families.push_back(twice.families.front());
  c.setGridLayout(twice);
  EXPECT_FALSE(c.build().model.grid().has_value());
}

TYPED_TEST(ModelTest, ValuesOutsideThePrecisionAreRejected) {
  using S = TypeParam;
  // 1e300 fits a double but not a float; 1e308 * 10 is inf in both (rejected earlier, as
  // not finite). Converting an out-of-range double to float would be undefined behaviour.
  if constexpr (sizeof(S) == 4) {
    expectInvalid(
        [] {
          ModelBuilder<S> b;
          b.addParticle({0, 1e300, 0}, 1);
          b.build();
        },
        "position.y of particle [0]", "1e+300");
    expectInvalid(
        [] {
          ModelBuilder<S> b;
          b.addParticle({0, 0, 0}, 1);
          b.addParticle({1, 0, 0}, 1);
          b.addSpring(0, 1, {1e300, 0});
          b.build();
        },
        "stiffness of spring [0]", "1e+300");
  } else {
    // A double holds 1e300, but positions must keep the squares of their distances finite.
    expectInvalid(
        [] {
          ModelBuilder<S> b;
          b.addParticle({0, 1e300, 0}, 1);
          b.build();
        },
        "position.y of particle [0] must be within +-1e+150 m in double precision", "1e+300");
    ModelBuilder<S> b;
    b.addParticle({0, 1e150, 0}, 1);
    EXPECT_NO_THROW(b.build());
  }
}

TYPED_TEST(ModelTest, SkewedGridStartsAtRest) {
  using S = TypeParam;
  // Non-orthogonal axes: every spring's rest length is its initial length, so with no
  // gravity nothing accelerates (within rounding).
  ClothGridSpec spec = gridSpec(6, 5);
  spec.rowAxis = {1, 0, 0};
  spec.columnAxis = {0.5, 0, 1};
  ModelBuilder<S> b;
  addClothGrid(b, spec);
  const ModelAndState<S> built = b.build();
  ASSERT_TRUE(built.model.grid().has_value());
  Executor exec(1);
  ForceField<S> forces(built.model, ForceStrategy::GridStencil, {0, 0, 0});
  Vec3Array<S> a(built.model.particleCount(), 3);
  forces.accelerations(built.state.x, built.state.v, a, exec);
  // Rounding scale: ks * spacing * (1/m) * 1000 eps (about 0.6 m/s^2 in float). Lattice
  // rest lengths on these axes would be off by ~12% of the spacing: ~600 m/s^2.
  const double w = static_cast<double>(built.model.inverseMass()[0]);
  const double bound = 1e3 * static_cast<double>(eps<S>()) * spec.structural.stiffness * spec.spacing * w;
  EXPECT_LE(static_cast<double>(a.cwiseAbs().maxCoeff()), bound) << "a skewed grid is pre-stressed";
}

TYPED_TEST(ModelTest, ParallelGridAxesAreRejected) {
  using S = TypeParam;
  ClothGridSpec spec = gridSpec(4, 4);
  spec.rowAxis = {1, 0, 0};
  spec.columnAxis = {-2, 0, 0};
  ModelBuilder<S> b;
  EXPECT_THROW(addClothGrid(b, spec), std::invalid_argument);
}

// A rope or grid the builder accepts also builds: what the precision cannot hold (a mass
// whose inverse overflows, a coordinate whose square does, a stiffness beyond its range)
// is refused before anything is added, naming the spec's field.
TYPED_TEST(ModelTest, RopesAndGridsThePrecisionCannotHoldAreRefusedBeforeAnythingIsAdded) {
  using S = TypeParam;
  const bool single = sizeof(S) == sizeof(float);
  const auto refused = [](auto add) {
    ModelBuilder<S> b;
    b.addParticle({0, 0, 0}, 1);
    std::string what;
    try {
      add(b);
    } catch (const std::invalid_argument& e) {
      what = e.what();
    }
    EXPECT_EQ(b.particleCount(), 1) << what;
    EXPECT_EQ(b.springCount(), 0) << what;
    return what;
  };
  RopeSpec rope;
  rope.totalMass = single ? 1e-40 : 1e-310;
  EXPECT_NE(refused([&](ModelBuilder<S>& b) {
              addRope(b, rope);
            }).find("RopeSpec particle mass (totalMass / particles) must be such that it and 1/mass are finite"),
            std::string::npos);
  rope = {};
  rope.length = single ? 1e19 : 1e151;
  EXPECT_NE(refused([&](ModelBuilder<S>& b) {
              addRope(b, rope);
            }).find("RopeSpec extent (a coordinate of a particle) must be within"),
            std::string::npos);
  rope = {};
  rope.structural.stiffness = std::numeric_limits<double>::infinity();
  EXPECT_NE(refused([&](ModelBuilder<S>& b) { addRope(b, rope); }).find("RopeSpec.structural.stiffness must be finite"),
            std::string::npos);
  // A spacing whose square underflows: refused for its size, not as parallel axes.
  rope = {};
  rope.length = 1e-300;
  EXPECT_NE(
      refused([&](ModelBuilder<S>& b) {
        addRope(b, rope);
      }).find(std::string("RopeSpec.length / (particleCount - 1) must be at least ") + (single ? "1e-18" : "1e-150")),
      std::string::npos);
  ClothGridSpec grid = gridSpec(4, 4);
  grid.spacing = 1e-300;
  EXPECT_NE(refused([&](ModelBuilder<S>& b) {
              addClothGrid(b, grid);
            }).find(std::string("ClothGridSpec.spacing must be at least ") + (single ? "1e-18" : "1e-150") + " m in "),
            std::string::npos);
  grid = gridSpec(4, 4);
  grid.shear.damping = single ? 1e39 : -1;
  EXPECT_NE(refused([&](ModelBuilder<S>& b) { addClothGrid(b, grid); }).find("ClothGridSpec.shear.damping must be"),
            std::string::npos);
  grid = gridSpec(4, 4);
  grid.origin = {0, single ? -2e18 : -2e150, 0};
  EXPECT_NE(refused([&](ModelBuilder<S>& b) { addClothGrid(b, grid); }).find("ClothGridSpec extent"),
            std::string::npos);
  grid = gridSpec(70000, 70000);
  EXPECT_NE(refused([&](ModelBuilder<S>& b) {
              addClothGrid(b, grid);
            }).find("ClothGridSpec.width x height must be at most 268435455 particles, got 70000 x 70000"),
            std::string::npos);
  // A grid or rope whose coordinates the precision cannot hold its spacing at: refused for
  // float at 1e6 m (a coordinate steps by 6 cm there, more than the 4 cm spacing), held in
  // double; the reach is spacing / (10 sqrt(3) epsilon).
  const double reach = 0.04 / (10 * std::sqrt(3.0) * static_cast<double>(std::numeric_limits<S>::epsilon()));
  grid = gridSpec(8, 8);
  grid.spacing = 0.04;
  grid.origin = {single ? 1e6 : 1e15, 0, 0};
  EXPECT_NE(refused([&](ModelBuilder<S>& b) { addClothGrid(b, grid); })
                .find("ClothGridSpec extent (the largest |coordinate| of a particle) must be at most " +
                      detail::number(reach) + " m in " + (single ? "float" : "double") +
                      " precision (the spring's rest length, 0.04 m, / (10 sqrt(3) epsilon)"),
            std::string::npos);
  rope = {};
  rope.origin = {0, 0, -1.01 * reach * (rope.length / (rope.particleCount - 1)) / 0.04};
  EXPECT_NE(refused([&](ModelBuilder<S>& b) {
              addRope(b, rope);
            }).find("RopeSpec extent (the largest |coordinate| of a particle) must be at most "),
            std::string::npos);
  for (const double at : {0.99 * reach - 0.28, single ? 1e4 : 1e12}) {  // (the grid's far corner: 0.28 m further)
    grid.origin = {at, 0, 0};
    ModelBuilder<S> held;
    addClothGrid(held, grid);
    EXPECT_EQ(held.build().model.particleCount(), 64) << at;
  }
  // Within the bounds, both build.
  rope = {};
  rope.totalMass = 1e-30;
  ModelBuilder<S> b;
  addRope(b, rope);
  EXPECT_EQ(b.build().model.particleCount(), rope.particleCount);
}

// ---------------------------------------------------------------------------------------
// Derived topology: checked against brute force
// ---------------------------------------------------------------------------------------

/// A cloth grid after a lone particle (so its triangles are not a grid's), as a Model.
template <class S>
Model<S> offsetGrid(Index w, Index h) {
  ModelBuilder<S> b;
  b.addParticle({5, 5, 5}, 1);
  addClothGrid(b, gridSpec(w, h));
  return b.build().model;
}

TYPED_TEST(ModelTest, SpringIncidenceListsEachParticlesSpringsAscending) {
  using S = TypeParam;
  for (const Model<S>& model : {offsetGrid<S>(5, 4), ModelBuilder<S>().build().model}) {
    const Incidence& inc = model.springIncidence();
    const Springs<S>& sp = model.springs();
    ASSERT_EQ(inc.offsets.size(), model.particleCount() + 1);
    EXPECT_EQ(inc.entries.size(), 2 * sp.count());
    for (Index i = 0; i < model.particleCount(); ++i) {
      std::vector<Index> expected;
      for (Index s = 0; s < sp.count(); ++s) {
        if (sp.a[s] == i) expected.push_back(2 * s);
        if (sp.b[s] == i) expected.push_back(2 * s + 1);
      }
      const std::vector<Index> listed(inc.entries.data() + inc.begin(i), inc.entries.data() + inc.end(i));
      EXPECT_EQ(listed, expected) << "particle " << i;
    }
  }
}

TYPED_TEST(ModelTest, TriangleIncidenceListsEachParticlesTrianglesAscending) {
  using S = TypeParam;
  const Model<S> model = offsetGrid<S>(4, 6);
  const Incidence& inc = model.triangleIncidence();
  const Triangles& tr = model.triangles();
  EXPECT_EQ(inc.entries.size(), 3 * tr.count());
  for (Index i = 0; i < model.particleCount(); ++i) {
    std::vector<Index> expected;
    for (Index t = 0; t < tr.count(); ++t)
      if (tr.a[t] == i || tr.b[t] == i || tr.c[t] == i) expected.push_back(t);
    const std::vector<Index> listed(inc.entries.data() + inc.begin(i), inc.entries.data() + inc.end(i));
    EXPECT_EQ(listed, expected) << "particle " << i;
  }
}

TYPED_TEST(ModelTest, SpringColouringIsAPermutationWithNoSharedParticleInAColour) {
  using S = TypeParam;
  const Model<S> model = makeFlag<S>(9).model;
  const SpringColouring<S>& col = model.springColouring();
  const Springs<S>& sp = model.springs();
  ASSERT_GT(col.colourCount(), 0);
  EXPECT_EQ(col.offsets.front(), 0);
  EXPECT_EQ(col.offsets.back(), sp.count());
  // Each spring (its endpoints and parameters) appears exactly once.
  std::multiset<std::tuple<Index, Index, S, S, S>> original, permuted;
  for (Index s = 0; s < sp.count(); ++s) {
    original.insert({sp.a[s], sp.b[s], sp.restLength[s], sp.stiffness[s], sp.damping[s]});
    permuted.insert({col.a[s], col.b[s], col.restLength[s], col.stiffness[s], col.damping[s]});
  }
  EXPECT_EQ(original, permuted);
  for (Index c = 0; c < col.colourCount(); ++c) {
    std::set<Index> touched;
    for (Index k = col.offsets[c]; k < col.offsets[c + 1]; ++k) {
      EXPECT_TRUE(touched.insert(col.a[k]).second) << "colour " << c << " touches particle " << col.a[k] << " twice";
      EXPECT_TRUE(touched.insert(col.b[k]).second) << "colour " << c << " touches particle " << col.b[k] << " twice";
    }
  }
}

TYPED_TEST(ModelTest, GridTrianglesAndCollisionEdgesAreDerivedFromTheSprings) {
  using S = TypeParam;
  const Model<S> grid = makeFlag<S>(6).model;
  EXPECT_TRUE(grid.trianglesFormGrid());
  EXPECT_FALSE(offsetGrid<S>(6, 6).trianglesFormGrid());
  EXPECT_FALSE(ModelBuilder<S>().build().model.trianglesFormGrid());
  std::vector<Edge> expected;
  const Springs<S>& sp = grid.springs();
  for (Index s = 0; s < sp.count(); ++s)
    if (sp.kind[static_cast<size_t>(s)] != SpringClass::Bend) expected.push_back({sp.a[s], sp.b[s]});
  EXPECT_EQ(grid.collisionEdges(), expected);
}

TYPED_TEST(ModelTest, DerivedDataIsComputedOnceAndSharedByCopies) {
  using S = TypeParam;
  const Model<S> model = offsetGrid<S>(5, 5);
  EXPECT_EQ(model.derivedBuildCount(), 0) << "nothing is derived before it is asked for";
  const Incidence* first = &model.springIncidence();
  model.triangleIncidence();
  model.springColouring();
  model.trianglesFormGrid();
  model.collisionEdges();
  EXPECT_EQ(model.derivedBuildCount(), 5);
  const Model<S> copy = model;  // shares the derived data
  EXPECT_EQ(&copy.springIncidence(), first);
  copy.springColouring();
  EXPECT_EQ(model.derivedBuildCount(), 5);
}

TEST(ModelNames, SpringClassNames) {
  EXPECT_STREQ(springClassName(SpringClass::Structural), "structural");
  EXPECT_STREQ(springClassName(SpringClass::Shear), "shear");
  EXPECT_STREQ(springClassName(SpringClass::Bend), "bend");
}

TEST(Energy, KineticSpringAndGravityOfAKnownState) {
  // Two particles 1 m apart on a spring of rest length 0.5 m and stiffness 100 N/m; the
  // lower one (2 kg) moves at 3 m/s, the upper one (1 kg) is pinned at y = 2.
  ModelBuilder<double> b;
  const Index top = b.addParticle({0, 2, 0}, 1.0);
  const Index bob = b.addParticle({0, 1, 0}, 2.0);
  b.addSpring(top, bob, {100, 0.1}, SpringClass::Structural, 0.5);
  b.pin(top);
  ModelAndState<double> m = b.build();
  m.state.v(bob, 0) = 3;
  const Energy e = energy(m.model, m.state, {0, -9.81, 0});
  EXPECT_DOUBLE_EQ(e.kinetic, 0.5 * 2 * 9);
  EXPECT_DOUBLE_EQ(e.spring, 0.5 * 100 * 0.25);
  EXPECT_DOUBLE_EQ(e.gravity, 2 * 9.81 * 1);  // the pinned particle's potential is not counted
  EXPECT_DOUBLE_EQ(e.total(), e.kinetic + e.spring + e.gravity);
  State<double> wrong = m.state;
  wrong.x.resize(1, 3);
  EXPECT_THROW(energy(m.model, wrong, {0, -9.81, 0}), std::invalid_argument);
}

TEST(Stretch, MaxAndMeanOfTheStructuralSpringsByHand) {
  // Four particles: structural springs 0-1 (rest 0.5 m, now 0.6 m long: +20 %), 1-2 (rest
  // 1 m, now 0.9 m: -10 %) and 2-3 (rest 0 m: no stretch, left out); a shear spring 0-2
  // (rest 1 m, now 1.5 m: +50 %) and a bend spring 1-3 (rest 2 m, now 3 m: +50 %) are not
  // structural.
  ModelBuilder<double> b;
  const Index p0 = b.addParticle({0, 0, 0}, 1.0);
  const Index p1 = b.addParticle({0, 0, 0.6}, 1.0);
  const Index p2 = b.addParticle({0, 0.9, 0.6}, 1.0);
  const Index p3 = b.addParticle({0, 0.9, 0.6}, 1.0);
  b.addSpring(p0, p1, {100, 0}, SpringClass::Structural, 0.5);
  b.addSpring(p1, p2, {100, 0}, SpringClass::Structural, 1.0);
  b.addSpring(p2, p3, {100, 0}, SpringClass::Structural, 0.0);
  b.addSpring(p0, p2, {100, 0}, SpringClass::Shear, std::sqrt(0.81 + 0.36) / 1.5);
  b.addSpring(p1, p3, {100, 0}, SpringClass::Bend, 0.9 / 1.5);
  const ModelAndState<double> m = b.build();

  const Stretch s = stretch(m.model, m.state);
  EXPECT_EQ(s.springs, 2);
  EXPECT_NEAR(s.max, 0.6 / 0.5 - 1, 1e-15);
  EXPECT_NEAR(s.mean, ((0.6 / 0.5 - 1) + (0.9 / 1.0 - 1)) / 2, 1e-15);  // (0.2 - 0.1) / 2 = 0.05
  ASSERT_GE(s.longest, 0);                                              // the spring 0-1 (+20 %)
  EXPECT_EQ(m.model.springs().a[s.longest], p0);
  EXPECT_EQ(m.model.springs().b[s.longest], p1);
  const Stretch shear = stretch(m.model, m.state, SpringClass::Shear);
  EXPECT_EQ(shear.springs, 1);
  EXPECT_NEAR(shear.max, 0.5, 1e-15);
  EXPECT_NEAR(shear.mean, 0.5, 1e-15);
  EXPECT_NEAR(stretch(m.model, m.state, SpringClass::Bend).max, 0.5, 1e-15);

  // Float gives the same to float's rounding.
  ModelBuilder<float> bf;
  bf.addParticle({0, 0, 0}, 1.0);
  bf.addParticle({0, 0, 0.6}, 1.0);
  bf.addSpring(0, 1, {100, 0}, SpringClass::Structural, 0.5);
  const ModelAndState<float> mf = bf.build();
  EXPECT_NEAR(stretch(mf.model, mf.state).max, 0.2, 1e-6);

  // A flag at rest: no structural spring stretched or compressed.
  const ModelAndState<double> flag = makeFlag<double>(8);
  const Stretch rest = stretch(flag.model, flag.state);
  EXPECT_EQ(rest.springs, flag.model.springCountByClass()[0]);
  EXPECT_NEAR(rest.max, 0, 1e-15);
  EXPECT_NEAR(rest.mean, 0, 1e-15);

  // No spring of the class: nothing counted.
  const Stretch none = stretch(mf.model, mf.state, SpringClass::Bend);
  EXPECT_EQ(none.springs, 0);
  EXPECT_EQ(none.max, 0);
  EXPECT_EQ(none.mean, 0);
  EXPECT_EQ(none.longest, -1);
}

TEST(Stretch, BadInputsAreRefusedByName) {
  const ModelAndState<double> flag = makeFlag<double>(4);
  State<double> wrong = flag.state;
  wrong.x.resize(3, 3);
  expectInvalid([&] { stretch(flag.model, wrong); }, "stretch: the state has 3 positions", "16 particles");
  expectInvalid([&] { stretch(flag.model, flag.state, static_cast<SpringClass>(7)); }, "kind", "got 7");
}

}  // namespace
}  // namespace weft::test
