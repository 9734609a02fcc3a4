// tests/test_collide_bvh.cpp — the triangle BVH (weft/collide/bvh.hpp) and its geometry
// (weft/collide/geometry.hpp): exact predicates against integer arithmetic, the
// triangle-triangle test on constructed degenerate cases and against a floating-point
// reference, closest points against a reference, every BVH query against brute force on
// random, sphere, cloth and degenerate meshes, refit containment, identical results for
// 1 and 2 threads, and no allocation once warmed up.
//
// This program counts global operator new calls (tests/support/alloc_counter.hpp, linked in)
// to check that warmed-up builds, refits and queries allocate nothing; the BVH keeps its
// buffers in std::vector.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "collide/bvh.hpp"
#include "collide/geometry.hpp"
#include "support/alloc_counter.hpp"
#include "support/test_support.hpp"
#include "weft/collide/self_collision.hpp"
#include "weft/collide/shapes.hpp"

namespace weft::test {
namespace {

using V = Vec3<double>;

// ---------------------------------------------------------------------------------------
// Meshes
// ---------------------------------------------------------------------------------------

template <class S>
struct Mesh {
  Vec3Array<S> x;
  Triangles triangles;
  std::string name;
};

template <class S>
Mesh<S> fromTriangleMesh(const TriangleMesh& m, std::string name) {
  return {meshPositions<S>(m), meshTriangles(m), std::move(name)};
}

/// n triangles of size ~`size` at random places in the unit cube, each with its own
/// corners, plus every fifth one reusing a corner of the previous (shared vertices).
template <class S>
Mesh<S> randomSoup(Index n, double size, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1), d(-size, size);
  TriangleMesh m;
  for (Index t = 0; t < n; ++t) {
    const Vec3d c{u(rng), u(rng), u(rng)};
    const Index first = static_cast<Index>(m.vertices.size());
    for (int k = 0; k < 3; ++k) m.vertices.push_back({c.x + d(rng), c.y + d(rng), c.z + d(rng)});
    if (t % 5 == 4) {
      m.triangles.push_back({first - 1, first + 1, first + 2});  // shares a corner with triangle t - 1
    } else {
      m.triangles.push_back({first, first + 1, first + 2});
    }
  }
  return fromTriangleMesh<S>(m, "soup" + std::to_string(seed));
}

/// A size x size cloth grid (weft::addClothGrid), crumpled by noise of `noise` spacings.
template <class S>
Mesh<S> crumpledCloth(Index size, double noise, std::uint32_t seed) {
  ModelBuilder<S> builder;
  ClothGridSpec spec;
  spec.width = size;
  spec.height = size;
  spec.spacing = 1.0 / (size - 1);
  addClothGrid(builder, spec);
  auto built = builder.build();
  addNoise<S>(built.state.x, noise * spec.spacing, seed);
  return {built.state.x, built.model.triangles(), "cloth" + std::to_string(size)};
}

/// Degenerate configurations in one mesh: duplicated triangles (same corners, and copies
/// of the corners), coplanar overlapping and touching triangles, slivers, zero-area
/// (collinear and single-point) triangles, a vertex exactly on a face, crossing edges.
template <class S>
Mesh<S> degenerateMesh() {
  TriangleMesh m;
  auto tri = [&](Vec3d a, Vec3d b, Vec3d c) {
    const Index f = static_cast<Index>(m.vertices.size());
    m.vertices.insert(m.vertices.end(), {a, b, c});
    m.triangles.push_back({f, f + 1, f + 2});
    return f;
  };
  // A base triangle, the same corners again, and a copy with its own corners.
  const Index base = tri({0, 0, 0}, {1, 0, 0}, {0, 1, 0});
  m.triangles.push_back({base, base + 1, base + 2});
  m.triangles.push_back({base + 2, base + 1, base});  // reversed winding
  tri({0, 0, 0}, {1, 0, 0}, {0, 1, 0});
  // Coplanar overlapping, coplanar touching at a vertex, coplanar sharing an edge, coplanar disjoint.
  tri({0.25, 0.25, 0}, {1.25, 0.25, 0}, {0.25, 1.25, 0});
  tri({1, 0, 0}, {2, 0, 0}, {1.5, -1, 0});
  tri({1, 0, 0}, {0, 1, 0}, {1, 1, 0});
  tri({3, 3, 0}, {4, 3, 0}, {3, 4, 0});
  // Slivers: one through the base, one just above its plane.
  tri({0.1, 0.1, -0.5}, {0.1, 0.1, 0.5}, {0.1 + 1e-9, 0.1, 0.5});
  tri({-1, 0.5, 1e-7}, {2, 0.5, 1e-7}, {2, 0.5 + 1e-12, 1e-7});
  // Zero-area: collinear corners piercing the base, collinear beside it, a point on it, a point off it.
  tri({0.2, 0.2, -1}, {0.2, 0.2, 1}, {0.2, 0.2, 0.5});
  tri({5, 5, -1}, {5, 5, 1}, {5, 5, 0});
  tri({0.3, 0.3, 0}, {0.3, 0.3, 0}, {0.3, 0.3, 0});
  tri({0.3, 0.3, 0.25}, {0.3, 0.3, 0.25}, {0.3, 0.3, 0.25});
  // A vertex exactly on the base's face (perpendicular triangle), an edge crossing its edge.
  tri({0.5, 0.25, 0}, {0.5, 0.25, 1}, {0.75, 0.25, 1});
  tri({0.5, -0.5, 0}, {0.5, 0.5, 0}, {0.5, 0, 1});
  // Collinear overlapping segments (two zero-area triangles on one line), and one on the line further out.
  tri({10, 0, 0}, {12, 0, 0}, {11, 0, 0});
  tri({11.5, 0, 0}, {13, 0, 0}, {14, 0, 0});
  tri({20, 0, 0}, {21, 0, 0}, {22, 0, 0});
  // A small cluster of random triangles around the base for the BVH's internal nodes.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.5, 1.5), d(-0.3, 0.3);
  for (int t = 0; t < 60; ++t) {
    const Vec3d c{u(rng), u(rng), 0.25 * u(rng)};
    tri(c, {c.x + d(rng), c.y + d(rng), c.z + d(rng)}, {c.x + d(rng), c.y + d(rng), c.z});
  }
  return fromTriangleMesh<S>(m, "degenerate");
}

template <class S>
V corner(const Mesh<S>& m, Index t, int k) {
  const Index i = k == 0 ? m.triangles.a[t] : (k == 1 ? m.triangles.b[t] : m.triangles.c[t]);
  return V(m.x(i, 0), m.x(i, 1), m.x(i, 2));
}

template <class S>
Aabb<S> triangleBox(const Vec3Array<S>& x, const Triangles& tr, Index t, S margin) {
  Aabb<S> b;
  const Index c[3] = {tr.a[t], tr.b[t], tr.c[t]};
  for (int k = 0; k < 3; ++k) {
    b.lo[k] = std::min({x(c[0], k), x(c[1], k), x(c[2], k)}) - margin;
    b.hi[k] = std::max({x(c[0], k), x(c[1], k), x(c[2], k)}) + margin;
  }
  return b;
}

bool shareVertex(const Triangles& tr, Index i, Index j) {
  const Index a[3] = {tr.a[i], tr.b[i], tr.c[i]};
  const Index b[3] = {tr.a[j], tr.b[j], tr.c[j]};
  for (Index p : a)
    for (Index q : b)
      if (p == q) return true;
  return false;
}

template <class S>
bool intersect(const Mesh<S>& m, Index i, const Mesh<S>& n, Index j) {
  return trianglesIntersect(corner(m, i, 0), corner(m, i, 1), corner(m, i, 2), corner(n, j, 0), corner(n, j, 1),
                            corner(n, j, 2));
}

// ---------------------------------------------------------------------------------------
// Brute-force references
// ---------------------------------------------------------------------------------------

template <class S>
std::vector<TrianglePair> bruteOverlapping(const Mesh<S>& m, S mm, const Mesh<S>& n, S nm, bool exact) {
  std::vector<TrianglePair> pairs;
  for (Index i = 0; i < m.triangles.count(); ++i) {
    const Aabb<S> bi = triangleBox(m.x, m.triangles, i, mm);
    for (Index j = 0; j < n.triangles.count(); ++j) {
      if (!bi.overlaps(triangleBox(n.x, n.triangles, j, nm))) continue;
      if (exact && !intersect(m, i, n, j)) continue;
      pairs.push_back({i, j});
    }
  }
  return pairs;
}

template <class S>
std::vector<TrianglePair> bruteSelf(const Mesh<S>& m, S margin, bool exact) {
  std::vector<TrianglePair> pairs;
  for (Index i = 0; i < m.triangles.count(); ++i) {
    const Aabb<S> bi = triangleBox(m.x, m.triangles, i, margin);
    for (Index j = i + 1; j < m.triangles.count(); ++j) {
      if (shareVertex(m.triangles, i, j) || !bi.overlaps(triangleBox(m.x, m.triangles, j, margin))) continue;
      if (exact && !intersect(m, i, m, j)) continue;
      pairs.push_back({i, j});
    }
  }
  return pairs;
}

template <class S>
std::optional<ClosestTriangle<S>> bruteClosest(const Mesh<S>& m, const Vec3<S>& p, S radius) {
  std::optional<ClosestTriangle<S>> best;
  for (Index t = 0; t < m.triangles.count(); ++t) {
    const auto c = [&](Index i) { return Vec3<S>(m.x(i, 0), m.x(i, 1), m.x(i, 2)); };
    const Vec3<S> q = closestPointOnTriangle<S>(p, c(m.triangles.a[t]), c(m.triangles.b[t]), c(m.triangles.c[t]));
    const S d2 = (p - q).squaredNorm();
    if (d2 <= radius * radius && (!best || d2 < best->squaredDistance)) best = ClosestTriangle<S>{t, q, d2};
  }
  return best;
}

// ---------------------------------------------------------------------------------------
// Structural checks
// ---------------------------------------------------------------------------------------

/// Every leaf box is its triangle's box (exactly) and every node's child box is the union
/// of that child's boxes (exactly, hence tight and containing); every slot appears once.
template <class S>
void expectConsistent(const TriangleBvh<S>& bvh, const Vec3Array<S>& x, const Triangles& tr) {
  const Index n = tr.count();
  ASSERT_EQ(bvh.triangleCount(), n);
  if (n == 0) return;
  std::vector<int> seen(static_cast<size_t>(n), 0);
  for (Index s = 0; s < n; ++s) {
    const Index t = bvh.slotTriangle(s);
    ASSERT_GE(t, 0);
    ASSERT_LT(t, n);
    ++seen[static_cast<size_t>(t)];
    const Aabb<S> expected = triangleBox(x, tr, t, bvh.margin());
    const Aabb<S>& box = bvh.leafBox(s);
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(box.lo[k], expected.lo[k]) << "slot " << s;
      ASSERT_EQ(box.hi[k], expected.hi[k]) << "slot " << s;
    }
  }
  for (int c : seen) ASSERT_EQ(c, 1);
  const auto& nodes = bvh.nodes();
  ASSERT_EQ(static_cast<Index>(nodes.size()), n - 1);
  std::vector<int> leafSeen(static_cast<size_t>(n), 0), nodeSeen(nodes.size(), 0);
  for (size_t q = 0; q < nodes.size(); ++q) {
    for (int c = 0; c < 2; ++c) {
      const Index ref = nodes[q].child[c];
      Aabb<S> expected;
      if (ref < 0) {
        ++leafSeen[static_cast<size_t>(~ref)];
        expected = bvh.leafBox(~ref);
      } else {
        ASSERT_GT(ref, static_cast<Index>(q)) << "pre-order: children after parents";
        ++nodeSeen[static_cast<size_t>(ref)];
        const auto& ch = nodes[static_cast<size_t>(ref)];
        for (int k = 0; k < 3; ++k) {
          expected.lo[k] = std::min(ch.box[0].lo[k], ch.box[1].lo[k]);
          expected.hi[k] = std::max(ch.box[0].hi[k], ch.box[1].hi[k]);
        }
      }
      for (int k = 0; k < 3; ++k) {
        ASSERT_EQ(nodes[q].box[c].lo[k], expected.lo[k]) << "node " << q << " child " << c;
        ASSERT_EQ(nodes[q].box[c].hi[k], expected.hi[k]) << "node " << q << " child " << c;
      }
      // Containment, explicitly: the child's own boxes (or the leaf's triangle) lie inside.
      if (ref >= 0) {
        ASSERT_TRUE(nodes[q].box[c].contains(nodes[static_cast<size_t>(ref)].box[0]));
        ASSERT_TRUE(nodes[q].box[c].contains(nodes[static_cast<size_t>(ref)].box[1]));
      } else {
        ASSERT_TRUE(nodes[q].box[c].contains(triangleBox(x, tr, bvh.slotTriangle(~ref), S(0))));
      }
    }
    if (nodes[q].child[0] >= 0) {
      EXPECT_EQ(nodes[q].child[0], static_cast<Index>(q) + 1) << "left child follows";
    }
  }
  for (int c : leafSeen) ASSERT_EQ(c, 1);
  for (size_t q = 1; q < nodeSeen.size(); ++q) ASSERT_EQ(nodeSeen[q], 1);
  if (n >= 2) {
    const int bound = 30 + static_cast<int>(std::ceil(std::log2(static_cast<double>(n))));
    EXPECT_LE(bvh.depth(), bound);
  }
}

