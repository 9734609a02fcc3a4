// Rigid shapes (weft/rigid/convex_hull.hpp, weft/rigid/mass_properties.hpp): box hulls and
// their supports; quickhull against brute force on random clouds (containment, vertices are
// input points, every strict extreme point is a vertex and every vertex is one), coplanar
// merging (a box's corners with face, edge and interior points gives 6 quads), points on a
// sphere (all vertices, triangles only), near-degenerate clouds (Minkowski differences of
// rotated boxes, lattices, thin slabs, far from the origin) and the documented errors;
// the invariant check rejecting broken hulls. Mass properties: box and tetrahedron closed
// forms, rigid motions (centre moves, inertia rotates as R I R^T), convergence of sphere
// hulls, the capsule's hemisphere shift checked against a fine hull, and bad input.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "weft/rigid/convex_hull.hpp"
#include "weft/rigid/mass_properties.hpp"

namespace weft {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using ::testing::HasSubstr;

Matrix3d randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
}

Vector3d randomUnit(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  return Vector3d(n(rng), n(rng), n(rng)).normalized();
}

/// The message of the std::invalid_argument that f throws, or a note that it did not.
template <class F>
std::string invalidArgumentMessage(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no std::invalid_argument thrown)";
}

double extentOf(const std::vector<Vector3d>& points) {
  Vector3d lo = points[0], hi = points[0];
  for (const Vector3d& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return (hi - lo).maxCoeff();
}

/// Largest height of any point above any face plane of the hull.
double maxHeightAboveFaces(const ConvexHull& hull, const std::vector<Vector3d>& points) {
  double worst = -std::numeric_limits<double>::infinity();
  for (const ConvexFace& f : hull.faces)
    for (const Vector3d& p : points) worst = std::max(worst, f.normal.dot(p) - f.offset);
  return worst;
}

/// Every hull vertex is bitwise one of the points.
bool verticesAreInputPoints(const ConvexHull& hull, std::vector<Vector3d> points) {
  const auto less = [](const Vector3d& a, const Vector3d& b) {
    return std::tie(a.x(), a.y(), a.z()) < std::tie(b.x(), b.y(), b.z());
  };
  std::sort(points.begin(), points.end(), less);
  for (const Vector3d& v : hull.vertices)
    if (!std::binary_search(points.begin(), points.end(), v, less)) return false;
  return true;
}

/// The properties every hull of `points` must have, `tolerance` relative to their extent.
void expectValidHullOf(const ConvexHull& hull, const std::vector<Vector3d>& points, double tolerance) {
  const double scale = extentOf(points);
  EXPECT_EQ(checkConvexHull(hull, tolerance), "");
  EXPECT_LE(maxHeightAboveFaces(hull, points), tolerance * scale);
  EXPECT_TRUE(verticesAreInputPoints(hull, points));
}

std::vector<Vector3d> boxCorners(const Vector3d& h) {
  std::vector<Vector3d> corners;
  for (int i = 0; i < 8; ++i)
    corners.emplace_back((i & 1) ? h.x() : -h.x(), (i & 2) ? h.y() : -h.y(), (i & 4) ? h.z() : -h.z());
  return corners;
}

/// Roughly uniform points on the unit sphere (Fibonacci lattice).
std::vector<Vector3d> fibonacciSphere(int count) {
  std::vector<Vector3d> points;
  const double golden = std::numbers::pi * (3 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double y = 1 - 2 * (i + 0.5) / count, r = std::sqrt(1 - y * y), phi = golden * i;
    points.emplace_back(r * std::cos(phi), y, r * std::sin(phi));
  }
  return points;
}

// ----------------------------------------------------------------------------- box hulls

TEST(BoxHull, CountsInvariantsAndSupports) {
  const Vector3d h(0.5, 1.25, 2);
  const ConvexHull box = makeBoxHull(h);
  EXPECT_EQ(box.vertexCount(), 8);
  EXPECT_EQ(box.faceCount(), 6);
  EXPECT_EQ(box.edgeCount(), 12);
  EXPECT_EQ(checkConvexHull(box), "");
  EXPECT_TRUE(box.centroid.isZero(0));
  EXPECT_DOUBLE_EQ(box.boundingRadius, h.norm());
  for (const ConvexFace& f : box.faces) {
    EXPECT_EQ(f.count, 4);
    EXPECT_DOUBLE_EQ(f.normal.cwiseAbs().maxCoeff(), 1.0);  // axis-aligned unit normals
    EXPECT_DOUBLE_EQ(f.offset, h.dot(f.normal.cwiseAbs()));
  }
  // Each edge joins two faces that both contain its two vertices.
  for (const ConvexEdge& e : box.edges)
    for (const int f : {e.face0, e.face1}) {
      const auto idx = box.faceIndices(f);
      EXPECT_NE(std::find(idx.begin(), idx.end(), e.v0), idx.end());
      EXPECT_NE(std::find(idx.begin(), idx.end(), e.v1), idx.end());
    }
  for (int i = 0; i < 8; ++i) {
    const Vector3d d((i & 1) ? 1 : -1, (i & 2) ? 1 : -1, (i & 4) ? 1 : -1);
    EXPECT_EQ(box.vertices[static_cast<std::size_t>(box.support(d))], h.cwiseProduct(d)) << "direction " << i;
  }
  // Ties go to the first vertex in index order.
  EXPECT_EQ(box.support(Vector3d(1, 0, 0)), 1);
  EXPECT_EQ(box.support(Vector3d::Zero()), 0);
}

TEST(BoxHull, RejectsBadHalfExtents) {
  EXPECT_EQ(invalidArgumentMessage([] { makeBoxHull(Vector3d(1, -1, 1)); }),
            "makeBoxHull: halfExtents.y must be finite and > 0, got -1");
  EXPECT_THAT(invalidArgumentMessage([] { makeBoxHull(Vector3d(0, 1, 1)); }), HasSubstr("halfExtents.x"));
  EXPECT_THAT(invalidArgumentMessage([] { makeBoxHull(Vector3d(1, 1, std::nan(""))); }),
              HasSubstr("halfExtents.z must be finite and > 0, got nan"));
}

TEST(CheckConvexHull, RejectsBrokenHulls) {
  const ConvexHull box = makeBoxHull(Vector3d(1, 2, 3));
  ConvexHull h = box;
  h.faces[2].normal = -h.faces[2].normal;
  h.faces[2].offset = -h.faces[2].offset;
  EXPECT_THAT(checkConvexHull(h), HasSubstr("counter-clockwise"));
  h = box;
  h.vertices[7] *= 1.01;  // off its three planes
  EXPECT_NE(checkConvexHull(h), "");
  h = box;
  h.faces[0].normal *= 2;
  EXPECT_THAT(checkConvexHull(h), HasSubstr("not unit"));
  h = box;
  h.edges.pop_back();
  EXPECT_THAT(checkConvexHull(h), HasSubstr("Euler"));
  h = box;
  for (int f = 0; f < 6; ++f)  // name a face that does not have the edge
    if (f != h.edges[0].face0 && f != h.edges[0].face1) {
      h.edges[0].face1 = f;
      break;
    }
  EXPECT_THAT(checkConvexHull(h), HasSubstr("does not name face"));
  h = box;
  h.faces[0].offset += 1e-3;  // vertices of face 0 below its plane, so off it
  EXPECT_THAT(checkConvexHull(h), HasSubstr("off its plane"));
  h = box;
  std::swap(h.faceVertices[0], h.faceVertices[1]);  // a bow-tie quad
  EXPECT_NE(checkConvexHull(h), "");
}

// ----------------------------------------------------------------------------- quickhull

class RandomCubeHull : public ::testing::TestWithParam<int> {};

TEST_P(RandomCubeHull, MatchesBruteForce) {
  const int count = GetParam();
  std::mt19937 rng(1234 + count);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vector3d> points;
  for (int i = 0; i < count; ++i) points.emplace_back(u(rng), u(rng), u(rng));
  const ConvexHull hull = makeConvexHull(points);
  expectValidHullOf(hull, points, 1e-9);
  for (const ConvexFace& f : hull.faces) EXPECT_EQ(f.count, 3);  // no four random points coplanar
  EXPECT_EQ(hull.faceCount(), 2 * hull.vertexCount() - 4);

  // Every point that is the strict maximum along some direction is a vertex, and support
  // finds it.
  const double margin = 1e-7;
  int strictCount = 0;
  for (int k = 0; k < 300; ++k) {
    const Vector3d d = randomUnit(rng);
    int best = 0;
    double first = -1e300, second = -1e300;
    for (int i = 0; i < count; ++i) {
      const double x = points[static_cast<std::size_t>(i)].dot(d);
      if (x > first) {
        second = first;
        first = x;
        best = i;
      } else {
        second = std::max(second, x);
      }
    }
    if (first - second < margin) continue;
    ++strictCount;
    EXPECT_EQ(hull.vertices[static_cast<std::size_t>(hull.support(d))], points[static_cast<std::size_t>(best)]);
  }
  EXPECT_GT(strictCount, 250);
  // Conversely every vertex is the strict maximum along the sum of its faces' normals.
  std::vector<Vector3d> direction(hull.vertices.size(), Vector3d::Zero());
  for (int f = 0; f < hull.faceCount(); ++f)
    for (const int v : hull.faceIndices(f)) direction[static_cast<std::size_t>(v)] += hull.faces[f].normal;
  for (int v = 0; v < hull.vertexCount(); ++v) {
    const Vector3d& d = direction[static_cast<std::size_t>(v)];
    const double own = hull.vertices[static_cast<std::size_t>(v)].dot(d);
    for (const Vector3d& p : points) {
      if (p != hull.vertices[static_cast<std::size_t>(v)]) {
        EXPECT_LT(p.dot(d), own) << "vertex " << v;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Sizes, RandomCubeHull, ::testing::Values(4, 5, 10, 100, 1000, 10000));

TEST(ConvexHull, DeterministicAndOrderIndependentInShape) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vector3d> points;
  for (int i = 0; i < 500; ++i) points.emplace_back(u(rng), u(rng), u(rng));
  const ConvexHull a = makeConvexHull(points), b = makeConvexHull(points);
  EXPECT_EQ(a.vertices, b.vertices);
  EXPECT_EQ(a.faceVertices, b.faceVertices);
  ASSERT_EQ(a.edgeCount(), b.edgeCount());
  for (int e = 0; e < a.edgeCount(); ++e) {
    EXPECT_EQ(a.edges[e].v0, b.edges[e].v0);
    EXPECT_EQ(a.edges[e].face1, b.edges[e].face1);
  }
  // Shuffled input: the same vertex set (hull vertices keep input order).
  std::vector<Vector3d> shuffled = points;
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  const ConvexHull c = makeConvexHull(shuffled);
  ASSERT_EQ(c.vertexCount(), a.vertexCount());
  for (const Vector3d& v : c.vertices) EXPECT_NE(std::find(a.vertices.begin(), a.vertices.end(), v), a.vertices.end());
}

/// A box's corners with points strictly inside, on its faces and on its edges, shuffled,
/// optionally rotated and moved: exactly the box (8 vertices, 6 quads, 12 edges).
TEST(ConvexHull, BoxWithFaceEdgeAndInteriorPointsGivesSixQuads) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  const Vector3d h(1, 2, 0.5);
  for (int trial = 0; trial < 6; ++trial) {
    std::vector<Vector3d> points = boxCorners(h);
    for (int i = 0; i < 400; ++i) {
      const Vector3d inside(u(rng), u(rng), u(rng));
      points.push_back(0.999 * inside.cwiseProduct(h));
      Vector3d onFace = inside;
      onFace[i % 3] = (i % 2) ? 1 : -1;
      points.push_back(onFace.cwiseProduct(h));
      Vector3d onEdge = onFace;
      onEdge[(i + 1) % 3] = ((i / 2) % 2) ? 1 : -1;
      points.push_back(onEdge.cwiseProduct(h));
    }
    std::shuffle(points.begin(), points.end(), rng);
    Matrix3d r = Matrix3d::Identity();
    Vector3d t = Vector3d::Zero();
    if (trial >= 2) r = randomRotation(rng);
    if (trial >= 4) t = Vector3d(300, -20, 7);
    for (Vector3d& p : points) p = r * p + t;
    const ConvexHull hull = makeConvexHull(points);
    SCOPED_TRACE(trial);
    EXPECT_EQ(hull.vertexCount(), 8);
    EXPECT_EQ(hull.faceCount(), 6);
    EXPECT_EQ(hull.edgeCount(), 12);
    expectValidHullOf(hull, points, 1e-9);
    for (const ConvexFace& f : hull.faces) {
      EXPECT_EQ(f.count, 4);
      EXPECT_NEAR((r.transpose() * f.normal).cwiseAbs().maxCoeff(), 1.0, 1e-12);
    }
    EXPECT_LE((hull.centroid - t).norm(), 1e-12 * (1 + t.norm()));
    EXPECT_NEAR(hull.boundingRadius, h.norm(), 1e-12);
  }
}

TEST(ConvexHull, PointsOnASphereAreAllVertices) {
  std::mt19937 rng(3);
  std::vector<Vector3d> points;
  for (int i = 0; i < 1000; ++i) points.push_back(randomUnit(rng));
  const ConvexHull hull = makeConvexHull(points);
  EXPECT_EQ(hull.vertexCount(), 1000);
  EXPECT_EQ(hull.faceCount(), 1996);
  EXPECT_EQ(hull.edgeCount(), 2994);
  for (const ConvexFace& f : hull.faces) EXPECT_EQ(f.count, 3);
  expectValidHullOf(hull, points, 1e-9);
  EXPECT_EQ(hull.vertices, points);  // kept in input order
}

/// Near-degenerate clouds: the hull of the Minkowski difference of two boxes (64 points on
/// 26 or fewer planes, rounded by the rotations), lattices (many coplanar and collinear
/// points), thin slabs (sharp rims), and clouds far from the origin.
TEST(ConvexHull, NearDegenerateCloudsGiveValidHulls) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 40; ++trial) {
    SCOPED_TRACE(trial);
    const Matrix3d ra = trial % 4 == 0 ? Matrix3d::Identity() : randomRotation(rng);
    const Matrix3d rb = trial % 3 == 0 ? ra : randomRotation(rng);
    std::vector<Vector3d> minkowski;
    for (const Vector3d& x : boxCorners(Vector3d(0.6 + 0.3 * u(rng), 0.4, 0.5)))
      for (const Vector3d& y : boxCorners(Vector3d(0.5, 0.3 + 0.2 * u(rng), 0.5))) minkowski.push_back(rb * y - ra * x);
    const ConvexHull m = makeConvexHull(minkowski);
    expectValidHullOf(m, minkowski, 1e-9);

    const int n = 2 + trial % 5;
    std::vector<Vector3d> lattice;
    const Vector3d offset = (trial % 2) ? Vector3d(1e4, -3e3, 2e4) : Vector3d::Zero();
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        for (int k = 0; k < n; ++k) lattice.push_back(ra * Vector3d(i, j, k) + offset);
    std::shuffle(lattice.begin(), lattice.end(), rng);
    const ConvexHull l = makeConvexHull(lattice);
    expectValidHullOf(l, lattice, 1e-9);
    if (trial % 4 == 0) {  // an axis-aligned lattice at the origin: a cube
      EXPECT_EQ(l.vertexCount(), 8);
      EXPECT_EQ(l.faceCount(), 6);
    }

    std::vector<Vector3d> slab;
    for (int i = 0; i < 200; ++i) slab.push_back(rb * Vector3d(u(rng), u(rng), 1e-6 * u(rng)) + offset);
    const ConvexHull s = makeConvexHull(slab);
    expectValidHullOf(s, slab, 1e-9);
  }
}

