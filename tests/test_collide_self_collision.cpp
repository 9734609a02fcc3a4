// tests/test_collide_self_collision.cpp — cloth against itself and against other cloths
// (weft/collide/self_collision.hpp).
//
//  * The continuous proximity queries never miss a touching pair: random, near-degenerate
//    (coplanar motion, parallel edges, a vertex on an edge, contact at the start or the
//    end) and adversarial queries against minimum distances found independently in long
//    double (dense sampling refined by golden section; a sampled minimum is an upper bound
//    of the true one, so "sampled minimum < threshold / 2 but no hit" is a proven miss).
//    False positives (a hit where the distance never came below the threshold) are
//    counted and printed.
//  * The hard scenes (fold, two-cloths, twist, flag-pole), small, step by step: zero
//    intersecting pairs of triangles after every step, in float and double; without
//    self-collision the same scenes do intersect (so the check has something to find).
//  * 1 and 2 threads give the same bits; bad options are refused by field.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iostream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "collide/self_collider.hpp"
#include "support/sanitizers.hpp"
#include "weft/io/scene.hpp"
#include "weft/weft.hpp"

namespace {

using namespace weft;
using V = Vec3<double>;
using L = long double;

struct LV {
  L x = 0, y = 0, z = 0;
  LV() = default;
  LV(L a, L b, L c) : x(a), y(b), z(c) {}
  explicit LV(const V& v) : x(v[0]), y(v[1]), z(v[2]) {}
  LV operator+(const LV& o) const { return {x + o.x, y + o.y, z + o.z}; }
  LV operator-(const LV& o) const { return {x - o.x, y - o.y, z - o.z}; }
  LV operator*(L s) const { return {x * s, y * s, z * s}; }
  L dot(const LV& o) const { return x * o.x + y * o.y + z * o.z; }
  LV cross(const LV& o) const { return {y * o.z - z * o.y, z * o.x - x * o.z, x * o.y - y * o.x}; }
  L norm() const { return std::sqrt(dot(*this)); }
};

/// Distance from p to the segment ab, long double.
L pointSegment(const LV& p, const LV& a, const LV& b) {
  const LV d = b - a;
  const L len2 = d.dot(d);
  L t = len2 > 0 ? (p - a).dot(d) / len2 : 0;
  t = std::clamp<L>(t, 0, 1);
  return (p - (a + d * t)).norm();
}

/// Distance from p to the closed triangle abc, long double: the plane distance when the
/// projection falls inside (all three edge orientations agree), else the nearest edge.
L pointTriangle(const LV& p, const LV& a, const LV& b, const LV& c) {
  const LV n = (b - a).cross(c - a);
  const L n2 = n.dot(n);
  L best = std::min({pointSegment(p, a, b), pointSegment(p, b, c), pointSegment(p, c, a)});
  if (n2 > 0) {
    const L h = (p - a).dot(n) / n2;
    const LV q = p - n * h;
    const L s1 = (b - a).cross(q - a).dot(n), s2 = (c - b).cross(q - b).dot(n), s3 = (a - c).cross(q - c).dot(n);
    if ((s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0))
      best = std::min(best, std::abs(h) * std::sqrt(n2));
  }
  return best;
}

/// Distance between the segments pq and ab, long double: the endpoint distances, and the
/// lines' distance when their closest points fall inside both segments.
L segmentSegment(const LV& p, const LV& q, const LV& a, const LV& b) {
  L best = std::min({pointSegment(p, a, b), pointSegment(q, a, b), pointSegment(a, p, q), pointSegment(b, p, q)});
  const LV d1 = q - p, d2 = b - a, r = p - a;
  const L A = d1.dot(d1), E = d2.dot(d2), B = d1.dot(d2), C = d1.dot(r), F = d2.dot(r);
  const L den = A * E - B * B;
  if (den > 1e-30L * A * E) {
    const L s = (B * F - C * E) / den, t = (A * F - B * C) / den;
    if (s >= 0 && s <= 1 && t >= 0 && t <= 1) best = std::min(best, ((p + d1 * s) - (a + d2 * t)).norm());
  }
  return best;
}

LV at(const V x[2], L s) { return LV(x[0]) + (LV(x[1]) - LV(x[0])) * s; }

/// The minimum over s in [0, 1] of f(s), sampled at 2001 points and refined around the best
/// three by golden section: an upper bound of the true minimum (and close to it).
template <class F>
L sampledMinimum(F&& f) {
  constexpr int kSamples = 2000;
  std::vector<std::pair<L, int>> values;
  values.reserve(kSamples + 1);
  for (int k = 0; k <= kSamples; ++k) values.push_back({f(L(k) / kSamples), k});
  std::partial_sort(values.begin(), values.begin() + 3, values.end());
  L best = values[0].first;
  for (int r = 0; r < 3; ++r) {
    L lo = std::max<L>(0, L(values[r].second - 1) / kSamples), hi = std::min<L>(1, L(values[r].second + 1) / kSamples);
    const L g = (std::sqrt(L(5)) - 1) / 2;
    for (int it = 0; it < 80; ++it) {
      const L m1 = hi - g * (hi - lo), m2 = lo + g * (hi - lo);
      const L f1 = f(m1), f2 = f(m2);
      best = std::min({best, f1, f2});
      if (f1 < f2)
        hi = m2;
      else
        lo = m1;
    }
  }
  return best;
}

struct Query {
  bool vertexTriangle = true;
  V x[4][2];  // four vertices at s = 0 and s = 1
};

L trueMinimum(const Query& q) {
  return sampledMinimum([&](L s) {
    return q.vertexTriangle ? pointTriangle(at(q.x[0], s), at(q.x[1], s), at(q.x[2], s), at(q.x[3], s))
                            : segmentSegment(at(q.x[0], s), at(q.x[1], s), at(q.x[2], s), at(q.x[3], s));
  });
}

PrimitiveContact ask(const Query& q, double threshold) {
  return q.vertexTriangle ? vertexTriangleContact(q.x[0], q.x[1], q.x[2], q.x[3], threshold)
                          : edgeEdgeContact(q.x[0], q.x[1], q.x[2], q.x[3], threshold);
}

/// Hand-made degenerate and adversarial queries (the motion of every vertex is linear).
std::vector<Query> degenerateQueries() {
  std::vector<Query> out;
  const auto vt = [&](V p0, V p1, V a0, V a1, V b0, V b1, V c0, V c1) {
    Query q;
    q.vertexTriangle = true;
    q.x[0][0] = p0, q.x[0][1] = p1, q.x[1][0] = a0, q.x[1][1] = a1, q.x[2][0] = b0, q.x[2][1] = b1, q.x[3][0] = c0,
    q.x[3][1] = c1;
    out.push_back(q);
  };
  const auto ee = [&](V p0, V p1, V q0, V q1, V a0, V a1, V b0, V b1) {
    Query q;
    q.vertexTriangle = false;
    q.x[0][0] = p0, q.x[0][1] = p1, q.x[1][0] = q0, q.x[1][1] = q1, q.x[2][0] = a0, q.x[2][1] = a1, q.x[3][0] = b0,
    q.x[3][1] = b1;
    out.push_back(q);
  };
  const V a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // A vertex straight through the face, through an edge, through a corner.
  vt({0.25, 0.25, 1}, {0.25, 0.25, -1}, a, a, b, b, c, c);
  vt({0.5, 0, 1}, {0.5, 0, -1}, a, a, b, b, c, c);
  vt({0, 0, 1}, {0, 0, -1}, a, a, b, b, c, c);
  // Coplanar: the vertex slides in the triangle's plane into it, along an edge's line, onto a corner.
  vt({2, 0.2, 0}, {-1, 0.2, 0}, a, a, b, b, c, c);
  vt({3, 0, 0}, {0.5, 0, 0}, a, a, b, b, c, c);
  vt({-1, -1, 0}, {0, 0, 0}, a, a, b, b, c, c);
  // Contact at the start, at the end, throughout.
  vt({0.2, 0.2, 0}, {0.2, 0.2, 1}, a, a, b, b, c, c);
  vt({0.2, 0.2, 1}, {0.2, 0.2, 0}, a, a, b, b, c, c);
  vt({0.2, 0.2, 0}, {0.3, 0.1, 0}, a, a, b, b, c, c);
  // The triangle moves onto a resting vertex; the triangle flips through it (rotates).
  vt({0.2, 0.2, 0}, {0.2, 0.2, 0}, {0, 0, 1}, {0, 0, -1}, {1, 0, 1}, {1, 0, -1}, {0, 1, 1}, {0, 1, -1});
  vt({0.3, 0.3, 0}, {0.3, 0.3, 0}, {0, 0, -1}, {0, 0, 1}, {1, 0, 1}, {1, 0, -1}, {0, 1, 0}, {0, 1, 0});
  // A degenerate (collinear) triangle swept through a vertex.
  vt({0.5, 0, 0}, {0.5, 0, 0}, {0, 1, 0}, {0, -1, 0}, {1, 1, 0}, {1, -1, 0}, {2, 1, 0}, {2, -1, 0});
  // Edges: crossing, parallel sliding onto each other, collinear overlapping, touching at an end.
  ee({0.5, -1, 1}, {0.5, -1, -1}, {0.5, 1, 1}, {0.5, 1, -1}, {0, 0, 0}, {0, 0, 0}, {1, 0, 0}, {1, 0, 0});
  ee({0, 1, 0}, {0, 0, 0}, {1, 1, 0}, {1, 0, 0}, {0.5, 0, 0}, {0.5, 0, 0}, {2, 0, 0}, {2, 0, 0});
  ee({-2, 0, 0}, {0, 0, 0}, {-1, 0, 0}, {1, 0, 0}, {0.5, 0, 0}, {0.5, 0, 0}, {2, 0, 0}, {2, 0, 0});
  ee({1, 1, 0}, {1, 0, 0}, {1, 2, 0}, {1, 1, 0}, {0, 0, 0}, {0, 0, 0}, {1, 0, 0}, {1, 0, 0});
  ee({0, 0, 0}, {0, 0, 0}, {1, 0, 0}, {1, 0, 0}, {0, 0, 0}, {0, 0, 0}, {1, 0, 0}, {1, 0, 0});  // identical, resting
  // Parallel edges in parallel planes, one passing through the other's plane (coplanar at s = 1/2).
  ee({0, 0, 1}, {0, 0, -1}, {1, 0, 1}, {1, 0, -1}, {0.5, 0, 0}, {0.5, 0, 0}, {1.5, 0, 0}, {1.5, 0, 0});
  // Grazing: the vertex passes at a quarter of the threshold (below half: must be found).
  vt({0.25, 0.25, 1}, {0.25, 0.25, -1}, {0, 0, 0.25e-3}, {0, 0, 0.25e-3}, {1, 0, 0.25e-3}, {1, 0, 0.25e-3},
     {0, 1, 0.25e-3}, {0, 1, 0.25e-3});
  return out;
}

TEST(SelfCollisionQuery, NeverMissesATouchingPair) {
  constexpr double kThreshold = 1e-3;
  std::vector<Query> queries = degenerateQueries();
  const size_t handMade = queries.size();
  std::mt19937_64 rng(20261125);
  std::uniform_int_distribution<int> grid(-4, 4);  // small integer grids: full of coplanar and collinear cases
  std::uniform_real_distribution<double> real(-1, 1);
  for (int k = 0; k < 3000; ++k) {
    Query q;
    q.vertexTriangle = k % 2 == 0;
    const bool onGrid = k % 3 != 0;
    for (auto& vertex : q.x)
      for (V& p : vertex) p = onGrid ? V(grid(rng), grid(rng), grid(rng)) * 0.25 : V(real(rng), real(rng), real(rng));
    if (k % 5 == 0)  // a planar scene: everything in z = 0
      for (auto& vertex : q.x)
        for (V& p : vertex) p[2] = 0;
    queries.push_back(q);
  }
  int misses = 0, falsePositives = 0, touching = 0, hits = 0, capped = 0;
  for (size_t i = 0; i < queries.size(); ++i) {
    const Query& q = queries[i];
    const L minimum = trueMinimum(q);
    const PrimitiveContact c = ask(q, kThreshold);
    hits += c.hit ? 1 : 0;
    capped += c.capped ? 1 : 0;
    touching += minimum < 1e-12L ? 1 : 0;
    if (!c.hit && minimum < L(0.5 * kThreshold)) {
      ++misses;
      ADD_FAILURE() << "query " << i << (i < handMade ? " (hand-made)" : "") << ": minimum distance "
                    << static_cast<double>(minimum) << " < threshold / 2, not found";
    }
    if (c.hit && minimum > L(kThreshold) * (1 + 1e-9L)) ++falsePositives;
    if (c.hit && !c.capped) {  // a reported contact is real: the distance there is below the threshold
      EXPECT_LT(c.distance, kThreshold) << "query " << i;
      const double n = std::sqrt(c.normal[0] * c.normal[0] + c.normal[1] * c.normal[1] + c.normal[2] * c.normal[2]);
      EXPECT_TRUE(n == 0 || std::abs(n - 1) < 1e-9) << "query " << i;
    }
  }
  EXPECT_EQ(misses, 0);
  EXPECT_GT(touching, 100) << "the set should hold many touching queries";
  for (size_t i = 0; i + 1 < handMade; ++i) EXPECT_TRUE(ask(queries[i], kThreshold).hit) << "hand-made query " << i;
  std::cout << "[ self-collision queries ] " << queries.size() << " queries, " << touching << " touching, " << hits
            << " reported, " << misses << " missed, " << falsePositives
            << " false positives (reported, minimum distance above the threshold), " << capped << " capped\n";
  RecordProperty("false_positives", falsePositives);
}

// The pass takes the edge-edge first looks in batches (structure of arrays, no branches) and
// skips the full query where the batched look proves a pair apart: that must never happen
// where the one-by-one look would not prove it. The values agree to rounding, and to 2e-8
// relative for nearly parallel edges (ill-conditioned closest points); with the guard band
// of batchedLook a batched proof is a one-by-one proof at every threshold tried, including
// thresholds at and next to the pair's own distance. Queries: the degenerate ones, small
// integer grids (parallel, collinear and touching edges abound), random ones, nearly
// parallel ones, zero-length edges (left to the full query).
TEST(SelfCollisionQuery, ABatchedFirstLookProvesOnlyWhatTheOneByOneLookProves) {
  std::vector<Query> queries;
  for (const Query& q : degenerateQueries())
    if (!q.vertexTriangle) queries.push_back(q);
  std::mt19937_64 rng(20261126);
  std::uniform_int_distribution<int> grid(-4, 4);
  std::uniform_real_distribution<double> real(-1, 1), tiny(-1e-9, 1e-9);
  for (int k = 0; k < 4000; ++k) {
    Query q;
    q.vertexTriangle = false;
    const int kind = k % 4;
    for (auto& vertex : q.x)
      for (V& p : vertex) p = kind < 2 ? V(grid(rng), grid(rng), grid(rng)) * 0.25 : V(real(rng), real(rng), real(rng));
    if (kind == 3) {   // nearly parallel: the second edge is the first shifted, tilted by ~1e-9
      if (k % 8 == 3)  // and long against the distance: edges 100x longer
        for (int s = 0; s < 2; ++s) q.x[1][s] = q.x[0][s] + 100 * (q.x[1][s] - q.x[0][s]);
      const V shift(real(rng), real(rng), real(rng));
      for (int s = 0; s < 2; ++s) {
        q.x[2][s] = q.x[0][s] + shift;
        q.x[3][s] = q.x[1][s] + shift + V(tiny(rng), tiny(rng), tiny(rng));
      }
    }
    if (k % 3 != 0)  // slow motion against the distances, as at rest: the looks prove pairs apart
      for (auto& vertex : q.x) vertex[1] = vertex[0] + 1e-3 * (vertex[1] - vertex[0]);
    if (k % 50 == 0) q.x[1][0] = q.x[0][0];                                    // a zero-length edge at s = 0
    if (k % 97 == 0) q.x[2][1][0] = std::numeric_limits<double>::quiet_NaN();  // not finite at s = 1
    queries.push_back(q);
  }
  int compared = 0, leftToTheQuery = 0, proofs = 0;
  double worst = 0;
  for (size_t first = 0; first < queries.size(); first += kFirstLookBatch) {
    const int count = static_cast<int>(std::min<size_t>(kFirstLookBatch, queries.size() - first));
    double x[4][3][kFirstLookBatch], d[4][3][kFirstLookBatch], distance[kFirstLookBatch], lipschitz2[kFirstLookBatch],
        lengths[kFirstLookBatch];
    for (int k = 0; k < count; ++k)
      for (int i = 0; i < 4; ++i)
        for (int a = 0; a < 3; ++a) {
          x[i][a][k] = queries[first + k].x[i][0][a];
          d[i][a][k] = queries[first + k].x[i][1][a] - queries[first + k].x[i][0][a];
        }
    edgeEdgeFirstLooks(count, x, d, distance, lipschitz2, lengths);
    for (int k = 0; k < count; ++k) {
      const Query& q = queries[first + k];
      const FirstLook one = edgeEdgeFirstLook(q.x[0], q.x[1], q.x[2], q.x[3]);
      const bool finite = [&] {
        for (const auto& vertex : q.x)
          for (const V& p : vertex)
            if (!p.allFinite()) return false;
        return true;
      }();
      if (distance[k] == -1) {  // left to the full query: an edge of squared length <= 1e-300, or not finite
        ++leftToTheQuery;
        EXPECT_TRUE(!finite || (q.x[1][0] - q.x[0][0]).squaredNorm() <= 1e-300 ||
                    (q.x[3][0] - q.x[2][0]).squaredNorm() <= 1e-300)
            << "query " << first + k;
        continue;
      }
      EXPECT_TRUE(finite) << "query " << first + k << ": a non-finite query must be left to the full query";
      ++compared;
      if (one.distance > 0) worst = std::max(worst, std::abs(distance[k] - one.distance) / (one.distance + lengths[k]));
      EXPECT_LE(std::abs(lipschitz2[k] - one.lipschitz2), 4.5e-16 * one.lipschitz2) << "query " << first + k;
      const FirstLook batched = batchedLook(distance[k], lipschitz2[k], lengths[k]);
      for (const double scale : {0.25, 0.5, 0.999999, 1 - 1e-9, 1.0, 1 + 1e-9, 1.000001, 1.5, 1.9999999, 2.0, 4.0}) {
        const double threshold = scale * one.distance;
        if (!(threshold > 0)) continue;
        if (!firstLookProvesApart(batched, threshold)) continue;
        ++proofs;
        EXPECT_TRUE(firstLookProvesApart(one, threshold))
            << "query " << first + k << ", threshold " << threshold << ": the batched look proves it apart, "
            << "the one-by-one look does not";
      }
    }
  }
  std::cout << "[ batched first looks ] " << compared << " compared (largest difference " << worst
            << " of distance + edge lengths), " << leftToTheQuery << " left to the full query, " << proofs
            << " batched proofs checked\n";
  EXPECT_LT(worst, 1e-7);
  EXPECT_GT(compared, 3800);
  EXPECT_GT(leftToTheQuery, 50);
  EXPECT_GT(proofs, 1000);
}

TEST(SelfCollisionQuery, NoHitProvesHalfTheThreshold) {
  // Separated pairs approaching to just above the threshold: no hit is allowed only when
  // the distance stays above half of it, which the sampled minimum checks.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> real(-1, 1);
  int checked = 0;
  for (int k = 0; k < 1000; ++k) {
    Query q;
    q.vertexTriangle = k % 2 == 0;
    for (auto& vertex : q.x)
      for (V& p : vertex) p = V(real(rng), real(rng), real(rng));
    const double threshold = 0.05;
    const PrimitiveContact c = ask(q, threshold);
    if (c.hit) continue;
    ++checked;
    EXPECT_GE(trueMinimum(q), L(0.5 * threshold) * (1 - 1e-9L)) << "query " << k;
  }
  EXPECT_GT(checked, 100);
}

TEST(SelfCollisionOptions, BadValuesAreRefusedByField) {
  const auto refuses = [](SelfCollisionOptions o, const std::string& field) {
    try {
      validateSelfCollision(o);
      ADD_FAILURE() << field << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("self_collision." + field), std::string::npos) << e.what();
    }
  };
  SelfCollisionOptions o;
  o.thickness = 0;
  refuses(o, "thickness");
  o.thickness = std::nan("");
  refuses(o, "thickness");
  o = {};
  o.friction = -0.1;
  refuses(o, "friction");
  o = {};
  o.iterations = 0;
  refuses(o, "iterations");
  o.iterations = 65;
  refuses(o, "iterations");
  o = {};
  o.maxCandidatesPerTriangle = 0;
  refuses(o, "maxCandidatesPerTriangle");
  o.maxCandidatesPerTriangle = (1 << 20) + 1;
  refuses(o, "maxCandidatesPerTriangle");
  o.maxCandidatesPerTriangle = 1 << 20;
  EXPECT_NO_THROW(validateSelfCollision(o));
  EXPECT_NO_THROW(validateSelfCollision(SelfCollisionOptions{}));
}