/// The two BVHs have the same tree, boxes and slots, bit for bit.
template <class S>
void expectIdentical(const TriangleBvh<S>& a, const TriangleBvh<S>& b) {
  ASSERT_EQ(a.triangleCount(), b.triangleCount());
  ASSERT_EQ(a.nodes().size(), b.nodes().size());
  for (size_t q = 0; q < a.nodes().size(); ++q) {
    const auto& p = a.nodes()[q];
    const auto& r = b.nodes()[q];
    for (int c = 0; c < 2; ++c) {
      ASSERT_EQ(p.child[c], r.child[c]) << "node " << q;
      for (int k = 0; k < 3; ++k) {
        ASSERT_EQ(p.box[c].lo[k], r.box[c].lo[k]) << "node " << q;
        ASSERT_EQ(p.box[c].hi[k], r.box[c].hi[k]) << "node " << q;
      }
    }
  }
  for (Index s = 0; s < a.triangleCount(); ++s) {
    ASSERT_EQ(a.slotTriangle(s), b.slotTriangle(s));
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(a.leafBox(s).lo[k], b.leafBox(s).lo[k]);
      ASSERT_EQ(a.leafBox(s).hi[k], b.leafBox(s).hi[k]);
    }
  }
  EXPECT_EQ(a.depth(), b.depth());
}