TEST(ConvexHull, NoisyBoxWithALargerToleranceIsTheBox) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vector3d> points;
  for (int copy = 0; copy < 10; ++copy)
    for (const Vector3d& c : boxCorners(Vector3d(1, 2, 3)))
      points.push_back(c + 1e-5 * Vector3d(u(rng), u(rng), u(rng)));
  const ConvexHull fine = makeConvexHull(points);  // default tolerance: the noise is real
  expectValidHullOf(fine, points, 1e-9);
  EXPECT_GT(fine.vertexCount(), 8);
  const ConvexHull coarse = makeConvexHull(points, 1e-3);
  EXPECT_EQ(coarse.vertexCount(), 8);
  EXPECT_EQ(coarse.faceCount(), 6);
  EXPECT_EQ(coarse.edgeCount(), 12);
  EXPECT_EQ(checkConvexHull(coarse, 1e-4), "");
}

TEST(ConvexHull, RejectsDegenerateInput) {
  EXPECT_EQ(invalidArgumentMessage([] {
              const std::vector<Vector3d> p = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
              makeConvexHull(p);
            }),
            "makeConvexHull: needs at least 4 points, got 3");
  EXPECT_THAT(invalidArgumentMessage([] { makeConvexHull({}); }), HasSubstr("needs at least 4 points, got 0"));
  EXPECT_EQ(invalidArgumentMessage([] {
              std::vector<Vector3d> p = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
              p.emplace_back(std::nan(""), 0, 1);
              makeConvexHull(p);
            }),
            "makeConvexHull: point 7 has a non-finite coordinate (nan, 0, 1)");
  EXPECT_THAT(invalidArgumentMessage([] {
                const std::vector<Vector3d> p = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, HUGE_VAL}};
                makeConvexHull(p);
              }),
              HasSubstr("point 3 has a non-finite coordinate (0, 0, inf)"));
  // Sizes whose normals would overflow or underflow are refused as such, not as "no volume"
  // (a unit tetrahedron scaled to 1e200 m or 1e-200 m).
  const auto tetrahedron = [](double scale) {
    return std::vector<Vector3d>{{0, 0, 0}, {scale, 0, 0}, {0, scale, 0}, {0, 0, scale}};
  };
  EXPECT_EQ(invalidArgumentMessage([&] { makeConvexHull(tetrahedron(1e200)); }),
            "makeConvexHull: point 1 = (1e+200, 0, 0) must be within +-1e+50 m in each coordinate");
  EXPECT_EQ(invalidArgumentMessage([&] { makeConvexHull(tetrahedron(1e-200)); }),
            "makeConvexHull: the points' extent 1e-200 m must be at least 1e-50 m");
  EXPECT_EQ(makeConvexHull(tetrahedron(1e40)).vertexCount(), 4);
  EXPECT_EQ(makeConvexHull(tetrahedron(1e-40)).vertexCount(), 4);
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-1, 1);
  const Matrix3d r = randomRotation(rng);
  std::vector<Vector3d> coplanar, collinear, coincident;
  for (int i = 0; i < 50; ++i) {
    coplanar.push_back(r * Vector3d(u(rng), u(rng), 0) + Vector3d(5, 6, 7));
    collinear.push_back(r * Vector3d(u(rng), 0, 0));
    coincident.emplace_back(0.25, -1, 3);
  }
  EXPECT_THAT(invalidArgumentMessage([&] { makeConvexHull(coplanar); }),
              HasSubstr("points span no volume (all within"));
  EXPECT_THAT(invalidArgumentMessage([&] { makeConvexHull(coplanar); }), HasSubstr("of a plane"));
  EXPECT_THAT(invalidArgumentMessage([&] { makeConvexHull(collinear); }), HasSubstr("of a line"));
  EXPECT_THAT(invalidArgumentMessage([&] { makeConvexHull(coincident); }),
              HasSubstr("points span no volume (all coincident)"));
  // Duplicates of a valid tetrahedron are fine.
  std::vector<Vector3d> duplicated;
  for (int copy = 0; copy < 5; ++copy)
    for (const Vector3d& p : {Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0, 1, 0), Vector3d(0, 0, 1)})
      duplicated.push_back(p);
  const ConvexHull tetra = makeConvexHull(duplicated);
  EXPECT_EQ(tetra.vertexCount(), 4);
  EXPECT_EQ(tetra.faceCount(), 4);
  EXPECT_EQ(checkConvexHull(tetra), "");
}

