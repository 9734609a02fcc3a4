// BM_Rigid_NarrowPhase_<Method>: one hull-hull narrow-phase query (weft/rigid/narrow_phase.hpp)
// per iteration, Method in {Exact, Ofg (k = 6), Witness}.
//
//   shape:0  box (8 vertices, 6 faces, 12 edges)
//   shape:1  icosahedron (12 vertices, 20 faces, 30 edges)
//   shape:2  sphere hull: the convex hull of a 3-times subdivided icosphere's vertices
//            (642 vertices, 1280 faces, 1920 edges)
//   situation:0  resting: two copies face to face, 0.5 mm deep, jittering by 1e-6 m and
//                1e-6 rad about the rest pose every query (a settled pair)
//   situation:1  tumbling: the second copy circles the first 5 % of their size apart (never
//                touching) while spinning, 1/4096 of a turn per query (a slow, separated pair)
// A pair's poses are precomputed (4096 of them, cyclic); the PairCache lives across
// iterations, as it does across steps. Counters: hit_rate (share of queries the witness
// answered without the full search; 0 for the other methods), contact_rate (share with a
// manifold), allocs_per_iteration (expected 0). Time per iteration = time per pair.
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "bench_common.hpp"
#include "weft/rigid/convex_hull.hpp"
#include "weft/rigid/narrow_phase.hpp"

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr int kPoses = 4096;
constexpr double kMargin = 0.01;  // m, RigidOptions::speculativeDistance's default

/// The vertices of an icosahedron (circumradius 1) subdivided `levels` times onto the sphere.
std::vector<Vector3d> icosphereVertices(int levels) {
  const double t = (1 + std::sqrt(5.0)) / 2;
  std::vector<Vector3d> v = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                             {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  for (Vector3d& x : v) x.normalize();
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> midpoints;
    const auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto it = midpoints.find(key);
      if (it != midpoints.end()) return it->second;
      v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
      return midpoints[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& [a, b, c] : f) {
      const int ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
      next.push_back({a, ab, ca});
      next.push_back({b, bc, ab});
      next.push_back({c, ca, bc});
      next.push_back({ab, bc, ca});
    }
    f = std::move(next);
  }
  return v;
}

const weft::ConvexHull& shape(int index) {
  static const weft::ConvexHull box = weft::makeBoxHull(Vector3d(0.5, 0.5, 0.5));
  static const weft::ConvexHull icosahedron = [] {
    std::vector<Vector3d> v = icosphereVertices(0);
    for (Vector3d& x : v) x *= 0.6;
    return weft::makeConvexHull(v);
  }();
  static const weft::ConvexHull sphere = [] {
    std::vector<Vector3d> v = icosphereVertices(3);
    for (Vector3d& x : v) x *= 0.5;
    return weft::makeConvexHull(v);
  }();
  return index == 0 ? box : index == 1 ? icosahedron : sphere;
}

weft::Pose makePose(const Matrix3d& r, const Vector3d& p) {
  weft::Pose pose;
  pose.rotation = r;
  pose.position = p;
  return pose;
}

/// Index of the face whose normal is closest to `direction`.
int faceToward(const weft::ConvexHull& h, const Vector3d& direction) {
  int best = 0;
  for (int f = 1; f < h.faceCount(); ++f)
    if (h.faces[static_cast<std::size_t>(f)].normal.dot(direction) >
        h.faces[static_cast<std::size_t>(best)].normal.dot(direction))
      best = f;
  return best;
}

Vector3d faceCentre(const weft::ConvexHull& h, int f) {
  Vector3d c = Vector3d::Zero();
  for (const int v : h.faceIndices(f)) c += h.vertices[static_cast<std::size_t>(v)];
  return c / static_cast<double>(h.faces[static_cast<std::size_t>(f)].count);
}

struct Scenario {
  weft::Pose poseA;
  std::vector<weft::Pose> posesB;
};