// ---------------------------------------------------------------------------------------
// Predicates
// ---------------------------------------------------------------------------------------

using Int = __int128;

int sign(Int v) { return (v > 0) - (v < 0); }

TEST(Geometry, Orient3dAndOrient2dMatchExactIntegerArithmetic) {
  // Integer coordinates up to 2^40, scaled by 2^-20 (exact in double): the products do not
  // fit in 53 bits, so near-zero determinants take the expansion path.
  std::mt19937_64 rng(42);
  std::uniform_int_distribution<std::int64_t> coord(-(std::int64_t(1) << 40), std::int64_t(1) << 40);
  std::uniform_int_distribution<std::int64_t> small(-3, 3);
  const double unit = std::ldexp(1.0, -20);
  int zeros = 0;
  for (int it = 0; it < 20000; ++it) {
    std::int64_t p[4][3];
    for (auto& q : p)
      for (auto& c : q) c = coord(rng);
    if (it % 2 == 1) {  // d = a + s (b - a) + t (c - a) + tiny: coplanar or within a few units
      const std::int64_t s = small(rng), t = small(rng);
      for (int k = 0; k < 3; ++k) {
        const std::int64_t base = p[0][k] / 8, e1 = (p[1][k] - p[0][k]) / 8, e2 = (p[2][k] - p[0][k]) / 8;
        p[0][k] = base;
        p[1][k] = base + e1;
        p[2][k] = base + e2;
        p[3][k] = base + s * e1 + t * e2 + (it % 4 == 1 ? 0 : small(rng));
      }
    }
    Int e[3][3];
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) e[r][k] = Int(p[r + 1][k]) - Int(p[0][k]);
    const Int det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                    e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                    e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    V v[4];
    for (int r = 0; r < 4; ++r) v[r] = V(p[r][0] * unit, p[r][1] * unit, p[r][2] * unit);
    ASSERT_EQ(orient3d(v[0], v[1], v[2], v[3]), sign(det)) << "iteration " << it;
    zeros += det == 0;
    const Int det2 = e[0][0] * e[1][1] - e[0][1] * e[1][0];
    ASSERT_EQ(orient2d(v[0][0], v[0][1], v[1][0], v[1][1], v[2][0], v[2][1]), sign(det2)) << "iteration " << it;
  }
  EXPECT_GT(zeros, 1000);  // the coplanar constructions really were coplanar
  // A classic near-degenerate case: points on the line y = x near 0.5, one ulp apart.
  const double h = 0.5, u = std::ldexp(1.0, -53);
  EXPECT_EQ(orient2d(h, h, 12, 12, 24, 24), 0);
  EXPECT_EQ(orient2d(h + u, h, 12, 12, 24, 24), -1);
  EXPECT_EQ(orient2d(h, h + u, 12, 12, 24, 24), 1);
}

struct Tri {
  V a, b, c;
};

bool intersects(const Tri& s, const Tri& t) {
  const bool r = trianglesIntersect(s.a, s.b, s.c, t.a, t.b, t.c);
  // Symmetric, and independent of the corner order.
  EXPECT_EQ(r, trianglesIntersect(t.a, t.b, t.c, s.a, s.b, s.c));
  EXPECT_EQ(r, trianglesIntersect(s.b, s.c, s.a, t.c, t.a, t.b));
  EXPECT_EQ(r, trianglesIntersect(s.c, s.b, s.a, t.a, t.c, t.b));
  return r;
}