// ----------------------------------------------------------------------- mass properties

/// The 12 triangles of a box (outward), optionally rotated and moved.
void boxMesh(const Vector3d& h, const Matrix3d& r, const Vector3d& t, std::vector<Vector3d>& vertices,
             std::vector<std::array<int, 3>>& triangles) {
  vertices = boxCorners(h);
  for (Vector3d& v : vertices) v = r * v + t;
  // Quads counter-clockwise seen from outside, vertex i at (+-x: bit 0, +-y: bit 1, +-z: bit 2).
  const int quads[6][4] = {{1, 3, 7, 5}, {0, 4, 6, 2}, {2, 6, 7, 3}, {0, 1, 5, 4}, {4, 5, 7, 6}, {0, 2, 3, 1}};
  triangles.clear();
  for (const auto& q : quads) {
    triangles.push_back({q[0], q[1], q[2]});
    triangles.push_back({q[0], q[2], q[3]});
  }
}

void expectSameMassProperties(const MassProperties& a, const MassProperties& b, double rel) {
  EXPECT_NEAR(a.mass, b.mass, rel * b.mass);
  EXPECT_NEAR(a.volume, b.volume, rel * b.volume);
  EXPECT_LE((a.centre - b.centre).norm(), rel * std::cbrt(b.volume));
  EXPECT_LE((a.inertia - b.inertia).norm(), rel * b.inertia.norm()) << a.inertia << "\nvs\n" << b.inertia;
}