TEST(SelfCollisionScene, BadSectionIsRefusedWithItsPath) {
  const auto message = [](const std::string& section) {
    try {
      (void)parseScene(R"({"bodies":[{"type":"cloth_grid","width":4,"height":4}],"dt":0.001,"steps":1,)" + section +
                       "}");
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message(R"("self_collision":{"thickness":-1})").find("self_collision.thickness"), std::string::npos)
      << message(R"("self_collision":{"thickness":-1})");
  EXPECT_NE(message(R"("self_collision":{"iterations":0})").find("self_collision.iterations"), std::string::npos);
  EXPECT_NE(message(R"("self_collision":{"thikness":0.01})").find("thikness"), std::string::npos);
  EXPECT_NE(message(R"("self_collision":{"friction":"high"})").find("self_collision.friction"), std::string::npos);
  EXPECT_NE(message(R"("self_collision":{"max_candidates_per_triangle":0})")
                .find("self_collision.max_candidates_per_triangle: must be in [1, 1048576], got 0"),
            std::string::npos)
      << message(R"("self_collision":{"max_candidates_per_triangle":0})");
  EXPECT_NE(message(R"("self_collision":{"max_candidates_per_triangle":2.5})").find("max_candidates_per_triangle"),
            std::string::npos);
  const SceneSpec ok = parseScene(
      R"({"bodies":[{"type":"cloth_grid","width":4,"height":4}],"dt":0.001,"steps":1,"self_collision":{"thickness":0.003}})");
  EXPECT_TRUE(ok.simulation.selfCollision.enabled);
  EXPECT_EQ(ok.simulation.selfCollision.thickness, 0.003);
}

TEST(SelfCollisionOptions, ParticleThicknessIsCheckedPerValueSizeAndTriangle) {
  ModelAndState<double> flag = makeFlag<double>(9);  // 1 m: spacing 0.125 m, altitude 0.0884 m
  const auto message = [&](const SelfCollisionOptions& o) {
    try {
      validateSelfCollision(o, flag.model, flag.state.x, "self_collision");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  SelfCollisionOptions o;
  o.particleThickness.assign(81, 0.01);
  EXPECT_EQ(message(o), "accepted");
  o.particleThickness[40] = -1;
  EXPECT_NE(message(o).find("self_collision.particleThickness[40] must be finite and > 0 (m), got -1"),
            std::string::npos)
      << message(o);
  o.particleThickness.assign(80, 0.01);
  EXPECT_NE(message(o).find("particleThickness holds 80 values for 81 particles"), std::string::npos) << message(o);
  o.particleThickness.assign(81, 0.01);
  o.particleThickness[40] = 0.1;  // thicker than the triangles around particle 40 are high
  EXPECT_NE(message(o).find("self_collision.particleThickness[40] = 0.1 m must be below the altitude"),
            std::string::npos)
      << message(o);
  // From a scene file the field is the body's.
  const auto sceneMessage = [](const std::string& bodies, const std::string& rest) {
    try {
      (void)assembleScene<double>(parseScene(R"({"bodies":[)" + bodies + R"(],"dt":0.001,"steps":1)" + rest + "}"));
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string lower = R"({"type":"cloth_grid","name":"lower","width":5,"height":5})";
  const std::string self = R"(,"self_collision":{"thickness":0.01})";
  EXPECT_EQ(sceneMessage(lower + R"(,{"type":"cloth_grid","name":"upper","width":5,"height":5,"origin":[0,0.1,0],)"
                                 R"("self_collision_thickness":0.05})",
                         self),
            "accepted");
  std::string m = sceneMessage(
      lower + R"(,{"type":"cloth_grid","name":"upper","width":5,"height":5,"self_collision_thickness":0.5})", self);
  EXPECT_NE(m.find("bodies[1] (upper).self_collision_thickness = 0.5 m must be below the altitude"), std::string::npos)
      << m;
  m = sceneMessage(R"({"type":"cloth_grid","width":5,"height":5,"self_collision_thickness":0.01})", "");
  EXPECT_NE(m.find("bodies[0].self_collision_thickness: needs a self_collision section"), std::string::npos) << m;
  m = sceneMessage(R"({"type":"cloth_grid","width":5,"height":5,"self_collision_thickness":-2})", self);
  EXPECT_NE(m.find("self_collision_thickness"), std::string::npos) << m;
  EXPECT_NE(m.find("-2"), std::string::npos) << m;
  m = sceneMessage(R"({"type":"rope","self_collision_thickness":0.01})", self);
  EXPECT_NE(m.find("self_collision_thickness"), std::string::npos) << m;
}

// A thickness at or above the smallest altitude of the cloth's triangles would make
// neighbours layers (and every neighbour a contact): refused before any step, by the
// Simulation and by scene assembly, naming the field, the value and the triangle.
TEST(SelfCollisionOptions, ThicknessAboveTheTrianglesAltitudeIsRefused) {
  ModelAndState<double> flag = makeFlag<double>(9);  // 1 m: spacing 0.125 m, altitude 0.0884 m
  auto model = std::make_shared<const Model<double>>(std::move(flag.model));
  SimulationOptions o;
  o.selfCollision.enabled = true;
  o.selfCollision.thickness = 0.09;
  try {
    Simulation<double> sim(model, flag.state, o);
    ADD_FAILURE() << "a thickness of 0.09 m on a 0.125 m grid was accepted";
  } catch (const std::invalid_argument& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("SimulationOptions.selfCollision.thickness = 0.09"), std::string::npos) << m;
    EXPECT_NE(m.find("altitude"), std::string::npos) << m;
    EXPECT_NE(m.find("0.0883883"), std::string::npos) << m;
  }
  o.selfCollision.thickness = 0.088;
  EXPECT_NO_THROW(Simulation<double>(model, flag.state, o));
  // The input the scene fuzzer found: a 5 m thickness on a 1 m cloth (one step took seconds).
  std::ifstream in(std::string(WEFT_SOURCE_DIR) + "/tests/fuzz/regressions/self-collision-thicker-than-the-cloth.json");
  ASSERT_TRUE(in);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const SceneSpec spec = parseScene(text, "thick.json");
  for (int precision = 0; precision < 2; ++precision) {
    try {
      if (precision == 0)
        (void)assembleScene<float>(spec);
      else
        (void)assembleScene<double>(spec);
      ADD_FAILURE() << "the scene was assembled";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("self_collision.thickness = 5.004 m"), std::string::npos) << e.what();
    }
  }
}

TEST(SurfaceTopology, EveryEdgeAndVertexIsOwnedOnce) {
  const ModelAndState<double> flag = makeFlag<double>(5);
  const Model<double>& m = flag.model;
  const SurfaceTopology& topo = m.surfaceTopology();
  const Index t = m.triangleCount();
  // A 5 x 5 grid: 4 x 5 x 2 sides along rows and columns, 16 diagonals.
  EXPECT_EQ(topo.edges.size(), 56u);
  std::vector<int> edgeSeen(topo.edges.size(), 0), vertexSeen(static_cast<size_t>(m.particleCount()), 0);
  for (Index k = 0; k < t; ++k) {
    for (Index e = topo.ownedEdges.begin(k); e < topo.ownedEdges.end(k); ++e) ++edgeSeen[topo.ownedEdges.entries[e]];
    for (Index v = topo.ownedVertices.begin(k); v < topo.ownedVertices.end(k); ++v)
      ++vertexSeen[topo.ownedVertices.entries[v]];
  }
  for (int s : edgeSeen) EXPECT_EQ(s, 1);
  for (int s : vertexSeen) EXPECT_EQ(s, 1);
  const int before = m.derivedBuildCount();
  (void)m.surfaceTopology();
  EXPECT_EQ(m.derivedBuildCount(), before) << "computed once";
}

/// A built-in scene, small, with self-collision on or off.
template <class S>
Simulation<S> makeScene(const std::string& name, Index size, bool self, int threads = 2) {
  SceneSpec spec = builtinSceneSpec(name, size);
  spec.simulation.selfCollision.enabled = self;
  AssembledScene<S> a = assembleScene<S>(spec);
  a.options.threads = threads;
  return Simulation<S>(std::move(a.built), a.options);
}

// A step far too long for the integrator: the collision response moves particles after
// the integrator's result was checked, and what it makes is checked too. Here it stretches
// a spring past the limit, and the step fails (the state as it was) instead of reporting
// ok with a spring eleven times its rest length.
TEST(SelfCollision, AResponseThatOverstretchesFailsTheStep) {
  WEFT_SKIP_UNDER_TSAN("it runs on one thread");
  SceneSpec spec = builtinSceneSpec("fold", 16);
  spec.simulation.integrator = IntegratorKind::Rk45;
  spec.simulation.dt = 10;
  AssembledScene<double> a = assembleScene<double>(spec);
  a.options.threads = 1;
  Simulation<double> sim(std::move(a.built), a.options);
  const std::uint64_t before = stateHash(sim.state());
  const StepStatus s = sim.step();
  EXPECT_EQ(s.code, StepCode::Overstretched) << s.message();
  EXPECT_GT(sim.lastCollision().rollbacks + sim.lastSelfCollision().contacts, 0) << "the step was split or responded";
  EXPECT_EQ(stateHash(sim.state()), before);
  EXPECT_EQ(sim.state().time, 0.0);
  EXPECT_EQ(s.time, 0.0);
  EXPECT_EQ(sim.stepCount(), 0);
}

// Two cloths inside a sphere of radius 1e12 m: the first chunk pushes every particle out
// 1e12 m, the swept boxes of all the triangles overlap, and listing the candidates would
// take all 2.2 million pairs (then tens of millions of exact tests per pass). The gathering
// stops at the limit instead, and the step fails at once with the state as it was, the same
// on one thread and two.
TEST(SelfCollision, ACloudOfCandidatesFailsTheStepAtOnce) {
  const std::string text = R"({"name": "swallowed", "dt": 2e-4, "steps": 3, "integrator": "rk4",
      "bodies": [{"type": "cloth_grid", "width": 24, "height": 24, "origin": [-0.5, 0.5, -0.5],
                  "row_axis": [1, 0, 0], "column_axis": [0, 0, 1], "total_mass": 0.5},
                 {"type": "cloth_grid", "width": 24, "height": 24, "origin": [-0.5, 0.51, -0.5],
                  "row_axis": [1, 0, 0], "column_axis": [0, 0, 1], "total_mass": 0.5}],
      "collision": {"obstacles": [{"type": "sphere", "center": [0, 0, 0], "radius": 1e12}]},
      "self_collision": {"thickness": 0.004}})";
  std::vector<std::uint64_t> hashes;
  for (const int threads : {1, 2}) {
    if (weft::test::kThreadSanitizer && threads == 1) continue;
    AssembledScene<double> a = assembleScene<double>(parseScene(text));
    a.options.threads = threads;
    Simulation<double> sim(std::move(a.built), a.options);
    ASSERT_EQ(sim.model().triangleCount(), 2116);
    const std::uint64_t before = stateHash(sim.state());
    const StepStatus s = sim.step();
    ASSERT_EQ(s.code, StepCode::TooManyCandidates) << s.message();
    EXPECT_EQ(s.value, 256);
    EXPECT_EQ(s.time, 0.0);
    EXPECT_NE(s.message().find("more than 256 candidate pairs per triangle"), std::string::npos) << s.message();
    EXPECT_NE(s.message().find("maxCandidatesPerTriangle"), std::string::npos) << s.message();
    EXPECT_STREQ(stepCodeName(s.code), "too-many-candidates");
    EXPECT_EQ(stateHash(sim.state()), before);
    EXPECT_EQ(sim.state().time, 0.0);
    EXPECT_EQ(sim.stepCount(), 0);
    EXPECT_EQ(sim.lastCollision().rollbacks, CollisionOptions{}.maxHalvings) << "every halving tried first";
    EXPECT_EQ(sim.step().code, StepCode::TooManyCandidates);  // refuses until something changes
    hashes.push_back(stateHash(sim.state()));
  }
  for (const std::uint64_t h : hashes) EXPECT_EQ(h, hashes.front());
}

// A cloth flying 0.85 m a step, 27 of its spacings, unculled: the step's swept boxes
// overlap about 780 others' per triangle, past the limit, so the chunk is halved and the
// halves pass (the count falls with the square of the chunk). The step is not failed, and
// it is faster than listing them all.
TEST(SelfCollision, AFastClothHalvesItsChunkInsteadOfFailing) {
  WEFT_SKIP_UNDER_TSAN("it runs on one thread");
  const auto run = [](int limit) {
    const std::string text = R"({"name": "fast", "dt": 0.01, "steps": 3, "integrator": "implicit",
      "bodies": [{"type": "cloth_grid", "width": 33, "height": 33, "origin": [-0.5, 0.5, -0.5],
                  "row_axis": [1, 0, 0], "column_axis": [0, 0, 1], "total_mass": 0.5, "velocity": [60, 0, 60]}],
      "self_collision": {"thickness": 0.004, "cull_flat_regions": false, "max_candidates_per_triangle": )" +
                             std::to_string(limit) + "}}";
    AssembledScene<double> a = assembleScene<double>(parseScene(text));
    a.options.threads = 1;
    Simulation<double> sim(std::move(a.built), a.options);
    const StepStatus s = sim.run(3);
    EXPECT_TRUE(s.ok()) << s.message();
    EXPECT_EQ(sim.selfIntersectionCount(), 0);
    return std::make_pair(sim.totalCollision().rollbacks, sim.totalSelfCollision());
  };
  const auto [halved, halvedStats] = run(256);
  const auto [whole, wholeStats] = run(1 << 20);
  EXPECT_EQ(whole, 0);
  EXPECT_GE(halved, 1);
  const std::int64_t triangles = 2 * 32 * 32;
  EXPECT_GT(wholeStats.candidates, 256 * triangles * wholeStats.rebuilds) << "the whole step is past the limit";
  EXPECT_LE(halvedStats.candidates, 256 * triangles * halvedStats.rebuilds);
}

// The limit is of the gathering's list: the built-in fold, which keeps about 3 candidate
// pairs per triangle, runs with a limit of 16 and fails with one of 1.
TEST(SelfCollision, TheCandidateLimitIsPerTriangleOfTheGathering) {
  WEFT_SKIP_UNDER_TSAN("it runs on one thread");
  for (const int limit : {16, 1}) {
    SceneSpec spec = builtinSceneSpec("fold", 16);
    spec.simulation.selfCollision.maxCandidatesPerTriangle = limit;
    AssembledScene<double> a = assembleScene<double>(spec);
    a.options.threads = 1;
    Simulation<double> sim(std::move(a.built), a.options);
    const StepStatus s = sim.run(std::llround(0.8 / spec.simulation.dt));
    if (limit == 16) {
      EXPECT_TRUE(s.ok()) << s.message();
      EXPECT_GT(sim.totalSelfCollision().candidates, 0);
      EXPECT_LE(sim.totalSelfCollision().candidates,
                16 * sim.model().triangleCount() * sim.totalSelfCollision().rebuilds);
    } else {
      EXPECT_EQ(s.code, StepCode::TooManyCandidates) << s.message();
      EXPECT_EQ(s.value, 1);
    }
  }
}

struct HardScene {
  const char* name;
  Index size;
  double seconds;  // how long the test runs it
};

// Small versions, long enough to fold, stack, wring or wrap.
const HardScene kHardScenes[] = {
    {"fold", 12, 1.2}, {"two-cloths", 10, 1.2}, {"twist", 10, 2.0}, {"flag-pole", 12, 2.0}};

// Under a sanitizer (10-20x slower) the exact check runs after every 5th step: the
// Release build checks every step, the sanitizers look for memory and threading errors.
constexpr Index kCheckEvery = weft::test::kSanitized ? 5 : 1;

// What the tests of the scenes below name when ThreadSanitizer skips them.
constexpr const char* kSameBitsTest =
    "SelfCollisionScenes.OneAndTwoThreadsGiveTheSameBits runs the same passes on 1 and 2 threads";

template <class S>
void expectNeverIntersects(const HardScene& scene) {
  Simulation<S> sim = makeScene<S>(scene.name, scene.size, true);
  ASSERT_EQ(sim.selfIntersectionCount(), 0) << "the scene starts intersecting";
  const Index steps = static_cast<Index>(std::ceil(scene.seconds / sim.timeStep()));
  std::int64_t worst = 0;
  for (Index k = 0; k < steps; ++k) {
    const StepStatus status = sim.step();
    ASSERT_TRUE(status.ok()) << scene.name << " step " << k << ": " << status.message();
    if ((k + 1) % kCheckEvery != 0 && k + 1 != steps) continue;
    const std::int64_t pairs = sim.selfIntersectionCount();
    if (pairs > 0 && worst == 0) ADD_FAILURE() << scene.name << ": " << pairs << " intersecting pairs after step " << k;
    worst = std::max(worst, pairs);
  }
  EXPECT_EQ(worst, 0);
  EXPECT_GT(sim.totalSelfCollision().contacts, 0) << scene.name << " never brought the cloth into contact with itself";
  EXPECT_EQ(sim.totalSelfCollision().unresolved, 0);
}

/// One chunk of the self-collision pass on `built` moving by `shift` (m, the same for every
/// particle), with flat regions culled or not: the candidates gathered and the pass's findings.
template <class S>
std::pair<Index, SelfCollisionStats> oneChunk(const ModelAndState<S>& built, bool cull, const Vec3<S>& shift,
                                              Vec3Array<S>* x1Out = nullptr) {
  Executor exec(2);
  SelfCollisionOptions options;
  options.enabled = true;
  options.cullFlatRegions = cull;
  SelfCollider<S> collider(built.model, options, built.state.x, exec);
  const Vec3Array<S>& x0 = built.state.x;
  Vec3Array<S> x1 = x0, v1 = built.state.v;
  for (int a = 0; a < 3; ++a) x1.col(a).array() += shift[a];
  const ScalarArray<S> w = ScalarArray<S>::Ones(built.model.particleCount());
  const SelfCollisionStats stats = collider.resolve(x0, x1, v1, w, 1e-3, exec);
  if (x1Out) *x1Out = x1;
  return {collider.candidateCount(), stats};
}

/// A size x size cloth of spacing 0.1 m lying flat at y = 5 mm (on a floor, say).
ClothGridSpec smallGrid(Index size) {
  ClothGridSpec spec;
  spec.width = spec.height = size;
  spec.spacing = 0.1;
  spec.origin = {0, 0.005, 0};
  return spec;
}

/// ContactSolver::supports for n particles: normal m for those in [begin, end), zero elsewhere.
std::vector<double> supportsOf(Index n, Index begin, Index end, const Eigen::Vector3d& m = {0, 1, 0}) {
  std::vector<double> supports(3 * static_cast<size_t>(n), 0.0);
  for (Index i = begin; i < end; ++i)
    for (int a = 0; a < 3; ++a) supports[3 * static_cast<size_t>(i) + static_cast<size_t>(a)] = m[a];
  return supports;
}

/// Two 4 x 4 cloths of spacing 0.1 m, the upper one shifted by half a spacing: the lower
/// lies at y = 5 mm (on a floor, say), the upper comes down from 9 to 7.5 mm over the chunk
/// at 1 m/s, within the 4 mm thickness of the lower one. Particles [0, 16) are the lower
/// cloth's.
struct TwoLayers {
  ModelAndState<double> built;
  Vec3Array<double> x1, v1;
  ScalarArray<double> w;
  static constexpr Index kLower = 16;
};
TwoLayers twoLayers() {
  ModelBuilder<double> b;
  ClothGridSpec spec = smallGrid(4);
  addClothGrid(b, spec);
  spec.origin = {0.05, 0.009, 0.05};
  addClothGrid(b, spec);
  TwoLayers t{b.build(), {}, {}, {}};
  t.x1 = t.built.state.x;
  t.v1 = t.built.state.v;
  for (Index i = TwoLayers::kLower; i < t.built.model.particleCount(); ++i) {
    t.x1(i, 1) -= 0.0015;
    t.v1(i, 1) = -1.0;
  }
  t.w = ScalarArray<double>::Ones(t.built.model.particleCount());
  return t;
}

TEST(SelfCollisionResponse, AClothOnAnObstacleIsNotPushedIntoIt) {
  // The lower cloth rests on an obstacle of normal m (supports): the response moves it only
  // in the obstacle's tangent plane, the upper one takes the whole push and separates to
  // the thickness. For a floor (m = y) and a slope (m tilted by 30 degrees).
  const double tilt = std::sin(M_PI / 6);
  for (const Eigen::Vector3d& m : {Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(tilt, std::sqrt(1 - tilt * tilt), 0)}) {
    TwoLayers t = twoLayers();
    const Index n = t.built.model.particleCount();
    const std::vector<double> supports = supportsOf(n, 0, TwoLayers::kLower, m);
    Executor exec(2);
    SelfCollisionOptions options;
    options.enabled = true;
    SelfCollider<double> collider(t.built.model, options, t.built.state.x, exec);
    const Vec3Array<double> before = t.x1, vBefore = t.v1;
    const SelfCollisionStats stats = collider.resolve(t.built.state.x, t.x1, t.v1, t.w, 1e-3, exec, supports.data());
    EXPECT_GT(stats.contacts, 0);
    EXPECT_EQ(stats.frozen, 0) << "the response alone separates the layers";
    for (Index i = 0; i < TwoLayers::kLower; ++i) {
      const Eigen::Vector3d dx = (t.x1.row(i) - before.row(i)).transpose();
      const Eigen::Vector3d dv = (t.v1.row(i) - vBefore.row(i)).transpose();
      EXPECT_GE(dx.dot(m), -1e-12) << "particle " << i << " moved into its obstacle, m = " << m.transpose();
      EXPECT_GE(dv.dot(m), -1e-12) << "particle " << i << " sped into its obstacle, m = " << m.transpose();
    }
    // The upper cloth takes the push: over the lower one's triangles it ends close to the
    // thickness above them (it came to 2.5 mm), and most of its 1 m/s approach is stopped
    // (the response's passes, not the supports, leave the rest; without supports these
    // particles end 3.7-3.9 mm above, approaching at 0.33-0.47 m/s).
    for (Index i = TwoLayers::kLower; i < n; ++i) {
      const Index r = (i - TwoLayers::kLower) / 4, c = (i - TwoLayers::kLower) % 4;
      if (r == 3 || c == 3) continue;  // beyond the lower cloth's border
      double below = -1;               // the lower cloth's highest particle (it moved within its tangent plane)
      for (Index j = 0; j < TwoLayers::kLower; ++j) below = std::max(below, t.x1(j, 1));
      EXPECT_GT(t.x1(i, 1) - below, 0.0038) << "m: particle " << i << ", m = " << m.transpose();
      EXPECT_GT(t.v1(i, 1), -0.2) << "m/s: particle " << i << ", m = " << m.transpose();
    }
  }
}

TEST(SelfCollisionResponse, ASupportTheResponsePushesAwayFromChangesNothing) {
  // The upper cloth rests on an obstacle below it too (m = y, say a shelf it overhangs):
  // every push and impulse moves it away from that obstacle, so the supports block nothing,
  // and the response (friction off) is the same bits as without supports, its take-backs
  // included.
  TwoLayers with = twoLayers(), without = twoLayers();
  const Index n = with.built.model.particleCount();
  const std::vector<double> supports = supportsOf(n, TwoLayers::kLower, n);
  Executor exec(2);
  SelfCollisionOptions options;
  options.enabled = true;
  options.friction = 0;
  SelfCollider<double> a(with.built.model, options, with.built.state.x, exec);
  SelfCollider<double> b(without.built.model, options, without.built.state.x, exec);
  const SelfCollisionStats sa = a.resolve(with.built.state.x, with.x1, with.v1, with.w, 1e-3, exec, supports.data());
  const SelfCollisionStats sb = b.resolve(without.built.state.x, without.x1, without.v1, without.w, 1e-3, exec);
  EXPECT_GT(sa.contacts, 0);
  EXPECT_EQ(sa.contacts, sb.contacts);
  for (Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(with.x1(i, c), without.x1(i, c)) << "particle " << i << " axis " << c;
      EXPECT_EQ(with.v1(i, c), without.v1(i, c)) << "particle " << i << " axis " << c;
    }
}

TEST(SelfCollisionResponse, APinnedClothPressingOneOnAnObstacleStillSeparates) {
  // The upper cloth pinned (w = 0) and the lower on a floor: no side can take the push
  // along n, so the supports are ignored for these contacts (the floor pushes back in its
  // next chunk) rather than the contacts being dropped.
  TwoLayers t = twoLayers();
  const Index n = t.built.model.particleCount();
  const std::vector<double> supports = supportsOf(n, 0, TwoLayers::kLower);
  for (Index i = TwoLayers::kLower; i < n; ++i) t.w[i] = 0;
  Executor exec(2);
  SelfCollisionOptions options;
  options.enabled = true;
  SelfCollider<double> collider(t.built.model, options, t.built.state.x, exec);
  const SelfCollisionStats stats = collider.resolve(t.built.state.x, t.x1, t.v1, t.w, 1e-3, exec, supports.data());
  EXPECT_GT(stats.contacts, 0);
  EXPECT_EQ(stats.frozen, 0);
  double lowestUpper = 1, highestLower = -1;
  for (Index i = 0; i < TwoLayers::kLower; ++i) highestLower = std::max(highestLower, t.x1(i, 1));
  for (Index i = TwoLayers::kLower; i < n; ++i) lowestUpper = std::min(lowestUpper, t.x1(i, 1));
  EXPECT_LT(highestLower, 0.005 - 1e-4) << "m: the lower cloth gives way";
  EXPECT_GT(lowestUpper - highestLower, 0.0035) << "m apart (they came to 2.5 mm)";
}

TEST(SelfCollisionResponse, FrictionOnAClothLyingOnAnObstacleDoesNotReverseTheSliding) {
  // One corner of a steep upper cloth comes down over the middle of a lower cloth's triangle
  // (one vertex-triangle contact) while sliding along x at 2 cm/s; the lower cloth rests on a
  // floor. Friction strong enough to stop the sliding stops it: the corner moves with the
  // lower cloth afterwards, not the other way (friction shared like the push, which the
  // blocked lower corners do not take, would give the pair 1 + sum b_i^2 times the change).
  ModelBuilder<double> b;
  ClothGridSpec spec = smallGrid(2);
  addClothGrid(b, spec);
  const Index corner = b.particleCount();
  spec.origin = {0.03, 0.0085, 0.06};
  spec.rowAxis = {1, 1, 0};
  spec.columnAxis = {0, 1, 1};
  addClothGrid(b, spec);
  ModelAndState<double> built = b.build();
  const Index n = built.model.particleCount();
  Vec3Array<double> x1 = built.state.x, v1 = built.state.v;
  for (Index i = corner; i < n; ++i) {
    x1(i, 1) -= 0.001;
    v1(i, 1) = -1.0;
    v1(i, 0) = 0.02;
  }
  const ScalarArray<double> w = ScalarArray<double>::Ones(n);
  const std::vector<double> supports = supportsOf(n, 0, corner);
  Executor exec(2);
  SelfCollisionOptions options;
  options.enabled = true;
  options.friction = 1.0;
  SelfCollider<double> collider(built.model, options, built.state.x, exec);
  const SelfCollisionStats stats = collider.resolve(built.state.x, x1, v1, w, 1e-3, exec, supports.data());
  ASSERT_GT(stats.contacts, 0);
  EXPECT_EQ(stats.vertexTriangle, stats.contacts) << "vertex-triangle contacts only";
  // The lower cloth's velocity under the corner: barycentric over the triangle below it.
  double lower = std::numeric_limits<double>::quiet_NaN();
  const Triangles& tr = built.model.triangles();
  for (Index t = 0; t < built.model.triangleCount(); ++t) {
    const Index c[3] = {tr.a[t], tr.b[t], tr.c[t]};
    if (c[0] >= corner || c[1] >= corner || c[2] >= corner) continue;
    const auto at = [&](Index i) { return Eigen::Vector2d(x1(i, 0), x1(i, 2)); };
    const Eigen::Vector2d p = at(corner), e1 = at(c[1]) - at(c[0]), e2 = at(c[2]) - at(c[0]);
    Eigen::Matrix2d m;
    m << e1, e2;
    const Eigen::Vector2d uv = m.inverse() * (p - at(c[0]));
    if (uv.minCoeff() < 0 || uv.sum() > 1) continue;
    lower = (1 - uv.sum()) * v1(c[0], 0) + uv[0] * v1(c[1], 0) + uv[1] * v1(c[2], 0);
  }
  ASSERT_TRUE(std::isfinite(lower)) << "no lower triangle under the corner";
  EXPECT_NEAR(v1(corner, 0) - lower, 0.0, 1e-9) << "m/s: the corner's sliding over the lower cloth";
  for (Index j = 0; j < corner; ++j) EXPECT_GE(x1(j, 1), 0.005 - 1e-15) << "lower " << j;
}

TEST(SelfCollisionCulling, AFlatOrGentlyCurvedClothGathersNoCandidates) {
  for (const bool curved : {false, true}) {
    ModelAndState<double> built = makeFlag<double>(32);
    if (curved)  // a quarter of a cylinder of radius 0.7 m: 82 degrees of normals
      for (Index i = 0; i < built.model.particleCount(); ++i) {
        const double z = static_cast<double>(i / 32) / 31, angle = z / 0.7;
        built.state.x(i, 0) = static_cast<double>(i % 32) / 31;
        built.state.x(i, 2) = 0.7 * std::sin(angle);
        built.state.x(i, 1) = 0.7 * (1 - std::cos(angle));
      }
    const auto [culled, culledStats] = oneChunk(built, true, Vec3<double>(0, -2e-4, 0));
    const auto [all, allStats] = oneChunk(built, false, Vec3<double>(0, -2e-4, 0));
    EXPECT_EQ(culled, 0) << (curved ? "curved" : "flat");
    EXPECT_GT(all, 0);
    EXPECT_EQ(culledStats.contacts, 0);
    EXPECT_EQ(allStats.contacts, 0);
  }
}

TEST(SelfCollisionCulling, LayersOfOneOrTwoClothsAreNeverCulledAgainstEachOther) {
  // Two flat cloths 3 mm apart (normals alike: one cone), and one cloth folded flat onto
  // itself (a U of two layers 3 mm apart): each layer is flat, the pairs between layers
  // are not, and the pass finds the same contacts and moves the cloth the same with
  // culling as without.
  for (const bool folded : {false, true}) {
    ModelAndState<double> built;
    if (folded) {
      built = makeFlag<double>(33);
      const double spacing = 1.0 / 32, r = 0.0015;
      for (Index row = 0; row < 33; ++row) {
        const double s = row * spacing;  // along the cloth; folded at s = 0.5 around a half circle
        double y = 0, z = s;
        if (s > 0.5) {
          const double past = s - 0.5;
          const double angle = std::min(past / r, M_PI);
          z = 0.5 + r * std::sin(angle) - std::max(0.0, past - M_PI * r);
          y = r - r * std::cos(angle);
        }
        for (Index c = 0; c < 33; ++c) {
          built.state.x(row * 33 + c, 0) = c * spacing;
          built.state.x(row * 33 + c, 1) = y;
          built.state.x(row * 33 + c, 2) = z;
        }
      }
    } else {
      ModelBuilder<double> b;
      ClothGridSpec spec = flagSpec(16);
      spec.origin = {0, 0, 0};
      addClothGrid(b, spec);
      spec.origin = {0.5 * spec.spacing, 0.003, 0.5 * spec.spacing};
      addClothGrid(b, spec);
      built = b.build();
    }
    Vec3Array<double> culledX, allX;
    const auto [culled, culledStats] = oneChunk(built, true, Vec3<double>(0, 0, 0), &culledX);
    const auto [all, allStats] = oneChunk(built, false, Vec3<double>(0, 0, 0), &allX);
    EXPECT_GT(culledStats.contacts, 0) << (folded ? "folded" : "two cloths");
    EXPECT_LT(culled, all);
    EXPECT_EQ(culledStats.contacts, allStats.contacts);
    EXPECT_EQ(culledStats.vertexTriangle, allStats.vertexTriangle);
    EXPECT_EQ(stateHash(State<double>{culledX, culledX, 0}), stateHash(State<double>{allX, allX, 0}));
  }
}

/// A size x size 1 m cloth folded flat onto itself at its middle row: a U of two layers
/// 2 r apart joined by a half circle of radius r.
ModelAndState<double> foldedInTwo(Index size, double r) {
  ModelAndState<double> built = makeFlag<double>(size);
  const double spacing = 1.0 / static_cast<double>(size - 1);
  for (Index row = 0; row < size; ++row) {
    const double s = row * spacing, past = s - 0.5, angle = std::min(std::max(past, 0.0) / r, M_PI);
    const double y = s > 0.5 ? r - r * std::cos(angle) : 0.0;
    const double z = s > 0.5 ? 0.5 + r * std::sin(angle) - std::max(0.0, past - M_PI * r) : s;
    for (Index c = 0; c < size; ++c) built.state.x.row(row * size + c) << c * spacing, y, z;
  }
  return built;
}

/// A self-collision pass with the default options (flat regions culled) on `built`, on 2
/// threads, every particle free.
struct CulledPass {
  static SelfCollisionOptions enabled() {
    SelfCollisionOptions o;
    o.enabled = true;
    // These passes are called directly, on chunks that carry the cloth up to 0.4 m (13 of
    // its spacings): no Simulation halves a chunk past the candidate limit, so there is none.
    o.maxCandidatesPerTriangle = 1 << 20;
    return o;
  }
  explicit CulledPass(const ModelAndState<double>& built)
      : collider(built.model, enabled(), built.state.x, exec),
        w(ScalarArray<double>::Ones(built.model.particleCount())) {}
  Executor exec{2};
  SelfCollider<double> collider;
  ScalarArray<double> w;
};

TEST(SelfCollisionCulling, ACarriedClothKeepsItsCandidatesAndFindsWhatAFreshPassFinds) {
  // Two layers 3 mm apart (the 4 mm thickness: in contact), carried 0.4 m a chunk while
  // sagging 0.1 mm: the list still covers the chunks (the centroid's motion is allowed
  // for), and the pass finds the contacts, and moves the cloth to the bits, that a fresh
  // pass without culling does.
  const ModelAndState<double> built = foldedInTwo(33, 0.0015);
  CulledPass pass(built);
  Vec3Array<double> x0 = built.state.x, x1 = x0, v1 = built.state.v;
  x1.col(1).array() -= 1e-4;
  const SelfCollisionStats first = pass.collider.resolve(x0, x1, v1, pass.w, 1e-3, pass.exec);
  EXPECT_GE(first.rebuilds, 1);
  EXPECT_GT(first.contacts, 0);
  // Each next chunk starts where the last ended: carried by (0.3, -0.2, 0.2) m, carried as
  // far again (x0 already far from where the list was gathered), then carried and sheared
  // by 5 mm across the cloth (more than the skin: it must gather again). Each finds the
  // contacts, and moves the cloth to the bits, of a fresh pass without culling.
  SelfCollisionOptions unculled = pass.collider.options();
  unculled.cullFlatRegions = false;
  for (int chunk = 0; chunk < 3; ++chunk) {
    x0 = x1;
    x1.col(0).array() += 0.3;
    x1.col(1).array() -= 0.2 + 1e-4;
    x1.col(2).array() += 0.2;
    if (chunk == 2)
      for (Index i = 0; i < built.model.particleCount(); ++i) x1(i, 0) += 0.005 * static_cast<double>(i / 33) / 32;
    Vec3Array<double> freshX1 = x1, freshV1 = v1;
    const SelfCollisionStats stats = pass.collider.resolve(x0, x1, v1, pass.w, 1e-3, pass.exec);
    if (chunk < 2) {
      EXPECT_EQ(stats.rebuilds, 0) << "chunk " << chunk << ": the carried cloth gathered its candidates again";
    } else {
      EXPECT_GE(stats.rebuilds, 1) << "the sheared cloth kept its candidates";
    }
    SelfCollider<double> fresh(built.model, unculled, x0, pass.exec);
    const SelfCollisionStats reference = fresh.resolve(x0, freshX1, freshV1, pass.w, 1e-3, pass.exec);
    EXPECT_GT(reference.contacts, 0) << "chunk " << chunk;
    EXPECT_EQ(stats.contacts, reference.contacts) << "chunk " << chunk;
    EXPECT_EQ(stats.vertexTriangle, reference.vertexTriangle) << "chunk " << chunk;
    EXPECT_EQ(stateHash(State<double>{x1, v1, 0}), stateHash(State<double>{freshX1, freshV1, 0})) << "chunk " << chunk;
  }
}

TEST(SelfCollisionCulling, LayersTheResponsePushesGatherOncePerChunk) {
  // Two layers 2 mm apart (the 4 mm thickness: the response pushes each by about 1 mm,
  // more than the skin), in chunks that start from the same folded cloth sheared by 5 mm
  // more each time (far more than the skin): each chunk gathers new candidates, once. The
  // pushes are about the same in every chunk, and the skin boxes of the pushed vertices
  // cover them; without that, each response pass moved them out of their boxes and the
  // next gathered again.
  const ModelAndState<double> built = foldedInTwo(65, 0.001);
  CulledPass pass(built);
  for (int chunk = 0; chunk < 4; ++chunk) {
    Vec3Array<double> x0 = built.state.x, v1 = built.state.v;
    for (Index i = 0; i < built.model.particleCount(); ++i)
      x0(i, 0) += 0.005 * chunk * static_cast<double>(i / 65) / 64;
    Vec3Array<double> x1 = x0;
    x1.col(1).array() -= 1e-4;
    const SelfCollisionStats stats = pass.collider.resolve(x0, x1, v1, pass.w, 1e-3, pass.exec);
    EXPECT_GT(stats.contacts, 0) << "chunk " << chunk;
    if (chunk > 0) {
      EXPECT_EQ(stats.rebuilds, 1) << "chunk " << chunk;
    }
    EXPECT_EQ(countSelfIntersections(built.model, x1, pass.exec), 0) << "chunk " << chunk;
  }
}

TEST(SelfCollisionScenes, NothingIntersectsAfterAnyStepInDouble) {
  WEFT_SKIP_UNDER_TSAN(kSameBitsTest);
  for (const HardScene& s : kHardScenes) expectNeverIntersects<double>(s);
}

TEST(SelfCollisionScenes, NothingIntersectsAfterAnyStepInFloat) {
  WEFT_SKIP_UNDER_TSAN(kSameBitsTest);
  for (const HardScene& s : kHardScenes) expectNeverIntersects<float>(s);
}

// Two 5 x 5 cloths with every particle pinned: a vertical one that a path moves down (1 m/s,
// dt 1 ms) through a horizontal one.
namespace {
Simulation<double> clothDrivenThroughAnother(bool selfCollision) {
  ModelBuilder<double> b;
  ClothGridSpec lower;
  lower.width = lower.height = 5;
  lower.spacing = 0.1;
  lower.origin = {-0.2, 0, -0.2};
  ClothGridSpec upper = lower;
  upper.origin = {-0.15, 0.05, 0.05};
  upper.columnAxis = {0, 1, 0};
  addClothGrid(b, lower);
  addClothGrid(b, upper);
  for (Index i = 0; i < 50; ++i) b.pin(i);
  SimulationOptions o;
  o.integrator = IntegratorKind::SymplecticEuler;
  o.dt = 1e-3;
  o.threads = 1;
  o.gravity = {0, 0, 0};
  o.selfCollision.enabled = selfCollision;
  KinematicPins down;
  down.path.velocity = {0, -1, 0};
  for (Index i = 25; i < 50; ++i) down.particles.push_back(i);
  o.kinematicPins.push_back(down);
  return Simulation<double>(b.build(), o);
}
}  // namespace

TEST(SelfCollisionScenes, WithoutSelfCollisionTheClothIntersects) {
  WEFT_SKIP_UNDER_TSAN("a check that the scenes are hard; it runs no parallel pass the others do not");
  // The same scenes with the pass off: the check finds intersections, so the scenes are hard.
  int intersecting = 0;
  for (const HardScene& scene : kHardScenes) {
    Simulation<double> sim = makeScene<double>(scene.name, scene.size, false);
    const Index steps = static_cast<Index>(std::ceil(scene.seconds / sim.timeStep()));
    std::int64_t worst = 0;
    for (Index k = 0; k < steps && sim.step().ok(); ++k)
      if (k % 10 == 0) worst = std::max(worst, sim.selfIntersectionCount());
    std::cout << "[ without self-collision ] " << scene.name << ": up to " << worst << " intersecting pairs\n";
    intersecting += worst > 0 ? 1 : 0;
    // What the run says at the end: the pairs there are now, and the option that keeps them apart.
    const std::int64_t now = sim.selfIntersectionCount();
    const std::vector<std::string> warnings = sim.warnings();
    const bool said = std::any_of(warnings.begin(), warnings.end(), [](const std::string& w) {
      return w.find("self-collision is off, so nothing keeps cloth from passing through itself") != std::string::npos;
    });
    EXPECT_EQ(said, now > 0) << scene.name << ": " << now << " pairs at the end";
  }
  EXPECT_GE(intersecting, 3);
}

TEST(SelfCollisionScenes, AClothThatPassedThroughWithSelfCollisionOffIsAWarning) {
  // Nothing keeps cloth apart with the pass off (it costs nothing then); a run that ends
  // with triangles through each other says so, with the count and the option. Before the
  // first step, and at the start of a new state, there is nothing to say.
  Simulation<double> sim = clothDrivenThroughAnother(false);
  EXPECT_TRUE(sim.warnings().empty());
  ASSERT_TRUE(sim.run(200).ok()) << sim.status().message();
  const std::int64_t now = sim.selfIntersectionCount();
  ASSERT_GT(now, 0);
  const std::vector<std::string> warnings = sim.warnings();
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0], std::to_string(now) +
                             " pairs of triangles sharing no particle intersect now: self-collision is off, so nothing "
                             "keeps cloth from passing through itself or through another cloth; turn it on "
                             "(SimulationOptions::selfCollision, \"self_collision\" in a scene file) where cloth "
                             "folds or cloths meet");
  sim.setState(sim.state());
  EXPECT_TRUE(sim.warnings().empty());
  // The same cloths before they meet: a run that ends with none says nothing.
  Simulation<double> apart = clothDrivenThroughAnother(false);
  ASSERT_TRUE(apart.run(20).ok());
  EXPECT_EQ(apart.selfIntersectionCount(), 0);
  EXPECT_TRUE(apart.warnings().empty());
}