/// See the header comment. Deterministic (fixed seeds).
const Scenario& scenario(int shapeIndex, int situation) {
  static std::map<std::pair<int, int>, Scenario> cache;
  const auto key = std::make_pair(shapeIndex, situation);
  const auto found = cache.find(key);
  if (found != cache.end()) return found->second;
  const weft::ConvexHull& h = shape(shapeIndex);
  Scenario s;
  if (situation == 0) {
    // A with a face up, B with a face down, face centres on one vertical line, B lowered
    // until the SAT separation is -0.5 mm.
    const int fa = faceToward(h, Vector3d::UnitY());
    const Matrix3d ra =
        Eigen::Quaterniond::FromTwoVectors(h.faces[static_cast<std::size_t>(fa)].normal, Vector3d::UnitY())
            .toRotationMatrix();
    const Matrix3d rb =
        Eigen::AngleAxisd(0.3, Vector3d::UnitY()).toRotationMatrix() *
        Eigen::Quaterniond::FromTwoVectors(h.faces[static_cast<std::size_t>(fa)].normal, -Vector3d::UnitY())
            .toRotationMatrix();
    s.poseA = makePose(ra, Vector3d::Zero());
    const Vector3d topA = ra * faceCentre(h, fa);
    const Vector3d bottomB = rb * faceCentre(h, fa);
    const auto at = [&](double y) { return makePose(rb, Vector3d(topA.x(), y, topA.z()) - bottomB); };
    double lo = topA.y() - 1, hi = topA.y() + 1;
    for (int it = 0; it < 80; ++it) {
      const double mid = 0.5 * (lo + hi);
      (weft::hullSeparation(h, s.poseA, h, at(mid)) < -0.0005 ? lo : hi) = mid;
    }
    const weft::Pose rest = at(0.5 * (lo + hi));
    std::uint64_t seed = 0x9e3779b97f4a7c15ull;
    const auto noise = [&] {  // deterministic uniform in [-1, 1] (splitmix64)
      seed += 0x9e3779b97f4a7c15ull;
      std::uint64_t z = seed;
      z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
      z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
      z ^= z >> 31;
      return static_cast<double>(z >> 11) * 0x1.0p-52 - 1.0;
    };
    for (int k = 0; k < kPoses; ++k) {
      const Vector3d axis = Vector3d(noise(), noise(), noise()).normalized();
      s.posesB.push_back(makePose(Eigen::AngleAxisd(1e-6, axis).toRotationMatrix() * rest.rotation,
                                  rest.position + 1e-6 * Vector3d(noise(), noise(), noise())));
    }
  } else {
    // Circling at 2.1 bounding radii (5 % gap) in the x-z plane, spinning 6 turns a cycle.
    s.poseA = makePose(Eigen::AngleAxisd(0.2, Vector3d(1, 2, 3).normalized()).toRotationMatrix(), -h.centroid);
    const double radius = 2.1 * h.boundingRadius;
    for (int k = 0; k < kPoses; ++k) {
      const double phase = 2 * M_PI * k / kPoses;
      const Matrix3d spin = Eigen::AngleAxisd(6 * phase, Vector3d(0.3, 1, -0.5).normalized()).toRotationMatrix();
      s.posesB.push_back(makePose(
          spin, radius * Vector3d(std::cos(phase), 0.1 * std::sin(3 * phase), std::sin(phase)) - spin * h.centroid));
    }
  }
  return cache.emplace(key, std::move(s)).first->second;
}

void runNarrowPhase(benchmark::State& st, weft::NarrowPhaseMethod method) {
  const int shapeIndex = static_cast<int>(st.range(0));
  const int situation = static_cast<int>(st.range(1));
  const weft::ConvexHull& h = shape(shapeIndex);
  const Scenario& s = scenario(shapeIndex, situation);
  weft::NarrowPhaseOptions options;
  options.method = method;
  options.ofgFaces = 6;
  weft::PairCache cache;
  weft::ContactManifold out;
  // One pass over the poses before timing (warm caches, and the witness's first full query).
  for (const weft::Pose& pb : s.posesB) weft::collideHulls(h, s.poseA, h, pb, kMargin, options, cache, out);
  std::int64_t hits = 0, contacts = 0, queries = 0;
  std::size_t k = 0;
  const std::int64_t before = weftbench::allocationCount();
  for (auto _ : st) {
    const weft::NarrowPhaseOutcome outcome =
        weft::collideHulls(h, s.poseA, h, s.posesB[k], kMargin, options, cache, out);
    benchmark::DoNotOptimize(out);
    hits += outcome != weft::NarrowPhaseOutcome::FullQuery;
    contacts += out.pointCount > 0;
    ++queries;
    if (++k == s.posesB.size()) k = 0;
  }
  const std::int64_t allocations = weftbench::allocationCount() - before;
  const double n = static_cast<double>(std::max<std::int64_t>(queries, 1));
  st.counters["hit_rate"] = static_cast<double>(hits) / n;
  st.counters["contact_rate"] = static_cast<double>(contacts) / n;
  st.counters["allocs_per_iteration"] = static_cast<double>(allocations) / n;
  st.counters["faces"] = h.faceCount();
  st.SetLabel(std::string(weft::narrowPhaseMethodName(method)) + (situation == 0 ? " resting" : " tumbling"));
}

void BM_Rigid_NarrowPhase_Exact(benchmark::State& st) { runNarrowPhase(st, weft::NarrowPhaseMethod::Exact); }
void BM_Rigid_NarrowPhase_Ofg(benchmark::State& st) { runNarrowPhase(st, weft::NarrowPhaseMethod::Ofg); }
void BM_Rigid_NarrowPhase_Witness(benchmark::State& st) { runNarrowPhase(st, weft::NarrowPhaseMethod::Witness); }

#define WEFT_NARROW_BENCH(name) \
  BENCHMARK(name)->ArgNames({"shape", "situation"})->ArgsProduct({{0, 1, 2}, {0, 1}})->Unit(benchmark::kMicrosecond)

WEFT_NARROW_BENCH(BM_Rigid_NarrowPhase_Exact);
WEFT_NARROW_BENCH(BM_Rigid_NarrowPhase_Ofg);
WEFT_NARROW_BENCH(BM_Rigid_NarrowPhase_Witness);

#undef WEFT_NARROW_BENCH

}  // namespace
