// tests/test_io_mesh.cpp — triangle meshes: cleaning (weld, degenerate, duplicate, edges), the
// cloth builder addClothMesh, and mesh files through assimp (weft::io).
//
// Test data (tests/data/, WEFT_TEST_DATA_DIR): the OBJ files are hand-written text, each
// with a comment saying what it holds. grid3x3.3ds is written by
// tests/data/make_mesh_3ds.py (python3, standard library only: a minimal chunk-by-chunk
// 3DS file, no material and no keyframer) from the same vertices, corners and winding as
// grid3x3.obj; re-run that script to regenerate it. Files for the error cases that need a
// particular path or content (missing, a directory, unreadable, NaN coordinates, ...) are
// written to the test temp directory.
//
// What the readers do, as these tests pin down: weft's OBJ reader keeps the file's shared
// vertices (a quad of 4 "v" lines and 2 faces arrives as 4 vertices) and counts "p" and "l"
// elements (not cloth); assimp gives every face corner of a 3DS file its own vertex, and its
// 3DS reader turns the file's z-up coordinates to y-up: (x, y, z) -> (x, z, -y).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "support/sanitizers.hpp"
#include "support/test_support.hpp"
#include "weft/effects/force_field.hpp"
#include "weft/io/mesh_import.hpp"
#include "weft/model/cloth_mesh.hpp"
#include "weft/model/triangle_mesh.hpp"
#include "weft/scene/simulation.hpp"

namespace weft::test {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::Not;

namespace fs = std::filesystem;

std::string dataPath(const std::string& name) { return std::string(WEFT_TEST_DATA_DIR) + "/" + name; }

/// A file under the test temp directory with `text` as its contents.
std::string tempFile(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "weft_mesh_" + name;
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

/// A (w x h)-quad grid in the z = 0 plane, `spacing` apart, two triangles per quad wound
/// like addClothGrid's: (a, b, e), (a, e, d). With cornerCopies every triangle gets its
/// own three vertices, as assimp delivers a file.
TriangleMesh gridMesh(Index w, Index h, double spacing, bool cornerCopies = false) {
  TriangleMesh mesh;
  for (Index r = 0; r <= h; ++r)
    for (Index c = 0; c <= w; ++c) mesh.vertices.push_back({spacing * c, spacing * r, 0});
  for (Index r = 0; r < h; ++r)
    for (Index c = 0; c < w; ++c) {
      const Index a = r * (w + 1) + c, b = a + 1, d = a + w + 1, e = d + 1;
      mesh.triangles.push_back({a, b, e});
      mesh.triangles.push_back({a, e, d});
    }
  if (!cornerCopies) return mesh;
  TriangleMesh copies;
  for (const auto& tri : mesh.triangles) {
    const Index first = static_cast<Index>(copies.vertices.size());
    for (int k = 0; k < 3; ++k) copies.vertices.push_back(mesh.vertices[tri[k]]);
    copies.triangles.push_back({first, first + 1, first + 2});
  }
  return copies;
}

/// Unique edges and interior (two-triangle) edges, counted by brute force with a std::map.
std::pair<Index, Index> edgeCounts(const TriangleMesh& mesh) {
  std::map<std::pair<Index, Index>, int> uses;
  for (const auto& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) ++uses[{std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])}];
  Index interior = 0;
  for (const auto& [edge, n] : uses) interior += n == 2 ? 1 : 0;
  return {static_cast<Index>(uses.size()), interior};
}

/// Area of the triangles around each vertex, a third each.
std::vector<double> lumpedAreas(const TriangleMesh& mesh) {
  std::vector<double> area(mesh.vertices.size(), 0.0);
  for (const auto& t : mesh.triangles) {
    const Vec3d &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
    const double ux = b.x - a.x, uy = b.y - a.y, uz = b.z - a.z, vx = c.x - a.x, vy = c.y - a.y, vz = c.z - a.z;
    const double cx = uy * vz - uz * vy, cy = uz * vx - ux * vz, cz = ux * vy - uy * vx;
    for (int k = 0; k < 3; ++k) area[t[k]] += std::sqrt(cx * cx + cy * cy + cz * cz) / 6;
  }
  return area;
}

std::tuple<double, double, double> asTuple(const Vec3d& v) { return {v.x, v.y, v.z}; }

/// Triangles as sorted lists of corner positions (independent of vertex numbering),
/// keeping the winding: each triangle rotated so its smallest corner comes first.
std::vector<std::array<std::tuple<double, double, double>, 3>> geometry(const TriangleMesh& mesh) {
  std::vector<std::array<std::tuple<double, double, double>, 3>> out;
  for (const auto& t : mesh.triangles) {
    std::array<std::tuple<double, double, double>, 3> p{asTuple(mesh.vertices[t[0]]), asTuple(mesh.vertices[t[1]]),
                                                        asTuple(mesh.vertices[t[2]])};
    std::rotate(p.begin(), std::min_element(p.begin(), p.end()), p.end());
    out.push_back(p);
  }
  std::sort(out.begin(), out.end());
  return out;
}

void expectCounts(const MeshReport& r, std::array<Index, 10> expected) {
  const std::array<Index, 10> got{
      r.inputVertices,      r.inputTriangles,   r.weldedVertices, r.unreferencedVertices, r.degenerateTriangles,
      r.duplicateTriangles, r.nonManifoldEdges, r.boundaryEdges,  r.outputVertices,       r.outputTriangles};
  EXPECT_EQ(got, expected) << "(inputVertices, inputTriangles, welded, unreferenced, degenerate, duplicate, "
                              "nonManifold, boundary, outputVertices, outputTriangles); "
                           << r.summary();
  EXPECT_EQ(r.inputVertices, r.weldedVertices + r.unreferencedVertices + r.outputVertices);
  EXPECT_EQ(r.inputTriangles, r.degenerateTriangles + r.duplicateTriangles + r.outputTriangles);
}

// ---------------------------------------------------------------------------------------
// cleanMesh
// ---------------------------------------------------------------------------------------

TEST(CleanMesh, WeldsCornerCopiesOfAGrid) {
  const TriangleMesh raw = gridMesh(8, 8, 0.1, /*cornerCopies=*/true);
  MeshReport r;
  const TriangleMesh clean = cleanMesh(raw, {}, &r);
  // 128 triangles x 3 corners in, 81 vertices out; 32 boundary edges.
  expectCounts(r, {384, 128, 303, 0, 0, 0, 0, 32, 81, 128});
  // The same triangles as the indexed grid, in the input order and winding; vertices in the
  // order of their first corner.
  const TriangleMesh indexed = gridMesh(8, 8, 0.1);
  EXPECT_EQ(geometry(clean), geometry(indexed));
  ASSERT_EQ(clean.triangles.size(), indexed.triangles.size());
  EXPECT_EQ(clean.triangles[0], (std::array<Index, 3>{0, 1, 2}));
  EXPECT_EQ(clean.triangles[1], (std::array<Index, 3>{0, 2, 3}));
  EXPECT_EQ(r.summary(),
            "384 vertices, 128 triangles in; 81 vertices, 128 triangles out; 303 welded vertices; "
            "32 boundary edges");
}