TEST(SelfCollisionScenes, AClothDrivenThroughItselfByItsPinsIsAWarning) {
  // The pass cannot stop a pair whose particles are all pinned or moved by a path, so the
  // cloths end intersecting, and the simulation says so and why.
  Simulation<double> sim = clothDrivenThroughAnother(true);
  const State<double> initial = sim.state();
  EXPECT_EQ(sim.startIntersectionCount(), 0);
  EXPECT_TRUE(sim.warnings().empty());
  ASSERT_TRUE(sim.run(200).ok()) << sim.status().message();  // 0.2 m down: across the lower cloth
  const std::int64_t now = sim.selfIntersectionCount();
  ASSERT_GT(now, 0);
  const std::vector<std::string> warnings = sim.warnings();
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0].rfind(std::to_string(now) +
                                  " pairs of triangles intersect now, 0 at the start: the cloth passed through itself "
                                  "although self-collision was on; ",
                              0),
            0u)
      << warnings[0];
  EXPECT_NE(
      warnings[0].find(
          "the pass moves only free particles, so pinned ones that a path moves (or that hold the cloth where it is "
          "pushed) go through it: change the pins or the path"),
      std::string::npos)
      << warnings[0];
  // A new start from there: the pairs are the start's now, said as such.
  sim.setState(sim.state());
  EXPECT_EQ(sim.startIntersectionCount(), now);
  ASSERT_EQ(sim.warnings().size(), 1u);
  EXPECT_EQ(sim.warnings()[0].rfind("the cloth started with " + std::to_string(now) + " pairs of triangles", 0), 0u)
      << sim.warnings()[0];
  // The count is kept until the state changes: another state at the same step count (given,
  // or restored from a checkpoint) is counted afresh.
  const std::string intersecting = sim.checkpoint();
  EXPECT_EQ(sim.selfIntersectionCount(), now);
  sim.setState(initial);
  EXPECT_EQ(sim.selfIntersectionCount(), 0);
  EXPECT_TRUE(sim.warnings().empty());
  sim.restore(intersecting);
  EXPECT_EQ(sim.selfIntersectionCount(), now);
  EXPECT_EQ(sim.startIntersectionCount(), now);
  sim.setState(initial);
  ASSERT_TRUE(sim.run(200).ok());  // the same steps again: the same count after them
  EXPECT_EQ(sim.selfIntersectionCount(), now);
}