TEST(Geometry, TrianglesIntersectOnDegenerateConfigurations) {
  const Tri base{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const double tiny = std::ldexp(1.0, -40);
  EXPECT_TRUE(intersects(base, base)) << "identical";
  EXPECT_TRUE(intersects(base, {{0.25, 0.25, 0}, {1.25, 0.25, 0}, {0.25, 1.25, 0}})) << "coplanar overlapping";
  EXPECT_FALSE(intersects(base, {{1, 1, 0}, {2, 1, 0}, {1, 2, 0}})) << "coplanar disjoint";
  EXPECT_TRUE(intersects(base, {{1, 0, 0}, {2, 0, 0}, {1.5, -1, 0}})) << "coplanar, touching at a vertex";
  EXPECT_TRUE(intersects(base, {{1, 0, 0}, {0, 1, 0}, {1, 1, 0}})) << "coplanar, sharing an edge";
  EXPECT_FALSE(intersects(base, {{1, tiny, 0}, {tiny, 1, 0}, {1, 1, 0}})) << "coplanar, an edge just apart";
  EXPECT_TRUE(intersects(base, {{0.1, 0.1, 0}, {0.2, 0.1, 0}, {0.1, 0.2, 0}})) << "coplanar, one inside the other";
  EXPECT_TRUE(intersects({{0.1, 0.1, 0}, {0.2, 0.1, 0}, {0.1, 0.2, 0}}, base)) << "coplanar, containing";
  EXPECT_FALSE(intersects(base, {{0, 0, tiny}, {1, 0, tiny}, {0, 1, tiny}})) << "parallel planes";
  EXPECT_TRUE(intersects(base, {{0.25, 0.25, 0}, {0.25, 0.25, 1}, {0.5, 0.25, 1}})) << "a vertex on the face";
  EXPECT_FALSE(intersects(base, {{0.25, 0.25, tiny}, {0.25, 0.25, 1}, {0.5, 0.25, 1}})) << "a vertex just above";
  EXPECT_TRUE(intersects(base, {{0.5, 0.5, 0}, {0.5, 0.5, 1}, {1, 1, 1}})) << "a vertex on the hypotenuse";
  EXPECT_TRUE(intersects(base, {{0.5, -0.5, 0}, {0.5, 0.5, 0}, {0.5, 0, 1}})) << "an edge crossing an edge";
  EXPECT_TRUE(intersects(base, {{0.2, 0.2, -1}, {0.3, 0.2, 1}, {0.2, 0.3, 1}})) << "piercing";
  EXPECT_FALSE(intersects(base, {{0.9, 0.9, -1}, {1, 0.9, 1}, {0.9, 1, 1}})) << "passing beside";
  EXPECT_TRUE(intersects(base, {{-1, 0.5, 0}, {2, 0.5, 0}, {0.5, 0.5, 1}})) << "an edge across the face";
  // Zero-area triangles: segments and points.
  EXPECT_TRUE(intersects(base, {{0.2, 0.2, -1}, {0.2, 0.2, 1}, {0.2, 0.2, 0.5}})) << "segment piercing";
  EXPECT_FALSE(intersects(base, {{0.7, 0.7, -1}, {0.7, 0.7, 1}, {0.7, 0.7, 0}})) << "segment beside";
  EXPECT_TRUE(intersects(base, {{-1, 0.5, 0}, {2, 0.5, 0}, {0.5, 0.5, 0}})) << "coplanar segment across";
  EXPECT_FALSE(intersects(base, {{-1, 2, 0}, {2, 2, 0}, {0.5, 2, 0}})) << "coplanar segment outside";
  EXPECT_TRUE(intersects(base, {{0.3, 0.3, 0}, {0.3, 0.3, 0}, {0.3, 0.3, 0}})) << "point on the face";
  EXPECT_TRUE(intersects(base, {{1, 0, 0}, {1, 0, 0}, {1, 0, 0}})) << "point at a corner";
  EXPECT_FALSE(intersects(base, {{0.3, 0.3, tiny}, {0.3, 0.3, tiny}, {0.3, 0.3, tiny}})) << "point off the face";
  const Tri seg{{10, 0, 0}, {12, 0, 0}, {11, 0, 0}};
  EXPECT_TRUE(intersects(seg, {{11.5, 0, 0}, {13, 0, 0}, {14, 0, 0}})) << "collinear overlapping segments";
  EXPECT_TRUE(intersects(seg, {{12, 0, 0}, {13, 0, 0}, {14, 0, 0}})) << "collinear segments touching";
  EXPECT_FALSE(intersects(seg, {{12 + 1e-9, 0, 0}, {13, 0, 0}, {14, 0, 0}})) << "collinear segments apart";
  EXPECT_TRUE(intersects(seg, {{11, -1, 0}, {11, 1, 0}, {11, 0.5, 0}})) << "coplanar crossing segments";
  EXPECT_FALSE(intersects(seg, {{11, -1, tiny}, {11, 1, tiny}, {11, 0.5, tiny}})) << "skew segments";
  EXPECT_TRUE(intersects(seg, {{11, 0, 0}, {11, 0, 0}, {11, 0, 0}})) << "point on a segment";
  EXPECT_FALSE(intersects(seg, {{11, tiny, 0}, {11, tiny, 0}, {11, tiny, 0}})) << "point beside a segment";
  EXPECT_TRUE(intersects({{3, 3, 3}, {3, 3, 3}, {3, 3, 3}}, {{3, 3, 3}, {3, 3, 3}, {3, 3, 3}})) << "equal points";
  EXPECT_FALSE(intersects({{3, 3, 3}, {3, 3, 3}, {3, 3, 3}}, {{3, 3, 4}, {3, 3, 4}, {3, 3, 4}})) << "distinct points";
  // Slivers: a needle through the face, a needle one ulp-ish above it.
  EXPECT_TRUE(intersects(base, {{0.1, 0.1, -0.5}, {0.1, 0.1, 0.5}, {0.1 + 1e-12, 0.1, 0.5}})) << "sliver piercing";
  EXPECT_FALSE(intersects(base, {{-1, 0.5, tiny}, {2, 0.5, tiny}, {2, 0.5 + 1e-12, tiny}})) << "sliver above";
  // Coplanar within rounding only: b2 = the midpoint of an edge computed in floating point.
  const V m = (base.b + base.c) / 2;
  EXPECT_TRUE(intersects(base, {m, {2, 2, 1}, {2, 2, -1}})) << "touching at an edge midpoint";
}

/// Reference for generic (non-degenerate) pairs in long double: Möller's interval test. Returns
/// 1 / 0 for intersecting / not, or -1 when the configuration is within `tol` of a change.
int referenceIntersect(const Tri& s, const Tri& t, long double tol) {
  using L = long double;
  using VL = Eigen::Matrix<L, 3, 1>;
  const VL p[3] = {s.a.cast<L>(), s.b.cast<L>(), s.c.cast<L>()};
  const VL q[3] = {t.a.cast<L>(), t.b.cast<L>(), t.c.cast<L>()};
  const VL n1 = (p[1] - p[0]).cross(p[2] - p[0]).normalized();
  const VL n2 = (q[1] - q[0]).cross(q[2] - q[0]).normalized();
  L d1[3], d2[3];
  for (int k = 0; k < 3; ++k) {
    d1[k] = n2.dot(p[k] - q[0]);
    d2[k] = n1.dot(q[k] - p[0]);
    if (std::abs(d1[k]) < tol || std::abs(d2[k]) < tol) return -1;
  }
  const auto sameSide = [](const L* d) {
    return (d[0] > 0 && d[1] > 0 && d[2] > 0) || (d[0] < 0 && d[1] < 0 && d[2] < 0);
  };
  if (sameSide(d1) || sameSide(d2)) return 0;
  const VL dir = n1.cross(n2);
  if (dir.norm() < 1e-6L) return -1;  // nearly parallel planes
  const auto interval = [&](const VL* v, const L* d, L& lo, L& hi) {
    lo = std::numeric_limits<L>::infinity();
    hi = -lo;
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3;
      if ((d[i] > 0) != (d[j] > 0)) {
        const VL x = v[i] + (v[j] - v[i]) * (d[i] / (d[i] - d[j]));
        const L proj = dir.dot(x);
        lo = std::min(lo, proj);
        hi = std::max(hi, proj);
      }
    }
  };
  L lo1, hi1, lo2, hi2;
  interval(p, d1, lo1, hi1);
  interval(q, d2, lo2, hi2);
  const L gap = std::max(lo1, lo2) - std::min(hi1, hi2);
  if (std::abs(gap) < tol) return -1;
  return gap < 0 ? 1 : 0;
}

TEST(Geometry, TrianglesIntersectMatchesAReferenceOnGenericPairs) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  int checked = 0, hits = 0;
  for (int it = 0; it < 20000; ++it) {
    Tri s{{u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}};
    Tri t{{u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}};
    const int ref = referenceIntersect(s, t, 1e-9L);
    if (ref < 0) continue;
    ++checked;
    hits += ref;
    ASSERT_EQ(trianglesIntersect(s.a, s.b, s.c, t.a, t.b, t.c), ref == 1) << "pair " << it;
  }
  EXPECT_GT(checked, 19000);
  EXPECT_GT(hits, 2000);
  EXPECT_LT(hits, checked - 2000);
}