TEST(CleanMesh, CountsDegenerateDuplicateUnreferencedAndNonManifold) {
  TriangleMesh raw;
  raw.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0.5, 0, 0}, {9, 9, 9}, {1, 0, 0}};
  raw.triangles = {
      {0, 1, 2},  // kept
      {1, 0, 3},  // kept
      {0, 1, 4},  // kept: the third triangle on edge 0-1
      {0, 5, 1},  // degenerate: collinear
      {7, 1, 2},  // degenerate: 7 welds into 1
      {2, 0, 1},  // duplicate of the first (rotated)
      {0, 2, 7},  // duplicate of the first (reversed, 7 = 1)
  };
  MeshReport r;
  const TriangleMesh clean = cleanMesh(raw, {}, &r);
  // Vertices: 7 welded into 1; 5 (only in a degenerate triangle) and 6 (in none) dropped.
  expectCounts(r, {8, 7, 1, 2, 2, 2, 1, 6, 5, 3});
  EXPECT_THAT(r.summary(),
              AllOf(HasSubstr("1 welded vertex;"), HasSubstr("2 unreferenced vertices dropped"),
                    HasSubstr("2 degenerate triangles dropped"), HasSubstr("2 duplicate triangles dropped"),
                    HasSubstr("1 non-manifold edge;"), HasSubstr("6 boundary edges")));
  const std::vector<std::array<Index, 3>> expected = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  EXPECT_EQ(clean.triangles, expected);
}

TEST(CleanMesh, WeldToleranceIsADistanceAndChainsAreTransitive) {
  const auto weldedOf = [](double offset, double tolerance) {
    TriangleMesh raw;
    raw.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1 + offset, 0, 0}, {1, 1, 0}};
    raw.triangles = {{0, 1, 2}, {3, 4, 2}};
    MeshReport r;
    cleanMesh(raw, {tolerance}, &r);
    return r.weldedVertices;
  };
  EXPECT_EQ(weldedOf(0.9e-3, 1e-3), 1);
  EXPECT_EQ(weldedOf(1.1e-3, 1e-3), 0);
  EXPECT_EQ(weldedOf(0, 0), 1);  // tolerance 0: identical positions only
  EXPECT_EQ(weldedOf(1e-12, 0), 0);
  // Diagonal: (0.6, 0.6, 0.6) mm is 1.04 mm away, outside 1 mm although each axis is inside.
  TriangleMesh raw;
  raw.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1.0006, 0.0006, 0.0006}, {1, 1, 0}};
  raw.triangles = {{0, 1, 2}, {3, 4, 2}};
  MeshReport r;
  cleanMesh(raw, {1e-3}, &r);
  EXPECT_EQ(r.weldedVertices, 0);

  // A chain 0.8 mm apart with a 1 mm tolerance: ends 1.6 mm apart, all one vertex, at the
  // lexicographically smallest member's position.
  TriangleMesh chain;
  chain.vertices = {{1.0008, 0, 0}, {0, 1, 0}, {0, 0, 0}, {1.0016, 0, 0}, {1, 0, 0}};
  chain.triangles = {{2, 0, 1}, {2, 3, 1}, {2, 4, 1}};
  const TriangleMesh clean = cleanMesh(chain, {1e-3}, &r);
  EXPECT_EQ(r.weldedVertices, 2);
  EXPECT_EQ(r.duplicateTriangles, 2);
  ASSERT_EQ(clean.vertices.size(), 3u);
  // Output order: the group of input vertex 0 comes first, at the position of input vertex 4.
  EXPECT_EQ(asTuple(clean.vertices[0]), asTuple(Vec3d{1, 0, 0}));
  EXPECT_EQ(asTuple(clean.vertices[1]), asTuple(Vec3d{0, 1, 0}));
  EXPECT_EQ(asTuple(clean.vertices[2]), asTuple(Vec3d{0, 0, 0}));
}

TEST(CleanMesh, WeldIsDeterministicAndIndependentOfVertexOrder) {
  // A grid as corner copies, each copy jittered by up to 0.25 tolerance per axis (copies of
  // one vertex stay within 0.87 tolerance; every group needs the tolerance pass, and groups
  // straddle cell boundaries), then the vertex array shuffled. The welded groups and their
  // positions must not depend on the order.
  const double tolerance = 1e-4;
  TriangleMesh raw = gridMesh(12, 9, 0.01, /*cornerCopies=*/true);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> jitter(-0.25 * tolerance, 0.25 * tolerance);
  for (Vec3d& v : raw.vertices) v = {v.x + jitter(rng), v.y + jitter(rng), v.z + jitter(rng)};
  const Index n = static_cast<Index>(raw.vertices.size());
  std::vector<Index> perm(static_cast<size_t>(n));
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), rng);
  TriangleMesh shuffled;
  shuffled.vertices.resize(raw.vertices.size());
  for (Index i = 0; i < n; ++i) shuffled.vertices[perm[i]] = raw.vertices[i];
  for (const auto& t : raw.triangles) shuffled.triangles.push_back({perm[t[0]], perm[t[1]], perm[t[2]]});

  MeshReport r1, r2, r3;
  const TriangleMesh a = cleanMesh(raw, {tolerance}, &r1);
  const TriangleMesh again = cleanMesh(raw, {tolerance}, &r3);
  const TriangleMesh b = cleanMesh(shuffled, {tolerance}, &r2);
  expectCounts(r1, {648, 216, 648 - 130, 0, 0, 0, 0, 42, 130, 216});
  expectCounts(r2, {648, 216, 648 - 130, 0, 0, 0, 0, 42, 130, 216});
  // Deterministic: the same input gives the same bits.
  ASSERT_EQ(again.vertices.size(), a.vertices.size());
  for (size_t i = 0; i < a.vertices.size(); ++i) EXPECT_EQ(asTuple(again.vertices[i]), asTuple(a.vertices[i]));
  EXPECT_EQ(again.triangles, a.triangles);
  // Order independent: the same triangles (as corner positions, with their winding).
  EXPECT_EQ(geometry(a), geometry(b));
  // Each group sits at its lexicographically smallest member (the copies within a tenth of
  // the spacing).
  for (size_t i = 0; i < a.vertices.size(); ++i) {
    std::tuple<double, double, double> smallest{HUGE_VAL, HUGE_VAL, HUGE_VAL};
    for (const Vec3d& v : raw.vertices)
      if (std::abs(v.x - a.vertices[i].x) < 1e-3 && std::abs(v.y - a.vertices[i].y) < 1e-3)
        smallest = std::min(smallest, asTuple(v));
    EXPECT_EQ(asTuple(a.vertices[i]), smallest) << "output vertex " << i;
  }
}