TEST(MassProperties, BoxMeshAndBoxHullMatchTheClosedForm) {
  const Vector3d h(0.5, 1.5, 0.25);
  const double density = 700;
  const MassProperties exact = boxMassProperties(h, density);
  EXPECT_DOUBLE_EQ(exact.volume, 8 * 0.5 * 1.5 * 0.25);
  EXPECT_DOUBLE_EQ(exact.inertia(0, 0), exact.mass / 3 * (1.5 * 1.5 + 0.25 * 0.25));
  std::vector<Vector3d> vertices;
  std::vector<std::array<int, 3>> triangles;
  boxMesh(h, Matrix3d::Identity(), Vector3d::Zero(), vertices, triangles);
  ASSERT_EQ(triangles.size(), 12u);
  expectSameMassProperties(polyhedronMassProperties(vertices, triangles, density), exact, 1e-14);
  expectSameMassProperties(hullMassProperties(makeBoxHull(h), density), exact, 1e-14);
  expectSameMassProperties(hullMassProperties(makeConvexHull(vertices), density), exact, 1e-14);
}

TEST(MassProperties, RigidMotionMovesTheCentreAndRotatesTheInertia) {
  std::mt19937 rng(8);
  const Vector3d h(0.3, 0.7, 1.1);
  const MassProperties local = boxMassProperties(h, 1000);
  for (int trial = 0; trial < 10; ++trial) {
    const Matrix3d r = randomRotation(rng);
    const Vector3d t = (trial < 5 ? 2.0 : 1e4) * randomUnit(rng);
    std::vector<Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
    boxMesh(h, r, t, vertices, triangles);
    const MassProperties moved = polyhedronMassProperties(vertices, triangles, 1000);
    EXPECT_NEAR(moved.mass, local.mass, 1e-11 * local.mass);
    EXPECT_LE((moved.centre - t).norm(), 1e-12 * std::max(1.0, t.norm()));
    EXPECT_LE((moved.inertia - r * local.inertia * r.transpose()).norm(), 1e-10 * local.inertia.norm());
    EXPECT_LE((moved.inertia - moved.inertia.transpose()).norm(), 1e-12 * local.inertia.norm());
    // Same through a hull of the moved corners.
    const MassProperties viaHull = hullMassProperties(makeConvexHull(vertices), 1000);
    EXPECT_LE((viaHull.inertia - r * local.inertia * r.transpose()).norm(), 1e-10 * local.inertia.norm());
    EXPECT_LE((viaHull.centre - t).norm(), 1e-12 * std::max(1.0, t.norm()));
  }
}