// ---------------------------------------------------------------------------------------
// Closest point
// ---------------------------------------------------------------------------------------

template <class S>
class BvhTyped : public ::testing::Test {};
TYPED_TEST_SUITE(BvhTyped, ScalarTypes);

/// Distance from p to the closed triangle, in long double: the plane projection when it is
/// inside, else the nearest of the three edges.
long double referenceDistance(const V& p, const V& a, const V& b, const V& c) {
  using L = long double;
  using VL = Eigen::Matrix<L, 3, 1>;
  const VL P = p.cast<L>(), A = a.cast<L>(), B = b.cast<L>(), C = c.cast<L>();
  const auto seg = [&](const VL& x, const VL& y) {
    const VL d = y - x;
    const L len2 = d.squaredNorm();
    L t = len2 > 0 ? (P - x).dot(d) / len2 : 0;
    t = std::clamp<L>(t, 0, 1);
    return (P - (x + t * d)).norm();
  };
  L best = std::min({seg(A, B), seg(B, C), seg(C, A)});
  const VL n = (B - A).cross(C - A);
  if (n.squaredNorm() > 0) {
    const VL q = P - n * (n.dot(P - A) / n.squaredNorm());
    const L s1 = (B - A).cross(q - A).dot(n), s2 = (C - B).cross(q - B).dot(n), s3 = (A - C).cross(q - C).dot(n);
    if (s1 >= 0 && s2 >= 0 && s3 >= 0) best = std::min(best, (P - q).norm());
  }
  return best;
}

TYPED_TEST(BvhTyped, ClosestPointOnTriangleMatchesAReference) {
  using S = TypeParam;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int it = 0; it < 20000; ++it) {
    Vec3<S> a(S(u(rng)), S(u(rng)), S(u(rng))), b(S(u(rng)), S(u(rng)), S(u(rng))), c(S(u(rng)), S(u(rng)), S(u(rng)));
    if (it % 4 == 1) c = a + S(0.5) * (b - a);                                    // collinear
    if (it % 4 == 2) b = a;                                                       // a repeated corner
    if (it % 4 == 3) c = b + S(1e-3) * Vec3<S>(S(u(rng)), S(u(rng)), S(u(rng)));  // sliver
    const Vec3<S> p(S(2 * u(rng)), S(2 * u(rng)), S(2 * u(rng)));
    const Vec3<S> q = closestPointOnTriangle<S>(p, a, b, c);
    ASSERT_TRUE(q.allFinite()) << "case " << it;
    const long double ref = referenceDistance(p.template cast<double>(), a.template cast<double>(),
                                              b.template cast<double>(), c.template cast<double>());
    const double tol = 64 * eps<S>() * 4 + (it % 4 == 3 ? 2e-3 * std::sqrt(eps<S>()) : 0);
    ASSERT_NEAR(static_cast<double>((p - q).norm()), static_cast<double>(ref), tol) << "case " << it;
    // q lies on the triangle: its distance to it is ~0.
    ASSERT_LT(static_cast<double>(referenceDistance(q.template cast<double>(), a.template cast<double>(),
                                                    b.template cast<double>(), c.template cast<double>())),
              tol)
        << "case " << it;
  }
}

// ---------------------------------------------------------------------------------------
// The BVH against brute force
// ---------------------------------------------------------------------------------------

template <class S>
void expectClosestMatchesBruteForce(const TriangleBvh<S>& bvh, const Mesh<S>& m, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.2, 1.2);
  std::uniform_int_distribution<Index> vertex(0, static_cast<Index>(m.x.rows()) - 1);
  const S radii[] = {std::numeric_limits<S>::infinity(), S(0.05), S(0)};
  for (int it = 0; it < 150; ++it) {
    Vec3<S> p(S(u(rng)), S(u(rng)), S(u(rng)));
    if (it % 3 == 2) p = m.x.row(vertex(rng)).transpose();  // on a vertex: ties at distance 0
    for (S radius : radii) {
      const auto got = bvh.closestTriangle(m.x, p, radius);
      const auto want = bruteClosest(m, p, radius);
      ASSERT_EQ(got.has_value(), want.has_value()) << m.name << " query " << it << " radius " << radius;
      if (!want) continue;
      ASSERT_EQ(got->triangle, want->triangle) << m.name << " query " << it << " radius " << radius;
      ASSERT_EQ(got->squaredDistance, want->squaredDistance);
      ASSERT_EQ(got->point, want->point);
    }
  }
}

template <class S>
void expectQueriesMatchBruteForce(const Mesh<S>& m, const Mesh<S>& other, double margin, const Executor& exec) {
  SCOPED_TRACE(m.name + " vs " + other.name + ", margin " + std::to_string(margin));
  TriangleBvh<S> bvh, obvh;
  bvh.build(m.x, m.triangles, exec, margin);
  obvh.build(other.x, other.triangles, exec, margin);
  expectConsistent(bvh, m.x, m.triangles);
  if (margin == 0) expectClosestMatchesBruteForce(bvh, m, 5);
  const S sm = static_cast<S>(margin);
  BvhPairScratch scratch;
  std::vector<TrianglePair> pairs;
  bvh.overlappingPairs(obvh, pairs, scratch, exec);
  EXPECT_EQ(pairs, bruteOverlapping(m, sm, other, sm, false));
  bvh.intersectingPairs(obvh, m.x, other.x, pairs, scratch, exec);
  EXPECT_EQ(pairs, bruteOverlapping(m, sm, other, sm, true));
  EXPECT_FALSE(pairs.empty()) << "every test pair of meshes intersects somewhere";
  bvh.selfPairs(pairs, scratch, exec);
  EXPECT_EQ(pairs, bruteSelf(m, sm, false));
  bvh.selfIntersectingPairs(m.x, pairs, scratch, exec);
  const auto selfHits = bruteSelf(m, sm, true);
  EXPECT_EQ(pairs, selfHits);
  if (m.name != "sphere") {
    EXPECT_FALSE(selfHits.empty()) << "the crumpled and random meshes intersect themselves";
  }
}