TEST(CleanMesh, HandlesALargeMesh) {
  // O(n log n): 40 k triangles as 120 k corner copies, about 0.07 s in Release (200 k
  // triangles: 0.17 s, and 0.15 s for addClothMesh).
  const TriangleMesh raw = gridMesh(200, 100, 0.005, /*cornerCopies=*/true);
  MeshReport r;
  const TriangleMesh clean = cleanMesh(raw, {}, &r);
  EXPECT_EQ(r.outputVertices, 201 * 101);
  EXPECT_EQ(r.outputTriangles, 40000);
  EXPECT_EQ(r.boundaryEdges, 2 * (200 + 100));
}

TEST(CleanMesh, RejectsBadInputNamingFieldAndValue) {
  TriangleMesh quad = gridMesh(1, 1, 1);
  TriangleMesh bad = quad;
  bad.vertices[1].y = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { cleanMesh(bad); }),
              AllOf(HasSubstr("cleanMesh"), HasSubstr("vertices[1].y"), HasSubstr("nan")));
  bad = quad;
  bad.vertices[3].z = -std::numeric_limits<double>::infinity();
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { cleanMesh(bad); }),
              AllOf(HasSubstr("vertices[3].z"), HasSubstr("-inf")));
  bad = quad;
  bad.triangles[1][2] = 4;
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { cleanMesh(bad); }),
              AllOf(HasSubstr("triangles[1][2]"), HasSubstr("[0, 4)"), HasSubstr("got 4")));
  bad.triangles[1][2] = -1;
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { cleanMesh(bad); }), HasSubstr("got -1"));
  for (const double tolerance : {-1e-3, std::numeric_limits<double>::quiet_NaN(), HUGE_VAL})
    EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { cleanMesh(quad, {tolerance}); }),
                AllOf(HasSubstr("MeshCleanOptions.weldTolerance"), HasSubstr("got")));
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { cleanMesh(quad, {-1e-3}); }), HasSubstr("-0.001"));

  bad = quad;
  bad.triangles.clear();
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { cleanMesh(bad); }),
              AllOf(HasSubstr("no triangles"), HasSubstr("4 vertices")));
  // Everything degenerate: the report is filled before the exception.
  bad = quad;
  bad.vertices[2] = bad.vertices[0];
  bad.vertices[3] = {2, 0, 0};
  MeshReport r;
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { cleanMesh(bad, {}, &r); }),
              AllOf(HasSubstr("no triangles after cleaning"), HasSubstr("2 degenerate"), HasSubstr("2 input")));
  EXPECT_EQ(r.degenerateTriangles, 2);
  EXPECT_EQ(r.outputTriangles, 0);
}

// ---------------------------------------------------------------------------------------
// addClothMesh
// ---------------------------------------------------------------------------------------

template <class S>
class ClothMeshTest : public ::testing::Test {};
TYPED_TEST_SUITE(ClothMeshTest, ScalarTypes);

TYPED_TEST(ClothMeshTest, QuadSpringsMassesAndTriangles) {
  using S = TypeParam;
  const TriangleMesh quad = gridMesh(1, 1, 1);  // (0, 1, 3), (0, 3, 2): diagonal 0-3
  ClothMeshSpec spec;
  spec.totalMass = 0.6;
  ModelBuilder<S> builder;
  const ClothMeshStats stats = addClothMesh(builder, quad, spec);
  EXPECT_EQ(stats.particles, 4);
  EXPECT_EQ(stats.structuralSprings, 5);
  EXPECT_EQ(stats.bendSprings, 1);
  EXPECT_EQ(stats.triangles, 2);
  EXPECT_EQ(stats.firstParticle, 0);
  EXPECT_DOUBLE_EQ(stats.area, 1.0);
  const ModelAndState<S> built = builder.build();
  const Model<S>& model = built.model;
  EXPECT_FALSE(model.grid().has_value());
  // Structural springs in (min, max) order, then the bend spring across the diagonal 0-3.
  const Springs<S>& sp = model.springs();
  const std::vector<std::pair<Index, Index>> pairs = {{0, 1}, {0, 2}, {0, 3}, {1, 3}, {2, 3}, {1, 2}};
  ASSERT_EQ(sp.count(), 6);
  for (Index s = 0; s < 6; ++s) {
    EXPECT_EQ(std::make_pair(sp.a[s], sp.b[s]), pairs[s]) << "spring " << s;
    EXPECT_EQ(sp.kind[s], s < 5 ? SpringClass::Structural : SpringClass::Bend);
    EXPECT_EQ(sp.stiffness[s], static_cast<S>(s < 5 ? spec.structural.stiffness : spec.bend.stiffness));
    EXPECT_EQ(sp.damping[s], static_cast<S>(s < 5 ? spec.structural.damping : spec.bend.damping));
  }
  EXPECT_NEAR(static_cast<double>(sp.restLength[2]), std::sqrt(2.0), 4 * eps<S>());
  EXPECT_NEAR(static_cast<double>(sp.restLength[5]), std::sqrt(2.0), 4 * eps<S>());
  // Vertices 0 and 3 are in both triangles (area 1/2 each): 1/3 of the area each; 1 and 2: 1/6.
  const double expected[4] = {0.2, 0.1, 0.1, 0.2};
  for (Index i = 0; i < 4; ++i) EXPECT_NEAR(static_cast<double>(model.mass()[i]), expected[i], 4 * eps<S>());
  ASSERT_EQ(model.triangleCount(), 2);
  EXPECT_EQ(model.triangles().a[1], 0);
  EXPECT_EQ(model.triangles().b[1], 3);
  EXPECT_EQ(model.triangles().c[1], 2);
}

TYPED_TEST(ClothMeshTest, GridMeshHasOneSpringPerEdgeAndOneBendPerInteriorEdge) {
  using S = TypeParam;
  // 8 x 8 quads, 9 x 9 vertices: edges 8*9 + 9*8 + 64 diagonals = 208, 32 of them on the
  // boundary; 128 triangles. Every interior edge of this grid has its own opposite pair.
  const TriangleMesh mesh = gridMesh(8, 8, 0.05);
  const auto [edges, interior] = edgeCounts(mesh);
  ASSERT_EQ(edges, 208);
  ASSERT_EQ(interior, 176);
  ClothMeshSpec spec;
  spec.totalMass = 0.37;
  ModelBuilder<S> builder;
  const ClothMeshStats stats = addClothMesh(builder, mesh, spec);
  EXPECT_EQ(stats.structuralSprings, edges);
  EXPECT_EQ(stats.bendSprings, interior);
  EXPECT_EQ(stats.triangles, 128);
  EXPECT_NEAR(stats.area, 0.16, 1e-14);
  const ModelAndState<S> built = builder.build();
  const auto byClass = built.model.springCountByClass();
  EXPECT_EQ(byClass[static_cast<int>(SpringClass::Structural)], 208);
  EXPECT_EQ(byClass[static_cast<int>(SpringClass::Shear)], 0);
  EXPECT_EQ(byClass[static_cast<int>(SpringClass::Bend)], 176);

  // Masses: total = totalMass, each proportional to its lumped area (corners with one
  // triangle get 1/6 of a quad, corners with two 1/3, inner vertices 1).
  const std::vector<double> area = lumpedAreas(mesh);
  double total = 0;
  for (Index i = 0; i < built.model.particleCount(); ++i) {
    const double m = static_cast<double>(built.model.mass()[i]);
    total += m;
    EXPECT_NEAR(m / area[i], spec.totalMass / 0.16, 8 * eps<S>() * spec.totalMass / 0.16) << "particle " << i;
  }
  EXPECT_NEAR(total, spec.totalMass, (std::is_same_v<S, double> ? 1e-12 : 1e-6));

  // No bend springs when asked for none.
  spec.bendSprings = false;
  ModelBuilder<S> plain;
  EXPECT_EQ(addClothMesh(plain, mesh, spec).bendSprings, 0);
  EXPECT_EQ(plain.springCount(), 208);
}