TEST(MassProperties, TetrahedronMatchesItsClosedForm) {
  // For a tetrahedron with vertices v_i and volume V, the integral of x x^T is
  // V / 20 (sum v_i v_i^T + s s^T) with s = sum v_i; the centroid is s / 4.
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 20; ++trial) {
    std::array<Vector3d, 4> v;
    for (Vector3d& x : v) x = Vector3d(u(rng), u(rng), u(rng)) + Vector3d(3, 0, 0);
    double signedVolume = (v[1] - v[0]).cross(v[2] - v[0]).dot(v[3] - v[0]) / 6;
    if (std::abs(signedVolume) < 1e-3) continue;
    if (signedVolume < 0) {
      std::swap(v[1], v[2]);
      signedVolume = -signedVolume;
    }
    // v[3] is above (a, b, c) = (v0, v1, v2), so (v0, v2, v1) faces away from it.
    const std::vector<Vector3d> vertices(v.begin(), v.end());
    const std::vector<std::array<int, 3>> triangles = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {2, 0, 3}};
    const double density = 2.5;
    const MassProperties mp = polyhedronMassProperties(vertices, triangles, density);
    const Vector3d s = v[0] + v[1] + v[2] + v[3];
    Matrix3d second = s * s.transpose();
    for (const Vector3d& x : v) second += x * x.transpose();
    second *= signedVolume / 20;
    const Vector3d c = s / 4;
    const Matrix3d central = second - signedVolume * c * c.transpose();
    const Matrix3d inertia = density * (central.trace() * Matrix3d::Identity() - central);
    EXPECT_NEAR(mp.volume, signedVolume, 1e-13);
    EXPECT_NEAR(mp.mass, density * signedVolume, 1e-13);
    EXPECT_LE((mp.centre - c).norm(), 1e-13);
    EXPECT_LE((mp.inertia - inertia).norm(), 1e-12 * inertia.norm());
    // The hull of the four points agrees.
    expectSameMassProperties(hullMassProperties(makeConvexHull(vertices), density), mp, 1e-12);
  }
  // The unit corner tetrahedron by hand: V = 1/6, I_xx = V (1/10 - 1/16) * 2 = 1/80,
  // I_xy = 1/480 about the centroid (1/4, 1/4, 1/4).
  const std::vector<Vector3d> corner = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const std::vector<std::array<int, 3>> faces = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {2, 0, 3}};
  const MassProperties unit = polyhedronMassProperties(corner, faces, 1);
  EXPECT_NEAR(unit.volume, 1.0 / 6, 1e-15);
  EXPECT_TRUE(unit.centre.isApprox(Vector3d::Constant(0.25), 1e-14));
  EXPECT_NEAR(unit.inertia(0, 0), 1.0 / 80, 1e-15);
  EXPECT_NEAR(unit.inertia(0, 1), 1.0 / 480, 1e-15);
  EXPECT_NEAR(unit.inertia(1, 2), 1.0 / 480, 1e-15);
}