TEST(SelfCollisionScenes, OneAndTwoThreadsGiveTheSameBits) {
  for (const HardScene& scene : {kHardScenes[0], kHardScenes[1]}) {
    const char* name = scene.name;
    Simulation<double> one = makeScene<double>(name, scene.size, true, 1);
    Simulation<double> two = makeScene<double>(name, scene.size, true, 2);
    const Index steps = static_cast<Index>(std::ceil(scene.seconds / one.timeStep()));
    ASSERT_TRUE(one.run(steps).ok());
    ASSERT_TRUE(two.run(steps).ok());
    EXPECT_GT(one.totalSelfCollision().contacts, 0) << name;
    EXPECT_EQ(stateHash(one.state()), stateHash(two.state())) << name;
    EXPECT_EQ(one.totalSelfCollision().contacts, two.totalSelfCollision().contacts) << name;
  }
}

/// A smaller cloth (8 x 8) over a larger one (12 x 12) lying 1 cm above a floor, shifted by
/// half a spacing so that no vertex is above another, the upper one `drop` m above the
/// lower; self-collision on. `upperThickness` > 0: the upper cloth's own thickness.
struct SmallOnLarge {
  Simulation<double> sim;
  Index lower;  // the upper cloth's first particle
  SimulationOptions options;
};
/// An 8 x 8 cloth dropped `drop` m onto a 12 x 12 one lying on a floor, `across` spacings
/// from its border along x (2.5: over its middle; 7.5: 3.5 spacings hang over its border);
/// shifted by half a spacing so that no vertex is above another.
SmallOnLarge smallOnLarge(double drop, double upperThickness = 0, double across = 2.5) {
  ModelBuilder<double> b;
  ClothGridSpec spec = flagSpec(12);
  spec.origin = {0, 0.01, 0};
  addClothGrid(b, spec);
  const Index lower = b.particleCount();
  spec.width = spec.height = 8;
  spec.totalMass *= 64.0 / 144.0;
  spec.origin = {across * spec.spacing, 0.01 + drop, 1.5 * spec.spacing};
  addClothGrid(b, spec);
  SimulationOptions o;
  o.dt = defaultTimeStep(BuiltinScene::Flag, 12);
  o.effects.drag = 1e-3;
  o.collision.obstacles.push_back(Obstacle::plane({0, 0, 0}, {0, 1, 0}));
  o.selfCollision.enabled = true;
  ModelAndState<double> built = b.build();
  if (upperThickness > 0) {
    o.selfCollision.particleThickness.assign(static_cast<size_t>(built.model.particleCount()),
                                             o.selfCollision.thickness);
    for (Index i = lower; i < built.model.particleCount(); ++i)
      o.selfCollision.particleThickness[static_cast<size_t>(i)] = upperThickness;
  }
  return {Simulation<double>(std::move(built), o), lower, o};
}