TYPED_TEST(ClothMeshTest, MeshAtRestHasNoSpringForces) {
  using S = TypeParam;
  // A flat square and the same square bent into a quarter cylinder (bend springs across
  // creases): every rest length is the initial distance, so with no gravity nothing moves.
  TriangleMesh flat = gridMesh(6, 6, 1.0 / 6);
  TriangleMesh bent = flat;
  for (Vec3d& v : bent.vertices) {
    const double angle = v.x * 1.5707963267948966;
    v = {std::sin(angle), v.y, 1 - std::cos(angle)};
  }
  for (const TriangleMesh* mesh : {&flat, &bent}) {
    ModelBuilder<S> builder;
    ClothMeshSpec spec;
    spec.translate = {0.3, 1.2, -0.4};
    addClothMesh(builder, *mesh, spec);
    const ModelAndState<S> built = builder.build();
    Executor exec(1);
    ForceField<S> forces(built.model, ForceStrategy::Gather, {0, 0, 0});
    Vec3Array<S> a(built.model.particleCount(), 3);
    forces.accelerations(built.state.x, built.state.v, a, exec);
    // Rounding scale: ks * length * (1/m) * 1000 eps (7 m/s^2 in float); a rest length 1%
    // off would give about 800 N/m * 0.0017 m * 432 / kg = 600 m/s^2.
    const double w = static_cast<double>(built.model.inverseMass().maxCoeff());
    const double bound = 1e3 * eps<S>() * spec.structural.stiffness * (1.0 / 6) * w;
    EXPECT_LE(static_cast<double>(a.cwiseAbs().maxCoeff()), bound) << (mesh == &flat ? "flat" : "bent");
  }
}

TYPED_TEST(ClothMeshTest, ArealDensityScaleTranslateAndANonEmptyBuilder) {
  using S = TypeParam;
  ModelBuilder<S> builder;
  RopeSpec rope;
  rope.particleCount = 5;
  addRope(builder, rope);
  const Index springsBefore = builder.springCount();
  const TriangleMesh quad = gridMesh(1, 1, 1);
  ClothMeshSpec spec;
  spec.arealDensity = 0.2;  // wins over totalMass
  spec.totalMass = 100;
  spec.scale = 0.5;
  spec.translate = {1, 2, 3};
  const ClothMeshStats stats = addClothMesh(builder, quad, spec);
  EXPECT_EQ(stats.firstParticle, 5);
  EXPECT_DOUBLE_EQ(stats.area, 0.25);
  EXPECT_EQ(builder.particleCount(), 9);
  EXPECT_EQ(builder.triangleCount(), 2);
  const Vec3d corner = builder.position(8);  // vertex 3 = (1, 1, 0)
  EXPECT_EQ(asTuple(corner), asTuple(Vec3d{1.5, 2.5, 3}));
  const ModelAndState<S> built = builder.build();
  double total = 0;
  for (Index i = 5; i < 9; ++i) total += static_cast<double>(built.model.mass()[i]);
  EXPECT_NEAR(total, 0.2 * 0.25, 8 * eps<S>());
  const Springs<S>& sp = built.model.springs();
  for (Index s = springsBefore; s < sp.count(); ++s) {
    EXPECT_GE(sp.a[s], 5);
    EXPECT_GE(sp.b[s], 5);
  }
  EXPECT_EQ(built.model.triangles().a[0], 5);
  EXPECT_EQ(built.model.triangles().c[0], 8);
}

TYPED_TEST(ClothMeshTest, BendSpringsSkipJoinedAndRepeatedPairs) {
  using S = TypeParam;
  // A tetrahedron: every edge is interior, and its opposite pair is itself an edge.
  TriangleMesh tetra;
  tetra.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  tetra.triangles = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  ModelBuilder<S> b1;
  ClothMeshStats stats = addClothMesh(b1, tetra, {});
  EXPECT_EQ(stats.structuralSprings, 6);
  EXPECT_EQ(stats.bendSprings, 0);
  // Four triangles around y with tips p, q: the interior edges x-y and y-z both hinge on
  // (p, q), y-p and y-q both on (x, z): 4 interior edges, 2 bend springs.
  TriangleMesh wings;
  wings.vertices = {{1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, 0, 1}, {0, 0, -1}};  // x y z p q
  wings.triangles = {{0, 1, 3}, {1, 0, 4}, {1, 2, 3}, {2, 1, 4}};
  ASSERT_EQ(edgeCounts(wings).second, 4);
  ModelBuilder<S> b2;
  stats = addClothMesh(b2, wings, {});
  EXPECT_EQ(stats.structuralSprings, 8);
  EXPECT_EQ(stats.bendSprings, 2);
  const ModelAndState<S> built = b2.build();
  const Springs<S>& sp = built.model.springs();
  EXPECT_EQ(std::make_pair(sp.a[8], sp.b[8]), std::make_pair(3, 4));  // across x-y, the first interior edge
  EXPECT_EQ(std::make_pair(sp.a[9], sp.b[9]), std::make_pair(0, 2));  // across y-p
  // A non-manifold edge gets its structural spring and no bend spring.
  TriangleMesh fan;
  fan.vertices = {{0, 0, 0}, {1, 0, 0}, {0.5, 1, 0}, {0.5, -1, 0}, {0.5, 0, 1}};
  fan.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  ModelBuilder<S> b3;
  stats = addClothMesh(b3, fan, {});
  EXPECT_EQ(stats.structuralSprings, 7);
  EXPECT_EQ(stats.bendSprings, 0);
}