TEST(MassProperties, SphereHullsConvergeToTheSphere) {
  const double radius = 0.8, density = 1100;
  const MassProperties exact = sphereMassProperties(radius, density);
  EXPECT_DOUBLE_EQ(exact.mass, density * 4.0 / 3.0 * std::numbers::pi * std::pow(radius, 3));
  EXPECT_DOUBLE_EQ(exact.inertia(1, 1), 0.4 * exact.mass * radius * radius);
  double previousMassError = 1, previousInertiaError = 1;
  for (const int count : {50, 200, 800, 3200}) {
    std::vector<Vector3d> points = fibonacciSphere(count);
    for (Vector3d& p : points) p *= radius;
    const ConvexHull hull = makeConvexHull(points);
    ASSERT_EQ(hull.vertexCount(), count);
    const MassProperties mp = hullMassProperties(hull, density);
    const double massError = std::abs(mp.mass - exact.mass) / exact.mass;
    const double inertiaError = (mp.inertia - exact.inertia).norm() / exact.inertia.norm();
    EXPECT_LT(mp.mass, exact.mass);  // inscribed
    EXPECT_LT(massError, 0.6 * previousMassError) << count;
    EXPECT_LT(inertiaError, 0.6 * previousInertiaError) << count;
    EXPECT_LT(mp.centre.norm(), 1e-2 * radius);
    previousMassError = massError;
    previousInertiaError = inertiaError;
  }
  EXPECT_LT(previousMassError, 2e-3);
  EXPECT_LT(previousInertiaError, 4e-3);
}