TYPED_TEST(BvhTyped, QueriesMatchBruteForce) {
  using S = TypeParam;
  const Executor exec(2);
  const Mesh<S> soup = randomSoup<S>(400, 0.06, 1);
  const Mesh<S> soup2 = randomSoup<S>(300, 0.08, 2);
  const Mesh<S> sphere = fromTriangleMesh<S>(makeIcosphere({0.5, 0.05, 0.5}, 0.35, 4), "sphere");
  const Mesh<S> cloth = crumpledCloth<S>(16, 0.8, 3);
  const Mesh<S> degenerate = degenerateMesh<S>();
  for (double margin : {0.0, 0.01}) {
    expectQueriesMatchBruteForce(soup, soup2, margin, exec);
    expectQueriesMatchBruteForce(sphere, cloth, margin, exec);
    expectQueriesMatchBruteForce(cloth, soup, margin, exec);
    expectQueriesMatchBruteForce(degenerate, degenerate, margin, exec);
  }
  // The crumpled cloth and the degenerate mesh really have intersections to find.
  TriangleBvh<S> bvh;
  BvhPairScratch scratch;
  std::vector<TrianglePair> pairs;
  bvh.build(cloth.x, cloth.triangles, exec);
  bvh.selfIntersectingPairs(cloth.x, pairs, scratch, exec);
  EXPECT_GT(pairs.size(), 10u);
  bvh.build(degenerate.x, degenerate.triangles, exec);
  bvh.selfIntersectingPairs(degenerate.x, pairs, scratch, exec);
  const auto found = [&](Index i, Index j) {
    return std::binary_search(pairs.begin(), pairs.end(), TrianglePair{i, j});
  };
  // The base (0) against: its copy with separate corners (3), coplanar overlapping (4), touching
  // at a vertex position (5) and along an edge (6), the sliver through it (8), the collinear
  // segment through it (10), the point on it (12), the vertex on its face (14), the edge across its
  // edge (15); collinear overlapping segments (16, 17).
  for (Index t : {3, 4, 5, 6, 8, 10, 12, 14, 15}) EXPECT_TRUE(found(0, t)) << "0 and " << t;
  EXPECT_TRUE(found(16, 17));
  // Not: 1 and 2 share the base's corners; coplanar disjoint (7), the sliver above (9), the
  // segment beside (11), the point off the face (13); segments apart on one line (17, 18).
  for (Index t : {1, 2, 7, 9, 11, 13}) EXPECT_FALSE(found(0, t)) << "0 and " << t;
  EXPECT_FALSE(found(17, 18));
}

/// The mesh as a Model (a particle of 1 kg per vertex, its triangles), for the checks that
/// take one.
template <class S>
Model<S> modelOf(const Mesh<S>& m) {
  ModelBuilder<S> builder;
  for (Index i = 0; i < m.x.rows(); ++i)
    builder.addParticle(
        {static_cast<double>(m.x(i, 0)), static_cast<double>(m.x(i, 1)), static_cast<double>(m.x(i, 2))}, 1.0);
  for (Index t = 0; t < m.triangles.count(); ++t)
    builder.addTriangle(m.triangles.a[t], m.triangles.b[t], m.triangles.c[t]);
  return builder.build().model;
}

// countSelfIntersections has a tree of its own (leaves of several triangles, an implicit
// hierarchy, pairs counted as the walk finds them): it must count exactly the pairs the brute
// force finds, on meshes of every size around its leaf size, crumpled cloths full of
// intersections and the degenerate cases, with the same count on 1 and 2 threads.
TYPED_TEST(BvhTyped, SelfIntersectionCountMatchesBruteForce) {
  using S = TypeParam;
  const Executor one(1), two(2);
  std::vector<Mesh<S>> meshes{degenerateMesh<S>(), crumpledCloth<S>(16, 0.8, 3), crumpledCloth<S>(40, 1.5, 4),
                              randomSoup<S>(400, 0.06, 1), randomSoup<S>(2000, 0.05, 9)};
  for (Index n : {1, 2, 3, 7, 8, 9, 15, 16, 17, 33, 100}) meshes.push_back(randomSoup<S>(n, 0.4, 10 + n));
  std::int64_t total = 0;
  for (const Mesh<S>& m : meshes) {
    SCOPED_TRACE(m.name + ", " + std::to_string(m.triangles.count()) + " triangles");
    const Model<S> model = modelOf(m);
    const std::int64_t want = static_cast<std::int64_t>(bruteSelf(m, S(0), true).size());
    EXPECT_EQ(countSelfIntersections(model, m.x, one), want);
    EXPECT_EQ(countSelfIntersections(model, m.x, two), want);
    total += want;
  }
  EXPECT_GT(total, 1000) << "the meshes have intersections to count";
  // A flat cloth: none. Positions of the wrong shape are refused.
  const Mesh<S> flat = crumpledCloth<S>(24, 0.0, 5);
  EXPECT_EQ(countSelfIntersections(modelOf(flat), flat.x, two), 0);
  const Vec3Array<S> wrong(flat.x.rows() - 1, 3);
  try {
    (void)countSelfIntersections(modelOf(flat), wrong, two);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("x must be 576 x 3 (the model's particles), got 575 x 3"), std::string::npos)
        << e.what();
  }
}