TYPED_TEST(ClothMeshTest, RejectsBadSpecsAndMeshesLeavingTheBuilderUnchanged) {
  using S = TypeParam;
  const TriangleMesh quad = gridMesh(1, 1, 1);
  const auto rejected = [&](const TriangleMesh& mesh, const ClothMeshSpec& spec) {
    ModelBuilder<S> builder;
    builder.addParticle({0, 0, 0}, 1);
    const std::string what = thrownMessage<std::invalid_argument>([&] { addClothMesh(builder, mesh, spec); });
    EXPECT_EQ(builder.particleCount(), 1) << what;
    EXPECT_EQ(builder.springCount(), 0) << what;
    EXPECT_EQ(builder.triangleCount(), 0) << what;
    return what;
  };
  ClothMeshSpec spec;
  spec.totalMass = 0;
  EXPECT_THAT(rejected(quad, spec), AllOf(HasSubstr("ClothMeshSpec.totalMass"), HasSubstr("got 0")));
  spec = {};
  spec.arealDensity = -1;
  EXPECT_THAT(rejected(quad, spec), AllOf(HasSubstr("ClothMeshSpec.arealDensity"), HasSubstr("got -1")));
  spec = {};
  spec.scale = 0;
  EXPECT_THAT(rejected(quad, spec), AllOf(HasSubstr("ClothMeshSpec.scale"), HasSubstr("got 0")));
  spec = {};
  spec.translate.y = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(rejected(quad, spec), AllOf(HasSubstr("ClothMeshSpec.translate.y"), HasSubstr("nan")));
  spec = {};
  spec.bend.stiffness = -5;
  EXPECT_THAT(rejected(quad, spec), AllOf(HasSubstr("ClothMeshSpec.bend.stiffness"), HasSubstr("got -5")));

  TriangleMesh bad = quad;
  bad.triangles[1][0] = 9;
  EXPECT_THAT(rejected(bad, {}), AllOf(HasSubstr("triangles[1][0]"), HasSubstr("got 9")));
  bad = quad;
  bad.triangles[0][2] = bad.triangles[0][0];
  EXPECT_THAT(rejected(bad, {}), AllOf(HasSubstr("triangles[0]"), HasSubstr("distinct"), HasSubstr("(0, 1, 0)")));
  bad = quad;
  bad.vertices.push_back({5, 5, 5});
  EXPECT_THAT(rejected(bad, {}), AllOf(HasSubstr("vertices[4]"), HasSubstr("no triangle area")));
  bad = quad;
  bad.vertices[0].x = HUGE_VAL;
  EXPECT_THAT(rejected(bad, {}), AllOf(HasSubstr("vertices[0].x"), HasSubstr("inf")));
  bad = quad;
  for (Vec3d& v : bad.vertices) v.y = 0;  // all on the x axis: no area
  EXPECT_THAT(rejected(bad, {}), AllOf(HasSubstr("total area"), HasSubstr("got 0")));
  bad.triangles.clear();
  EXPECT_THAT(rejected(bad, {}), HasSubstr("no triangles"));

  // What the builder's precision cannot hold is refused here, not later by build(): a
  // cloth addClothMesh accepts builds. (Found by fuzz_mesh: an STL of triangles 1e-30 m
  // across gave particles of 5e-61 kg, whose 1/mass no float holds.)
  const bool single = sizeof(S) == sizeof(float);
  bad = quad;
  for (Vec3d& v : bad.vertices) v = {v.x * 1e-30, v.y * 1e-30, v.z * 1e-30};
  spec = {};
  spec.arealDensity = 1;  // kg/m^2: masses of 1e-60 kg
  if (single) {
    EXPECT_THAT(rejected(bad, spec), AllOf(HasSubstr("mass of mesh vertices[0] (density * area / 3)"),
                                           HasSubstr("1/mass are finite in float precision")));
  } else {
    ModelBuilder<S> builder;
    addClothMesh(builder, bad, spec);
    EXPECT_EQ(builder.build().model.particleCount(), 4);
  }
  bad = quad;
  bad.vertices[2].z = 3e18;
  if (single) {
    EXPECT_THAT(rejected(bad, {}), AllOf(HasSubstr("addClothMesh: mesh vertices[2].z must be within +-1e+18 m in "
                                                   "float precision"),
                                         HasSubstr("got 3e+18")));
  }
  spec = {};
  spec.structural.stiffness = 1e300;
  if (single) {
    EXPECT_THAT(rejected(quad, spec), AllOf(HasSubstr("ClothMeshSpec.structural.stiffness must be finite and >= 0 "
                                                      "(N/m) and at most 3.40282"),
                                            HasSubstr("in float precision, got 1e+300")));
  }
}

// ---------------------------------------------------------------------------------------
// Mesh files (assimp)
// ---------------------------------------------------------------------------------------

TEST(MeshFile, ObjQuadKeepsItsFourSharedVertices) {
  const TriangleMesh raw = loadMesh(dataPath("quad.obj"));
  EXPECT_EQ(raw.vertices.size(), 4u) << "weft's OBJ reader keeps the file's vertices, shared by the faces";
  EXPECT_EQ(raw.triangles.size(), 2u);
  MeshReport r;
  const TriangleMesh clean = loadCleanMesh(dataPath("quad.obj"), {}, &r);
  expectCounts(r, {4, 2, 0, 0, 0, 0, 0, 4, 4, 2});
  const std::vector<std::array<Index, 3>> triangles = {{0, 1, 2}, {0, 2, 3}};
  EXPECT_EQ(clean.triangles, triangles);
  EXPECT_EQ(asTuple(clean.vertices[2]), asTuple(Vec3d{1, 1, 0}));
}

TEST(MeshFile, ObjAnd3dsOfTheSameGridAgree) {
  MeshReport objReport, tdsReport;
  const TriangleMesh obj = loadCleanMesh(dataPath("grid3x3.obj"), {}, &objReport);
  const TriangleMesh tds = loadCleanMesh(dataPath("grid3x3.3ds"), {}, &tdsReport);
  // OBJ's faces share the file's 9 vertices; 3DS gives each of the 24 corners its own, welded.
  expectCounts(objReport, {9, 8, 0, 0, 0, 0, 0, 8, 9, 8});
  expectCounts(tdsReport, {24, 8, 15, 0, 0, 0, 0, 8, 9, 8});
  // The same triangles with the same winding, numbered in each file's order. The 3DS reader
  // turns z-up into y-up: file (x, y, z) -> (x, z, -y).
  TriangleMesh turned = obj;
  for (Vec3d& v : turned.vertices) v = {v.x, v.z, -v.y + 0.0};
  EXPECT_EQ(geometry(turned), geometry(tds));
  ASSERT_EQ(obj.vertices.size(), tds.vertices.size());
  // Both make the same cloth.
  ModelBuilder<double> b1, b2;
  const ClothMeshStats s1 = addClothMesh(b1, obj, {}), s2 = addClothMesh(b2, tds, {});
  EXPECT_EQ(s1.structuralSprings, 16);
  EXPECT_EQ(s1.bendSprings, 8);
  EXPECT_EQ(std::tie(s1.particles, s1.structuralSprings, s1.bendSprings, s1.triangles),
            std::tie(s2.particles, s2.structuralSprings, s2.bendSprings, s2.triangles));
  EXPECT_DOUBLE_EQ(s1.area, 1.0);
  EXPECT_DOUBLE_EQ(s2.area, 1.0);
}