/// Points on a capsule's surface (along y): rings on the cylinder's ends and on the caps.
std::vector<Vector3d> capsuleSurface(double r, double h, int segments, int rings) {
  std::vector<Vector3d> points;
  for (const double side : {1.0, -1.0}) {
    for (int i = 0; i < rings; ++i) {  // latitude 0 (the cylinder's end) up to below the pole
      const double lat = 0.5 * std::numbers::pi * i / rings;
      for (int j = 0; j < segments; ++j) {
        const double lon = 2 * std::numbers::pi * (j + 0.5 * (i % 2)) / segments;
        points.emplace_back(r * std::cos(lat) * std::cos(lon), side * (h + r * std::sin(lat)),
                            r * std::cos(lat) * std::sin(lon));
      }
    }
    points.emplace_back(0, side * (h + r), 0);
  }
  return points;
}

TEST(MassProperties, CapsuleMatchesAFineHullIncludingTheHemisphereShift) {
  const double r = 0.4, h = 0.6, density = 900;
  const MassProperties exact = capsuleMassProperties(r, h, density);
  EXPECT_NEAR(exact.volume, std::numbers::pi * r * r * (2 * h + 4.0 / 3.0 * r), 1e-15);
  EXPECT_TRUE(exact.centre.isZero(0));
  const ConvexHull hull = makeConvexHull(capsuleSurface(r, h, 64, 16));
  EXPECT_EQ(checkConvexHull(hull), "");
  const MassProperties approx = hullMassProperties(hull, density);
  const double tol = 5e-3;  // the inscribed polyhedron's shortfall
  EXPECT_NEAR(approx.mass, exact.mass, tol * exact.mass);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(approx.inertia(k, k), exact.inertia(k, k), tol * exact.inertia(k, k)) << k;
  EXPECT_LT((approx.inertia - Matrix3d(approx.inertia.diagonal().asDiagonal())).norm(), 1e-6 * exact.inertia.norm());
  // The test can tell: leaving out the 3r/8 shift of the caps' centres of mass (treating
  // each cap's moment about its own centre as 2/5 m r^2 about its base) is off by far more.
  const double sphereMass = density * 4.0 / 3.0 * std::numbers::pi * r * r * r;
  const double withoutShift = exact.inertia(0, 0) - sphereMass * 0.75 * h * r;
  EXPECT_GT(std::abs(approx.inertia(0, 0) - withoutShift), 10 * tol * exact.inertia(0, 0));
  // halfHeight 0 is a sphere.
  expectSameMassProperties(capsuleMassProperties(r, 0, density), sphereMassProperties(r, density), 1e-15);
}