TYPED_TEST(BvhTyped, EmptySingleAndInvalidInput) {
  using S = TypeParam;
  const Executor exec(2);
  TriangleBvh<S> bvh;
  Vec3Array<S> x(3, 3);
  x << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  Triangles none;
  bvh.build(x, none, exec);
  EXPECT_TRUE(bvh.empty());
  EXPECT_EQ(bvh.root(), TriangleBvh<S>::kNoRoot);
  EXPECT_FALSE(bvh.closestTriangle(x, Vec3<S>(0, 0, 1), std::numeric_limits<S>::infinity()));
  BvhPairScratch scratch;
  std::vector<TrianglePair> pairs{{1, 2}};
  bvh.selfPairs(pairs, scratch, exec);
  EXPECT_TRUE(pairs.empty());

  Triangles one;
  one.a.resize(1);
  one.b.resize(1);
  one.c.resize(1);
  one.a << 0;
  one.b << 1;
  one.c << 2;
  bvh.build(x, one, exec, 0.5);
  EXPECT_EQ(bvh.root(), ~Index(0));
  EXPECT_EQ(bvh.rootBox().lo[2], S(-0.5));
  const auto hit = bvh.closestTriangle(x, Vec3<S>(S(0.25), S(0.25), 2), std::numeric_limits<S>::infinity());
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->triangle, 0);
  EXPECT_EQ(hit->squaredDistance, S(4));
  EXPECT_FALSE(bvh.closestTriangle(x, Vec3<S>(S(0.25), S(0.25), 2), S(1.5)));
  TriangleBvh<S> other;
  other.build(x, one, exec);
  bvh.intersectingPairs(other, x, x, pairs, scratch, exec);
  EXPECT_EQ(pairs, (std::vector<TrianglePair>{{0, 0}}));
  bvh.selfPairs(pairs, scratch, exec);
  EXPECT_TRUE(pairs.empty());

  Triangles bad = one;
  bad.c << 3;
  try {
    bvh.build(x, bad, exec);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 0 corner c = 3"), std::string::npos) << e.what();
  }
  EXPECT_EQ(bvh.triangleCount(), 1) << "a rejected build leaves the BVH unchanged";
  EXPECT_THROW(bvh.build(x, one, exec, -1), std::invalid_argument);
  EXPECT_THROW(bvh.build(x, one, exec, std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  EXPECT_THROW(bvh.refit(Vec3Array<S>(4, 3), exec), std::invalid_argument);
  EXPECT_THROW(bvh.closestTriangle(x, Vec3<S>(0, 0, 0), S(-1)), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------
// Refit
// ---------------------------------------------------------------------------------------

TYPED_TEST(BvhTyped, RefitGivesTightContainingBoxesAndBruteForceAnswers) {
  using S = TypeParam;
  const Executor exec(2);
  Mesh<S> cloth = crumpledCloth<S>(24, 0.3, 4);
  const Mesh<S> sphere = fromTriangleMesh<S>(makeIcosphere({0.5, 0.2, 0.5}, 0.3, 4), "sphere");
  TriangleBvh<S> bvh, sbvh;
  bvh.build(cloth.x, cloth.triangles, exec, 0.002);
  sbvh.build(sphere.x, sphere.triangles, exec, 0.002);
  // Move the cloth: fold it over (large motion: the tree built for the old shape stays valid).
  const Vec3Array<S> x0 = cloth.x;
  for (Index i = 0; i < cloth.x.rows(); ++i) {
    const double angle = 1.2 * static_cast<double>(x0(i, 0));
    cloth.x(i, 1) = static_cast<S>(0.3 * std::sin(angle * 3) + static_cast<double>(x0(i, 1)));
    cloth.x(i, 0) = static_cast<S>(0.5 + 0.4 * std::cos(angle * 2));
  }
  bvh.refit(cloth.x, exec);
  expectConsistent(bvh, cloth.x, cloth.triangles);
  TriangleBvh<S> fresh;
  fresh.build(cloth.x, cloth.triangles, exec, 0.002);
  expectConsistent(fresh, cloth.x, cloth.triangles);
  for (int k = 0; k < 3; ++k) {  // same root box: both are the union of the same triangle boxes
    EXPECT_EQ(bvh.rootBox().lo[k], fresh.rootBox().lo[k]);
    EXPECT_EQ(bvh.rootBox().hi[k], fresh.rootBox().hi[k]);
  }
  BvhPairScratch scratch;
  std::vector<TrianglePair> a, b;
  bvh.selfIntersectingPairs(cloth.x, a, scratch, exec);
  fresh.selfIntersectingPairs(cloth.x, b, scratch, exec);
  EXPECT_EQ(a, b);
  EXPECT_EQ(a, bruteSelf(cloth, S(0.002), true));
  bvh.intersectingPairs(sbvh, cloth.x, sphere.x, a, scratch, exec);
  fresh.intersectingPairs(sbvh, cloth.x, sphere.x, b, scratch, exec);
  EXPECT_EQ(a, b);
  EXPECT_FALSE(a.empty());
  bvh.selfPairs(a, scratch, exec);
  fresh.selfPairs(b, scratch, exec);
  EXPECT_EQ(a, b);
  expectClosestMatchesBruteForce(bvh, cloth, 9);

  // Swept boxes cover both ends of the motion: every pair overlapping at either end is a candidate.
  TriangleBvh<S> swept;
  swept.build(x0, cloth.triangles, exec, 0.002);
  swept.refitSwept(x0, cloth.x, exec);
  for (Index s = 0; s < swept.triangleCount(); ++s) {
    const Index t = swept.slotTriangle(s);
    const Aabb<S> at0 = triangleBox(x0, cloth.triangles, t, S(0.002));
    const Aabb<S> at1 = triangleBox(cloth.x, cloth.triangles, t, S(0.002));
    ASSERT_TRUE(swept.leafBox(s).contains(at0) && swept.leafBox(s).contains(at1)) << "slot " << s;
  }
  std::vector<TrianglePair> sweptPairs;
  swept.selfPairs(sweptPairs, scratch, exec);
  TriangleBvh<S> start;
  start.build(x0, cloth.triangles, exec, 0.002);
  start.selfPairs(a, scratch, exec);
  fresh.selfPairs(b, scratch, exec);
  EXPECT_TRUE(std::includes(sweptPairs.begin(), sweptPairs.end(), a.begin(), a.end()));
  EXPECT_TRUE(std::includes(sweptPairs.begin(), sweptPairs.end(), b.begin(), b.end()));
}

// ---------------------------------------------------------------------------------------
// Determinism and allocation
// ---------------------------------------------------------------------------------------

TYPED_TEST(BvhTyped, IdenticalForOneAndTwoThreadsOnA128ClothAndASphere) {
  using S = TypeParam;
  const Executor one(1), two(2);
  const Mesh<S> cloth = crumpledCloth<S>(128, 0.6, 5);
  ASSERT_EQ(cloth.triangles.count(), 2 * 127 * 127);
  const Mesh<S> sphere = fromTriangleMesh<S>(makeIcosphere({0.5, 0, 0.5}, 0.3, 16), "sphere");
  TriangleBvh<S> c1, c2, s1, s2;
  c1.build(cloth.x, cloth.triangles, one, 0.001);
  c2.build(cloth.x, cloth.triangles, two, 0.001);
  expectIdentical(c1, c2);
  expectConsistent(c2, cloth.x, cloth.triangles);
  EXPECT_GT(c2.subtreeCount(), 16);
  s1.build(sphere.x, sphere.triangles, one);
  s2.build(sphere.x, sphere.triangles, two);
  expectIdentical(s1, s2);

  Vec3Array<S> moved = cloth.x;
  addNoise<S>(moved, 0.004, 6);
  c1.refit(moved, one);
  c2.refit(moved, two);
  expectIdentical(c1, c2);
  expectConsistent(c2, moved, cloth.triangles);

  BvhPairScratch scratch1, scratch2;
  std::vector<TrianglePair> p1, p2;
  c1.selfIntersectingPairs(moved, p1, scratch1, one);
  c2.selfIntersectingPairs(moved, p2, scratch2, two);
  EXPECT_EQ(p1, p2);
  EXPECT_GT(p1.size(), 100u);
  c1.selfPairs(p1, scratch1, one);
  c2.selfPairs(p2, scratch2, two);
  EXPECT_EQ(p1, p2);
  c1.intersectingPairs(s1, moved, sphere.x, p1, scratch1, one);
  c2.intersectingPairs(s2, moved, sphere.x, p2, scratch2, two);
  EXPECT_EQ(p1, p2);
  EXPECT_GT(p1.size(), 100u);
  // Spot-check the 128^2 results: every reported pair intersects, and pairs are sorted and unique.
  const Mesh<S> movedCloth{moved, cloth.triangles, "moved"};
  for (const TrianglePair& p : p2) ASSERT_TRUE(intersect(movedCloth, p.first, sphere, p.second));
  EXPECT_TRUE(std::adjacent_find(p2.begin(), p2.end(), [](auto& l, auto& r) { return !(l < r); }) == p2.end());
}

// selfOverlappingPairs with a limit: it answers in full up to the limit, and past it stops
// and says so. Where it stops is a property of the tree (the pairs and the node pairs it
// meets), the same for one thread and two.
TYPED_TEST(BvhTyped, ASelfQueryStopsPastItsLimitTheSameOnAnyThreadCount) {
  using S = TypeParam;
  const Executor one(1), two(2);
  const Mesh<S> cloth = crumpledCloth<S>(32, 0.6, 5);
  TriangleBvh<S> bvh;
  bvh.build(cloth.x, cloth.triangles, two, 0.01);
  BvhPairScratch scratch;
  std::vector<TrianglePair> all, pairs;
  ASSERT_TRUE(bvh.selfOverlappingPairs(all, scratch, two));
  const std::int64_t n = static_cast<std::int64_t>(all.size());
  ASSERT_GT(n, 1000);
  // The least limit that lets the query finish, found by bisection on two threads.
  std::int64_t lo = 0, hi = 64 * n;  // fails at lo (nothing fits in 0), finishes at hi
  ASSERT_FALSE(bvh.selfOverlappingPairs(pairs, scratch, two, {}, lo));
  ASSERT_TRUE(bvh.selfOverlappingPairs(pairs, scratch, two, {}, hi));
  while (hi - lo > 1) {
    const std::int64_t mid = lo + (hi - lo) / 2;
    (bvh.selfOverlappingPairs(pairs, scratch, two, {}, mid) ? hi : lo) = mid;
  }
  EXPECT_GE(hi, n);      // every listed pair counts
  EXPECT_LE(hi, 4 * n);  // and the node pairs met are of the same order
  for (const Executor* exec : {&one, &two}) {
    for (int k = 0; k < 3; ++k) {  // (repeated: the tasks may run in another order)
      EXPECT_TRUE(bvh.selfOverlappingPairs(pairs, scratch, *exec, {}, hi));
      EXPECT_EQ(pairs, all);
      EXPECT_FALSE(bvh.selfOverlappingPairs(pairs, scratch, *exec, {}, hi - 1));
      EXPECT_TRUE(pairs.empty());
    }
  }
  // Every triangle at one point: all n (n - 1) / 2 pairs overlap, and a limit of 256 per
  // triangle stops the query long before it would list them.
  Vec3Array<S> collapsed = cloth.x;
  for (Index i = 0; i < collapsed.rows(); ++i)
    for (int a = 0; a < 3; ++a) collapsed(i, a) = S(0.25);
  TriangleBvh<S> crushed;
  crushed.build(collapsed, cloth.triangles, two, 0.01);
  EXPECT_FALSE(crushed.selfOverlappingPairs(pairs, scratch, two, {}, 256 * crushed.triangleCount()));
  EXPECT_THROW(bvh.selfOverlappingPairs(pairs, scratch, two, {}, -1), std::invalid_argument);
}

TYPED_TEST(BvhTyped, NoAllocationOnceWarmedUp) {
  using S = TypeParam;
  const Mesh<S> cloth = crumpledCloth<S>(48, 0.6, 8);
  const Mesh<S> sphere = fromTriangleMesh<S>(makeIcosphere({0.5, 0, 0.5}, 0.3, 8), "sphere");
  Vec3Array<S> moved = cloth.x;
  addNoise<S>(moved, 0.003, 9);
  for (int threads : {1, 2}) {
    const Executor exec(threads);
    TriangleBvh<S> bvh, sbvh;
    BvhPairScratch scratch;
    std::vector<TrianglePair> pairs;
    const auto work = [&](const Vec3Array<S>& x) {
      bvh.build(x, cloth.triangles, exec, 0.001);
      sbvh.build(sphere.x, sphere.triangles, exec);
      bvh.refit(moved, exec);
      bvh.refitSwept(x, moved, exec);
      bvh.refit(x, exec);
      std::size_t found = 0;
      for (int i = 0; i < 20; ++i)
        found += bvh.closestTriangle(x, Vec3<S>(S(0.05 * i), S(0.01), S(0.5)), S(0.1)).has_value();
      bvh.selfPairs(pairs, scratch, exec);
      found += pairs.size();
      bvh.selfIntersectingPairs(x, pairs, scratch, exec);
      found += pairs.size();
      bvh.intersectingPairs(sbvh, x, sphere.x, pairs, scratch, exec);
      found += pairs.size();
      bvh.overlappingPairs(sbvh, pairs, scratch, exec);
      return found + pairs.size();
    };
    work(moved);  // warm up on the larger result sets first
    work(cloth.x);
    const std::int64_t before = operatorNewCalls();
    const std::size_t found = work(cloth.x);
    EXPECT_EQ(operatorNewCalls() - before, 0) << threads << " threads";
    EXPECT_GT(found, 0u);
  }
}

// ---------------------------------------------------------------------------------------
// Sphere mesh
// ---------------------------------------------------------------------------------------

TEST(Shapes, IcosphereIsClosedOutwardAndOnTheSphere) {
  for (Index d : {1, 3, 8}) {
    const TriangleMesh m = makeIcosphere({1, 2, 3}, 0.5, d);
    ASSERT_EQ(static_cast<Index>(m.triangles.size()), 20 * d * d);
    ASSERT_EQ(static_cast<Index>(m.vertices.size()), 10 * d * d + 2);
    std::vector<std::pair<Index, Index>> edges;
    for (const auto& t : m.triangles) {
      V p[3];
      for (int k = 0; k < 3; ++k) {
        const Vec3d& v = m.vertices[static_cast<size_t>(t[static_cast<size_t>(k)])];
        p[k] = V(v.x - 1, v.y - 2, v.z - 3);
        ASSERT_NEAR(p[k].norm(), 0.5, 1e-12);
        edges.emplace_back(t[static_cast<size_t>(k)], t[static_cast<size_t>((k + 1) % 3)]);
      }
      EXPECT_GT((p[1] - p[0]).cross(p[2] - p[0]).dot(p[0] + p[1] + p[2]), 0) << "outward winding";
    }
    // Closed and consistently oriented: every directed edge appears once, and its reverse too.
    std::sort(edges.begin(), edges.end());
    EXPECT_TRUE(std::adjacent_find(edges.begin(), edges.end()) == edges.end());
    for (const auto& e : edges)
      ASSERT_TRUE(std::binary_search(edges.begin(), edges.end(), std::make_pair(e.second, e.first)));
  }
  EXPECT_THROW(makeIcosphere({0, 0, 0}, 0, 2), std::invalid_argument);
  EXPECT_THROW(makeIcosphere({0, 0, 0}, 1, 0), std::invalid_argument);
}

}  // namespace
}  // namespace weft::test