TEST(SelfCollisionScenes, EachClothKeepsItsOwnThickness) {
  WEFT_SKIP_UNDER_TSAN(kSameBitsTest);
  // The upper cloth 12 mm thick on the 4 mm lower one: the layers rest the mean apart, 8 mm
  // (with one thickness they rest 4 mm apart: RestingLayersNeitherJitterNorCreep).
  for (const double upper : {0.012}) {
    SmallOnLarge scene = smallOnLarge(0.02, upper);
    Simulation<double>& sim = scene.sim;
    const Index n = sim.model().particleCount();
    ASSERT_TRUE(sim.run(static_cast<Index>(std::ceil(1.0 / scene.options.dt))).ok());
    // The upper cloth lies over the lower one's middle; the lower one lies on the floor.
    double lowerTop = 0, upperBottom = 1;
    for (Index i = 0; i < scene.lower; ++i) lowerTop = std::max(lowerTop, sim.state().x(i, 1));
    for (Index i = scene.lower; i < n; ++i) upperBottom = std::min(upperBottom, sim.state().x(i, 1));
    const double gap = upperBottom - lowerTop, expected = 0.5 * (0.004 + upper);
    EXPECT_NEAR(gap, expected, 0.15 * expected) << "upper thickness " << upper;
    EXPECT_EQ(sim.selfIntersectionCount(), 0);
  }
}