TEST(MassProperties, RejectsBadInput) {
  EXPECT_EQ(invalidArgumentMessage([] { sphereMassProperties(-1, 1000); }),
            "sphereMassProperties: radius must be finite and > 0, got -1");
  EXPECT_EQ(invalidArgumentMessage([] { sphereMassProperties(1, 0); }),
            "sphereMassProperties: density must be finite and > 0, got 0");
  EXPECT_EQ(invalidArgumentMessage([] { boxMassProperties(Vector3d(1, 1, std::nan("")), 1); }),
            "boxMassProperties: halfExtents.z must be finite and > 0, got nan");
  EXPECT_EQ(invalidArgumentMessage([] { capsuleMassProperties(0.5, -0.25, 1); }),
            "capsuleMassProperties: halfHeight must be finite and >= 0, got -0.25");
  EXPECT_THAT(invalidArgumentMessage([] { capsuleMassProperties(0, 1, 1); }), HasSubstr("radius must be"));
  EXPECT_THAT(invalidArgumentMessage([] { capsuleMassProperties(1, 1, HUGE_VAL); }),
              HasSubstr("density must be finite and > 0, got inf"));
  EXPECT_THAT(invalidArgumentMessage([] { hullMassProperties(makeBoxHull(Vector3d(1, 1, 1)), -2); }),
              HasSubstr("hullMassProperties: density must be finite and > 0, got -2"));

  std::vector<Vector3d> vertices;
  std::vector<std::array<int, 3>> triangles;
  boxMesh(Vector3d(0.5, 0.5, 0.5), Matrix3d::Identity(), Vector3d::Zero(), vertices, triangles);
  std::vector<std::array<int, 3>> insideOut = triangles;
  for (auto& t : insideOut) std::swap(t[1], t[2]);
  EXPECT_EQ(invalidArgumentMessage([&] { polyhedronMassProperties(vertices, insideOut, 1); }),
            "polyhedronMassProperties: mesh encloses no positive volume (got -1 m^3): open or inside out?");
  EXPECT_THAT(invalidArgumentMessage([&] { polyhedronMassProperties(vertices, {}, 1); }),
              HasSubstr("no positive volume (got 0 m^3)"));
  std::vector<std::array<int, 3>> badIndex = triangles;
  badIndex[5][2] = 8;
  EXPECT_EQ(invalidArgumentMessage([&] { polyhedronMassProperties(vertices, badIndex, 1); }),
            "polyhedronMassProperties: triangle 5 has vertex index 8, out of range [0, 8)");
  badIndex[5][2] = -1;
  EXPECT_THAT(invalidArgumentMessage([&] { polyhedronMassProperties(vertices, badIndex, 1); }),
              HasSubstr("triangle 5 has vertex index -1"));
  vertices[3].y() = std::nan("");
  EXPECT_THAT(invalidArgumentMessage([&] { polyhedronMassProperties(vertices, triangles, 1); }),
              HasSubstr("vertex 3 has a non-finite coordinate"));
  EXPECT_THAT(invalidArgumentMessage([&] { polyhedronMassProperties({}, {}, std::nan("")); }),
              HasSubstr("density must be finite and > 0, got nan"));
}

}  // namespace
}  // namespace weft