TEST(MeshFile, DuplicateVerticesDegenerateAndDuplicateTriangles) {
  // 6 faces over the file's 7 vertices; v6 is 3e-7 m from v3.
  MeshReport r;
  TriangleMesh clean = loadCleanMesh(dataPath("duplicates.obj"), {}, &r);
  // Welded: 7 vertices into 5 groups; the group of v7 is used by a degenerate triangle only.
  expectCounts(r, {7, 6, 2, 1, 2, 2, 0, 4, 4, 2});
  EXPECT_EQ(clean.vertices.size(), 4u);
  // With tolerance 0, v6 stays apart, and v5 v3 v6 is a (thin but real) triangle.
  clean = loadCleanMesh(dataPath("duplicates.obj"), {0}, &r);
  expectCounts(r, {7, 6, 1, 1, 1, 2, 0, 7, 5, 3});
}

TEST(MeshFile, NonManifoldEdgeIsCounted) {
  MeshReport r;
  const TriangleMesh clean = loadCleanMesh(dataPath("nonmanifold.obj"), {}, &r);
  expectCounts(r, {5, 3, 0, 0, 0, 0, 1, 6, 5, 3});
  EXPECT_THAT(r.summary(), HasSubstr("1 non-manifold edge"));
}

TEST(MeshFile, PolygonsAreTriangulatedAndObjectsConcatenated) {
  const std::string path = tempFile("polygons.obj",
                                    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 5 5 5\nv 6 5 5\nv 6 6 5\n"
                                    "o first\nusemtl red\nf 1 2 3 4\no second\nusemtl blue\nf 5 6 7\n");
  MeshReport r;
  const TriangleMesh clean = loadCleanMesh(path, {}, &r);
  EXPECT_EQ(r.outputTriangles, 3);
  EXPECT_EQ(r.outputVertices, 7);
  std::set<std::tuple<double, double, double>> positions;
  for (const Vec3d& v : clean.vertices) positions.insert(asTuple(v));
  EXPECT_EQ(positions.count({6, 6, 5}), 1u);
  EXPECT_EQ(positions.size(), 7u);
}

TEST(MeshFile, BadFilesAreReportedWithTheirName) {
  const auto runtimeError = [](const std::string& path) {
    return thrownMessage<std::runtime_error>([&] { loadCleanMesh(path); });
  };
  const auto named = [](const std::string& path) { return HasSubstr("mesh file '" + path + "': "); };

  const std::string missing = ::testing::TempDir() + "weft_mesh_no_such_file.obj";
  fs::remove(missing);
  EXPECT_THAT(runtimeError(missing), AllOf(named(missing), HasSubstr("cannot open: No such file or directory")));
  const std::string directory = ::testing::TempDir() + "weft_mesh_directory.obj";
  fs::create_directories(directory);
  EXPECT_THAT(runtimeError(directory), AllOf(named(directory), HasSubstr("is a directory")));
  EXPECT_THAT(runtimeError(dataPath("empty.obj")),
              AllOf(named(dataPath("empty.obj")), HasSubstr("no triangles"), HasSubstr("empty (0 bytes)")));
  EXPECT_THAT(runtimeError(dataPath("no_faces.obj")),
              AllOf(named(dataPath("no_faces.obj")), HasSubstr("no triangles"), HasSubstr("1 point, 2 lines")));
  EXPECT_THAT(runtimeError(dataPath("garbage.obj")),
              AllOf(named(dataPath("garbage.obj")), HasSubstr("OBJ line 2: a face names vertex 9, but the file has 0 "
                                                              "vertices")));
  std::ifstream grid(dataPath("grid3x3.3ds"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(grid)), std::istreambuf_iterator<char>());
  ASSERT_EQ(bytes.size(), 237u);
  const std::string truncated = tempFile("truncated.3ds", bytes.substr(0, 120));
  EXPECT_THAT(runtimeError(truncated), AllOf(named(truncated), HasSubstr("assimp cannot read it: Chunk is too large")));
  const std::string unknown = tempFile("unknown.xyz", "hello\n");
  EXPECT_THAT(runtimeError(unknown),
              AllOf(named(unknown), HasSubstr("assimp cannot read it"), HasSubstr("No suitable reader found")));
  // Contents cleanMesh rejects: named by file, then by field and value.
  const std::string nan = tempFile("nan.obj", "v 0 0 0\nv 1 nan 0\nv 1 1 0\nf 1 2 3\n");
  EXPECT_THAT(runtimeError(nan), AllOf(named(nan), HasSubstr("vertices[1].y must be finite, got nan")));
  const std::string flat = tempFile("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 3 2 1\n");
  EXPECT_THAT(runtimeError(flat), AllOf(named(flat), HasSubstr("no triangles after cleaning: 2 degenerate")));
  // A bad option is the caller's error, reported before the file is read.
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { loadCleanMesh(missing, {-1}); }),
              AllOf(HasSubstr("MeshCleanOptions.weldTolerance"), HasSubstr("got -1"), Not(HasSubstr(missing))));
}