TEST(SelfCollisionScenes, OffCostsNothing) {
  // Without the option there is no pass: no collider, no statistics, the flag's step untouched.
  Simulation<double> sim = makeScene<double>("flag", 8, false);
  EXPECT_EQ(sim.selfCollider(), nullptr);
  ASSERT_TRUE(sim.run(10).ok());
  EXPECT_EQ(sim.totalSelfCollision().passes, 0);
  EXPECT_EQ(sim.contactListBytes(), 0U);
}

TEST(SelfCollisionScenes, ContactListBytesHoldTheListsAndOnlyGrow) {
  // What `weft soak` counts apart from a leak: the lists' capacities, at least the current
  // candidates (two indices each), never shrinking while the cloth folds.
  Simulation<double> sim = makeScene<double>("fold", 12, true);
  std::size_t last = sim.contactListBytes();
  for (int k = 0; k < 20; ++k) {
    ASSERT_TRUE(sim.run(static_cast<Index>(std::ceil(0.05 / sim.timeStep()))).ok());
    const std::size_t now = sim.contactListBytes();
    EXPECT_GE(now, last) << "after " << (k + 1) * 0.05 << " s";
    EXPECT_GE(now, 2 * sizeof(Index) * static_cast<std::size_t>(sim.selfCollider()->candidateCount()));
    last = now;
  }
  EXPECT_GT(last, 0U);
}

/// Settles `scene` for `seconds`, then steps it 0.5 s more: the fastest particle speed over
/// that half second (m/s) and how far the upper cloth's centre moved in it (m).
struct Settled {
  double fastest = 0, creep = 0;
};
Settled settle(SmallOnLarge& scene, double seconds) {
  Simulation<double>& sim = scene.sim;
  const Index lower = scene.lower, n = sim.model().particleCount();
  EXPECT_TRUE(sim.run(static_cast<Index>(std::ceil(seconds / scene.options.dt))).ok());
  const auto upperCentre = [&] {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (Index i = lower; i < n; ++i) c += sim.state().x.row(i).transpose();
    return Eigen::Vector3d(c / static_cast<double>(n - lower));
  };
  const Eigen::Vector3d before = upperCentre();
  Settled settled;
  for (Index k = 0; k < static_cast<Index>(std::ceil(0.5 / scene.options.dt)); ++k) {
    EXPECT_TRUE(sim.step().ok());
    for (Index i = 0; i < n; ++i) settled.fastest = std::max(settled.fastest, sim.state().v.row(i).norm());
  }
  settled.creep = (upperCentre() - before).norm();
  return settled;
}

TEST(SelfCollisionScenes, RestingLayersNeitherJitterNorCreep) {
  WEFT_SKIP_UNDER_TSAN(kSameBitsTest);
  // A smaller cloth dropped 1 cm onto a larger one lying on a floor: after settling the
  // particles are slow and the upper cloth stays where it is.
  SmallOnLarge scene = smallOnLarge(0.01);
  Simulation<double>& sim = scene.sim;
  const SimulationOptions& o = scene.options;
  const Settled settled = settle(scene, 1.0);
  EXPECT_GT(sim.lastSelfCollision().contacts, 0) << "the layers should touch";
  EXPECT_LT(settled.fastest, 0.01) << "m/s over the last 0.5 s";
  EXPECT_LT(settled.creep, 1e-4) << "m of creep in 0.5 s";
  EXPECT_EQ(sim.selfIntersectionCount(), 0);
  // The layers lie a thickness apart: the upper cloth rests on the lower one, not in it.
  double lowest = 1;
  for (Index i = scene.lower; i < sim.model().particleCount(); ++i) lowest = std::min(lowest, sim.state().x(i, 1));
  EXPECT_GT(lowest, o.collision.thickness + 0.5 * o.selfCollision.thickness) << "m: the upper cloth's lowest particle";
}