/// An input of tests/fuzz/fuzz_mesh.cpp kept in tests/fuzz/regressions/mesh/: its first
/// byte is the target's format choice ('1': ply), the rest the file.
std::string fuzzRegression(const std::string& name) {
  std::ifstream in(dataPath("../fuzz/regressions/mesh/" + name), std::ios::binary);
  const std::string input((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(input.substr(0, 4), "1ply") << name;
  return input.substr(1);
}

// Found by fuzz_mesh: a PLY header without its end_header line (a truncated file) kept
// assimp 5.2's PLY reader busy without end; weft refuses it before assimp sees it, from
// memory and from a file, and still hands assimp a header that does end (any line ending).
TEST(MeshFile, PlyHeaderWithoutEndHeaderIsRefused) {
  const auto named = [](const std::string& path) {
    return AllOf(HasSubstr("mesh file '" + path + "': "), HasSubstr("PLY header has no end_header line"));
  };
  for (const char* name : {"ply-header-without-end-hangs.ply", "ply-header-without-end-hangs-fuzzed.ply",
                           "ply-first-line-ply-then-garbage-hangs.ply"}) {
    const std::string contents = fuzzRegression(name);
    EXPECT_THAT(thrownMessage<std::runtime_error>([&] { loadMeshFromMemory(contents, "fuzzed.ply"); }),
                named("fuzzed.ply"))
        << name;
    const std::string path = tempFile(name, contents);
    EXPECT_THAT(thrownMessage<std::runtime_error>([&] { loadMesh(path); }), named(path)) << name;
  }
  const std::string header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n";
  EXPECT_THAT(thrownMessage<std::runtime_error>([&] { loadMeshFromMemory(header, "cut.ply"); }), named("cut.ply"));
  const std::string triangle = header +
                               "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                               "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  EXPECT_EQ(loadMeshFromMemory(triangle, "triangle.ply").triangles.size(), 1u);
  std::string crlf;
  for (const char c : triangle) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  EXPECT_EQ(loadMeshFromMemory(crlf, "crlf.ply").triangles.size(), 1u);
  // assimp takes a file for PLY when its first three bytes are "ply" in any case.
  EXPECT_THAT(thrownMessage<std::runtime_error>([&] { loadMeshFromMemory("pLyX\nformat ascii 1.0\n", "mixed.ply"); }),
              named("mixed.ply"));
  // Not PLY (no "ply" first line): not this check's business, whatever the name says.
  EXPECT_THAT(thrownMessage<std::runtime_error>([&] { loadMeshFromMemory("solid x\n", "x.ply"); }),
              Not(HasSubstr("end_header")));
}

// Found by fuzz_mesh: a PLY header corrupted by NUL bytes. assimp rejects it (and leaks the
// mesh it had started, inside assimp: assimp/assimp#5717, suppressed in
// tests/lsan.supp); weft reports that as the import's documented error.
// Since a header with binary bytes crashed assimp's PLY reader (a segmentation fault inside
// libassimp, found by fuzz_mesh), a PLY header must be text up to end_header: weft refuses
// the others before assimp sees them, naming the byte and the line.
TEST(MeshFile, FuzzedCorruptPlyIsReportedWithItsName) {
  for (const char* name : {"ply-corrupt-header-assimp-leak.ply", "ply-binary-bytes-in-header-crashes-assimp.ply"}) {
    const std::string contents = fuzzRegression(name);
    EXPECT_THAT(
        thrownMessage<std::runtime_error>([&] { loadMeshFromMemory(contents, "fuzzed.ply"); }),
        AllOf(HasSubstr("mesh file 'fuzzed.ply': PLY header has a byte that is not text ("), HasSubstr(" in line ")))
        << name;
  }
  // Text headers still go to assimp, which says what it cannot parse.
  EXPECT_THAT(thrownMessage<std::runtime_error>(
                  [] { loadMeshFromMemory("ply\nformat ascii 1.0\nelement vertex x\nend_header\n", "words.ply"); }),
              HasSubstr("mesh file 'words.ply': "));
}

// Found by fuzz_mesh: PLY files whose faces index vertices the file does not have (a header
// declaring 2 vertices, faces using 4; a vertex line cut short by NUL bytes). assimp 5.2's
// reader reads the extra vertex lines as faces and passes them on with primitive-type flags
// that do not match them, and its triangulation then aborted the program on an assertion.
// weft checks the raw scene before any post-processing and names the face.
TEST(MeshFile, FacesIndexingMissingVerticesAreRefusedBeforeAssimpPostProcessing) {
  EXPECT_THAT(thrownMessage<std::runtime_error>([] {
                loadMeshFromMemory(fuzzRegression("ply-fewer-vertices-than-indexed-aborts-assimp.ply"), "fuzzed.ply");
              }),
              HasSubstr("mesh file 'fuzzed.ply': PLY line 14: '0' after the last element the header declares (its "
                        "counts are smaller than the data)"));
  // A face indexing past the vertices the file has: named with its corner and index.
  const std::string beyond =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n3 0 1 7\n";
  EXPECT_THAT(thrownMessage<std::runtime_error>([&] { loadMeshFromMemory(beyond, "beyond.ply"); }),
              HasSubstr("mesh file 'beyond.ply': PLY face 0 corner 2: vertex index must be >= 0 and < 3 (the vertex "
                        "count), got 7"));
  const std::string cut = fuzzRegression("ply-short-vertex-line-aborts-assimp.ply");
  EXPECT_THAT(thrownMessage<std::runtime_error>([&] { loadMeshFromMemory(cut, "cut.ply"); }),
              HasSubstr("mesh file 'cut.ply': "));
  const std::string path = tempFile("cut.ply", cut);
  EXPECT_THAT(thrownMessage<std::runtime_error>([&] { loadMesh(path); }), HasSubstr("mesh file '" + path + "': "));
  // The same file with its header's counts right still loads, its quad split in two.
  const std::string quad =
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
      "4 0 1 2 3\n";
  const TriangleMesh mesh = loadMeshFromMemory(quad, "quad.ply");
  EXPECT_EQ(mesh.vertices.size(), 4u);
  EXPECT_EQ(mesh.triangles.size(), 2u);
}

TEST(MeshFile, UnreadableFileIsReported) {
  if (geteuid() == 0) GTEST_SKIP() << "running as root: file permissions do not stop reading";
  const std::string path = tempFile("unreadable.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n");
  ASSERT_EQ(chmod(path.c_str(), 0), 0);
  EXPECT_THAT(thrownMessage<std::runtime_error>([&] { loadMesh(path); }),
              AllOf(HasSubstr("mesh file '" + path + "'"), HasSubstr("cannot open: Permission denied")));
  chmod(path.c_str(), 0644);
}

// Adversarial meshes: very large, coordinates beyond what the precision can square, only
// degenerate triangles, one vertex shared by ten thousand triangles. Each is either built
// or refused with a message naming the field and the value, never a crash or NaN later.

/// A binary STL of a w x h grid of 1 mm squares (2 w h triangles).
std::string binaryStlGrid(int w, int h) {
  std::string out(80, ' ');
  const std::uint32_t count = static_cast<std::uint32_t>(2 * w * h);
  out.append(reinterpret_cast<const char*>(&count), 4);
  const auto triangle = [&](float ax, float ay, float bx, float by, float cx, float cy) {
    const float values[12] = {0, 0, 1, ax, ay, 0, bx, by, 0, cx, cy, 0};
    out.append(reinterpret_cast<const char*>(values), sizeof values);
    out.append(2, '\0');
  };
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const float x = 0.001f * static_cast<float>(c), y = 0.001f * static_cast<float>(r), d = 0.001f;
      triangle(x, y, x + d, y, x + d, y + d);
      triangle(x, y, x + d, y + d, x, y + d);
    }
  return out;
}

TEST(AdversarialMesh, AMillionTrianglesAreReadCleanedAndBuilt) {
  // A million triangles, a 50 MB file; 100 k under the sanitizers (10-20x slower).
  const int w = weft::test::kSanitized ? 250 : 1000, h = weft::test::kSanitized ? 200 : 500;
  const std::string path = tempFile("million.stl", binaryStlGrid(w, h));
  MeshReport report;
  const TriangleMesh mesh = loadCleanMesh(path, {}, &report);
  std::filesystem::remove(path);
  EXPECT_EQ(report.outputTriangles, 2 * w * h);
  EXPECT_EQ(report.outputVertices, (w + 1) * (h + 1)) << "corner copies welded";
  EXPECT_EQ(report.boundaryEdges, 2 * (w + h));
  ModelBuilder<float> builder;
  const ClothMeshStats stats = addClothMesh(builder, mesh);
  EXPECT_EQ(stats.particles, (w + 1) * (h + 1));
  const ModelAndState<float> built = builder.build();
  EXPECT_EQ(built.model.triangleCount(), 2 * w * h);
}

TEST(AdversarialMesh, CoordinatesTooLargeToSquareAreRefusedByPrecision) {
  // 1e38 fits in a float, but its square does not: every spring length would overflow, so
  // a float cloth refuses it (naming the vertex and the bound) and leaves the builder as it
  // was, as build() would refuse a particle there; double takes it and steps.
  const TriangleMesh mesh =
      loadCleanMeshFromMemory("v 0 0 0\nv 1e38 0 0\nv 0 1e38 0\nv 1e38 1e38 0\nf 1 2 3\nf 2 4 3\n", "big.obj");
  ModelBuilder<float> single;
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { (void)addClothMesh(single, mesh); }),
              AllOf(HasSubstr("addClothMesh: mesh vertices[1].x must be within +-1e+18 m in float precision"),
                    HasSubstr("got 1e+38")));
  EXPECT_EQ(single.particleCount(), 0);
  ModelBuilder<float> direct;  // the same particle added by hand: build() refuses it
  direct.addParticle({1e38, 0, 0}, 1.0);
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { (void)direct.build(); }),
              HasSubstr("position.x of particle [0] must be within +-1e+18 m in float precision"));
  ModelBuilder<double> twice;
  addClothMesh(twice, mesh);
  SimulationOptions o;
  o.threads = 1;
  Simulation<double> sim(twice.build(), o);
  EXPECT_TRUE(sim.run(3).ok());
  // A coordinate is read as the file holds it (in double), and one that no precision holds
  // is refused when the cloth is built, naming it; a NaN or an infinity is refused at import.
  const TriangleMesh huge = loadCleanMeshFromMemory("v 0 0 0\nv 1e200 0 0\nv 0 1e200 0\nf 1 2 3\n", "huge.obj");
  EXPECT_EQ(huge.vertices[1].x, 1e200);
  ModelBuilder<double> far;
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { (void)addClothMesh(far, huge); }),
              HasSubstr("addClothMesh: mesh vertices[1].x must be within +-1e+150 m in double precision"));
  EXPECT_THAT(thrownMessage<std::runtime_error>(
                  [] { (void)loadCleanMeshFromMemory("v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n", "inf.obj"); }),
              AllOf(HasSubstr("mesh file 'inf.obj'"), HasSubstr("vertices[1].x must be finite, got inf")));
  EXPECT_THAT(thrownMessage<std::runtime_error>(
                  [] { (void)loadCleanMeshFromMemory("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "nan.obj"); }),
              AllOf(HasSubstr("mesh file 'nan.obj'"), HasSubstr("vertices[1].x must be finite, got nan")));
}

TEST(AdversarialMesh, ACoordinateThatCannotHoldTheEdgesIsRefusedByPrecision) {
  // A 1 cm quad moved 1e5 m away: in float a coordinate there steps by 8 mm, and rounding
  // would change its edges by more than a tenth, so it is refused naming the edge's vertices
  // and the builder is left as it was; double holds it.
  const TriangleMesh quad =
      loadCleanMeshFromMemory("v 0 0 0\nv 0.01 0 0\nv 0 0.01 0\nv 0.01 0.01 0\nf 1 2 3\nf 2 4 3\n", "small.obj");
  ClothMeshSpec spec;
  spec.translate = {1e5, 0, 0};
  ModelBuilder<float> single;
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { (void)addClothMesh(single, quad, spec); }),
              AllOf(HasSubstr("addClothMesh: the largest |coordinate| of the ends of the structural spring between "
                              "mesh vertices[0] and vertices[1] (scaled and translated) must be at most "),
                    HasSubstr("m in float precision (the spring's rest length, 0.00999999")));
  EXPECT_EQ(single.particleCount(), 0);
  spec.translate = {1e3, 0, 0};
  EXPECT_NO_THROW((void)addClothMesh(single, quad, spec));
  spec.translate = {1e5, 0, 0};
  ModelBuilder<double> twice;
  EXPECT_NO_THROW((void)addClothMesh(twice, quad, spec));
}