TEST(SelfCollisionScenes, AClothDrapedOverAnothersBorderComesToRest) {
  WEFT_SKIP_UNDER_TSAN(kSameBitsTest);
  // The upper cloth hangs 3.5 spacings over the lower one's border and drapes down to the
  // floor beside it. The lower cloth's border particles rest on the floor under the upper
  // cloth's weight: the response must not push them into the floor (the floor pushing them
  // back the next chunk kept them and their neighbours moving at a few cm/s), and contacts
  // sharing vertices must not throw them up (sequential impulses, accumulated >= 0).
  // (The overhang sags for longer: at 1 s it still comes down at 6-8 mm/s.)
  SmallOnLarge scene = smallOnLarge(0.01, 0, 7.5);
  Simulation<double>& sim = scene.sim;
  const Settled settled = settle(scene, 2.0);
  EXPECT_GT(sim.lastSelfCollision().contacts, 0) << "the layers should touch";
  double lowerTop = 0, upperLowest = 1;
  for (Index i = 0; i < scene.lower; ++i) lowerTop = std::max(lowerTop, sim.state().x(i, 1));
  for (Index i = scene.lower; i < sim.model().particleCount(); ++i)
    upperLowest = std::min(upperLowest, sim.state().x(i, 1));
  // (Lying on the lower cloth it would be a thickness above it: it hangs down to the floor.)
  EXPECT_LT(upperLowest, lowerTop + 0.5 * scene.options.selfCollision.thickness)
      << "m: the upper cloth should drape over the lower one's border";
  EXPECT_LT(settled.fastest, 0.01) << "m/s over the last 0.5 s";
  EXPECT_LT(settled.creep, 1e-4) << "m of creep in 0.5 s";
  EXPECT_EQ(sim.selfIntersectionCount(), 0);
  // Nothing ends a step inside the floor's thickness: self-collision does not push the
  // particles lying on it down (the floor's response leaves them at its thickness).
  double lowest = 1;
  for (Index i = 0; i < sim.model().particleCount(); ++i) lowest = std::min(lowest, sim.state().x(i, 1));
  EXPECT_GE(lowest, scene.options.collision.thickness - 1e-12) << "m: the lowest particle";
}

}  // namespace