TEST(AdversarialMesh, OnlyDegenerateTrianglesLeaveNothingToBuild) {
  // A thousand triangles of zero area: collinear corners, repeated corners, coincident points.
  std::string obj;
  for (int k = 0; k < 500; ++k) obj += "v " + std::to_string(k) + " 0 0\n";
  obj += "v 7 7 7\nv 7 7 7\nv 7 7 7\n";
  for (int k = 1; k + 2 <= 500; k += 2)
    obj += "f " + std::to_string(k) + " " + std::to_string(k + 1) + " " + std::to_string(k + 2) + "\n";
  for (int k = 0; k < 500; ++k) obj += "f 501 502 503\n";
  EXPECT_THAT(thrownMessage<std::runtime_error>([&] { (void)loadCleanMeshFromMemory(obj, "flat.obj"); }),
              AllOf(HasSubstr("mesh file 'flat.obj'"), HasSubstr("no triangles after cleaning")));
}

TEST(AdversarialMesh, OneVertexSharedByTenThousandTriangles) {
  // A fan: the hub is in every triangle. It builds and steps; self-collision refuses its
  // default thickness (the slivers' altitude, 0.6 mm, is below 4 mm) rather than making
  // every pair of the fan a contact.
  constexpr int kFan = 10000;
  std::string obj = "v 0 0 0\n";
  for (int k = 0; k < kFan; ++k) {
    const double a = 2 * 3.14159265358979323846 * k / kFan;
    obj += "v " + std::to_string(std::cos(a)) + " " + std::to_string(std::sin(a)) + " 0\n";
  }
  for (int k = 0; k < kFan; ++k)
    obj += "f 1 " + std::to_string(2 + k) + " " + std::to_string(2 + (k + 1) % kFan) + "\n";
  MeshReport report;
  const TriangleMesh mesh = loadCleanMeshFromMemory(obj, "fan.obj", {}, &report);
  EXPECT_EQ(report.outputTriangles, kFan);
  ModelBuilder<double> builder;
  const ClothMeshStats stats = addClothMesh(builder, mesh);
  EXPECT_EQ(stats.particles, kFan + 1);
  EXPECT_EQ(stats.structuralSprings, 2 * kFan);
  auto model = std::make_shared<const Model<double>>(builder.build().model);
  ModelBuilder<double> again;
  addClothMesh(again, mesh);
  const State<double> initial = again.build().state;
  SimulationOptions o;
  o.threads = 2;
  o.dt = 1e-5;
  Simulation<double> sim(model, initial, o);
  EXPECT_TRUE(sim.run(5).ok());
  o.selfCollision.enabled = true;
  EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { Simulation<double>(model, initial, o); }),
              AllOf(HasSubstr("SimulationOptions.selfCollision.thickness = 0.004"), HasSubstr("smallest altitude")));
}

}  // namespace
}  // namespace weft::test
