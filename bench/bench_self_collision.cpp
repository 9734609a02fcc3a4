// Self-collision benchmarks (weft/collide/self_collision.hpp), on a cloth folded like an
// accordion: rows follow a serpentine of 0.2 m layers 6 mm apart (1.5 x the 4 mm
// thickness) joined by half circles, so every layer lies over the next (about five layers
// for a 1 m cloth) and nothing intersects (checked).
//
//   BM_SelfCollision_Detect<S>/size/threads   one chunk's pass with new candidates: the
//       cloth is sheared each iteration (row r slides r / (size - 1) x 5 mm along x, far more
//       than the skin: a uniform shift would keep the candidates, since the pass allows for
//       the centroid's motion), so every chunk refits the BVH, queries it and gathers the
//       vertex-triangle and edge-edge candidates, then runs the advancement on each.
//       Counters: triangle_pairs, tests (primitive pairs), rebuilds (gatherings) per chunk.
//   BM_SelfCollision_Cached<S>/size/threads   the same chunk again: the candidates cover it,
//       so only the advancement runs.
//   BM_SelfCollision_Culling_float/size/threads   the candidate pairs of one gathering on
//       the flat cloth and on the accordion, with flat regions culled and without, and the
//       share culled (counters); the time: a collider built and its first chunk run on
//       the accordion, with culling.
//   BM_Peer_Embree_SelfCollide/size/threads   (where Embree 3 is found) rtcCollide of the
//       accordion with itself, boxes grown by half the thickness: the candidate listing of a
//       peer, for the ratio (counters: candidates, pairs_i_lt_j).
//   BM_IntersectionCheck/size/bvh/threads     the exact check (countSelfIntersections) on the
//       accordion, and (bvh:1) the same count through the refittable BVH's pair query.
//   BM_FoldStep/size/self/threads             one step (double, RK4) of the accordion after it
//       has settled 0.1 s on a floor, with and without self-collision (the state is reset
//       before each step): what the pass costs in a step with resting layers.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

#include "bench_common.hpp"
#ifdef WEFT_HAVE_EMBREE
#include "bench_embree.hpp"
#endif
#include "collide/self_collider.hpp"
#include "weft/weft.hpp"

namespace {

using namespace weft;

constexpr double kLayer = 0.2, kGap = 0.006;

/// The accordion: a size x size 1 m cloth (flagSpec) with its rows along the serpentine.
template <class S>
ModelAndState<S> accordion(Index size, double lift = 0) {
  ModelAndState<S> built = makeFlag<S>(size);
  const double spacing = 1.0 / static_cast<double>(size - 1), r = 0.5 * kGap, period = kLayer + M_PI * r;
  for (Index row = 0; row < size; ++row) {
    const double s = row * spacing;
    const int k = static_cast<int>(std::floor(s / period));
    const double u = s - k * period;
    const bool even = k % 2 == 0;
    double y, z;
    if (u < kLayer) {
      z = even ? u : kLayer - u;
      y = k * kGap;
    } else {
      const double theta = (u - kLayer) / r;
      z = (even ? kLayer : 0.0) + (even ? 1 : -1) * r * std::sin(theta);
      y = k * kGap + r - r * std::cos(theta);
    }
    for (Index c = 0; c < size; ++c) {
      const Index i = row * size + c;
      built.state.x(i, 0) = static_cast<S>(c * spacing);
      built.state.x(i, 1) = static_cast<S>(y + lift);
      built.state.x(i, 2) = static_cast<S>(z);
    }
  }
  built.state.v.setZero();
  return built;
}

template <class S>
void BM_SelfCollision_Detect(benchmark::State& st, bool cached) {
  const Index size = static_cast<Index>(st.range(0));
  Executor exec(static_cast<int>(st.range(1)));
  ModelAndState<S> built = accordion<S>(size);
  SelfCollisionOptions options;
  options.enabled = true;
  SelfCollider<S> collider(built.model, options, built.state.x, exec);
  if (countSelfIntersections(built.model, built.state.x, exec) != 0) throw std::logic_error("the accordion intersects");
  Vec3Array<S> x0 = built.state.x, x1 = x0, v1 = built.state.v;
  ScalarArray<S> w = ScalarArray<S>::Ones(built.model.particleCount());
  // Warm up (buffers sized by the first chunk) so that the figures are the steady state.
  x1 = x0;
  (void)collider.resolve(x0, x1, v1, w, 1e-4, exec);
  SelfCollisionStats total;
  std::int64_t chunks = 0;
  for (auto _ : st) {
    if (!cached) {
      st.PauseTiming();
      const double shift = chunks % 2 == 0 ? 0.005 : -0.005;
      for (Index i = 0; i < built.model.particleCount(); ++i)
        x0(i, 0) += static_cast<S>(shift * static_cast<double>(i / size) / static_cast<double>(size - 1));
      st.ResumeTiming();
    }
    x1 = x0;
    x1.col(1).array() -= S(1e-4);
    total += collider.resolve(x0, x1, v1, w, 1e-4, exec);
    ++chunks;
  }
  st.counters["triangle_pairs"] =
      static_cast<double>(total.candidates) / static_cast<double>(std::max<std::int64_t>(1, total.rebuilds));
  st.counters["tests"] = static_cast<double>(total.tests) / static_cast<double>(chunks);
  st.counters["rebuilds"] = static_cast<double>(total.rebuilds) / static_cast<double>(chunks);
}

template <class S>
void BM_SelfCollision_Detect(benchmark::State& st) {
  BM_SelfCollision_Detect<S>(st, false);
}
template <class S>
void BM_SelfCollision_Cached(benchmark::State& st) {
  BM_SelfCollision_Detect<S>(st, true);
}

void sizesAndThreads(benchmark::internal::Benchmark* b) {
  weftbench::valuesOnOneAndTwoThreads(b, "size", {64, 128}, benchmark::kMicrosecond);
}

WEFT_BENCHMARK_AS(BM_SelfCollision_Detect_float, sizesAndThreads, BM_SelfCollision_Detect<float>);
WEFT_BENCHMARK_AS(BM_SelfCollision_Detect_double, sizesAndThreads, BM_SelfCollision_Detect<double>);
WEFT_BENCHMARK_AS(BM_SelfCollision_Cached_float, sizesAndThreads, BM_SelfCollision_Cached<float>);
WEFT_BENCHMARK_AS(BM_SelfCollision_Cached_double, sizesAndThreads, BM_SelfCollision_Cached<double>);

/// The share of candidate pairs that culling flat regions removes, on the flat cloth and on
/// the accordion: one gathering each with culling on and off (counters; the time is the
/// accordion's collider built and its first chunk, with culling).
template <class S>
void BM_SelfCollision_Culling(benchmark::State& st) {
  const Index size = static_cast<Index>(st.range(0));
  Executor exec(static_cast<int>(st.range(1)));
  const auto gather = [&](const ModelAndState<S>& built, bool cull) {
    SelfCollisionOptions options;
    options.enabled = true;
    options.cullFlatRegions = cull;
    SelfCollider<S> collider(built.model, options, built.state.x, exec);
    Vec3Array<S> x1 = built.state.x, v1 = built.state.v;
    x1.col(1).array() -= S(1e-4);
    const ScalarArray<S> w = ScalarArray<S>::Ones(built.model.particleCount());
    (void)collider.resolve(built.state.x, x1, v1, w, 1e-4, exec);
    return static_cast<double>(collider.candidateCount());
  };
  const ModelAndState<S> flat = makeFlag<S>(size), folded = accordion<S>(size);
  for (auto _ : st) benchmark::DoNotOptimize(gather(folded, true));
  const double flatAll = gather(flat, false), flatCulled = gather(flat, true);
  const double foldedAll = gather(folded, false), foldedCulled = gather(folded, true);
  st.counters["flat_pairs_all"] = flatAll;
  st.counters["flat_pairs_culled"] = flatCulled;
  st.counters["folded_pairs_all"] = foldedAll;
  st.counters["folded_pairs_culled"] = foldedCulled;
  st.counters["flat_share_culled"] = flatAll > 0 ? 1 - flatCulled / flatAll : 0;
  st.counters["folded_share_culled"] = foldedAll > 0 ? 1 - foldedCulled / foldedAll : 0;
}
WEFT_BENCHMARK_AS(BM_SelfCollision_Culling_float, sizesAndThreads, BM_SelfCollision_Culling<float>);

#ifdef WEFT_HAVE_EMBREE
/// The peer: Embree's rtcCollide of the accordion against itself, its triangles as user
/// geometry with boxes grown by half the thickness (so the pairs it lists are the pairs
/// whose boxes come within the thickness, what weft's pass needs before culling): the
/// candidate listing alone, on a committed scene.
void BM_Peer_Embree_SelfCollide(benchmark::State& st) {
  const Index size = static_cast<Index>(st.range(0));
  const int threads = static_cast<int>(st.range(1));
  Executor exec(threads);
  const ModelAndState<float> built = accordion<float>(size);
  weftbench::EmbreeCollisions pairs;
  exec.run([&] {
    weftbench::EmbreeMesh cloth(built.state.x, built.model.triangles(), threads, true, RTC_BUILD_QUALITY_MEDIUM,
                                0.5f * static_cast<float>(SelfCollisionOptions{}.thickness));
    cloth.commit();
    for (auto _ : st) pairs.collide(cloth.scene, cloth.scene);
  });
  std::int64_t distinct = 0;
  for (const RTCCollision& c : pairs.found()) distinct += c.primID0 < c.primID1 ? 1 : 0;
  st.counters["candidates"] = static_cast<double>(pairs.found().size());
  st.counters["pairs_i_lt_j"] = static_cast<double>(distinct);
}
BENCHMARK(BM_Peer_Embree_SelfCollide)
    ->ArgsProduct({{64, 128}, {1, 2}})
    ->ArgNames({"size", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);
#endif

/// The exact intersection check (countSelfIntersections: its own tree of 8-triangle leaves,
/// counting as it walks) on the accordion, float; `bvh:1` is the same count through the
/// refittable TriangleBvh and its pair query (selfIntersectingPairs), which the check used
/// before (their memory is in docs/benchmarks.md, from the process's peak).
void BM_IntersectionCheck(benchmark::State& st) {
  const Index size = static_cast<Index>(st.range(0));
  const bool viaBvh = st.range(1) != 0;
  Executor exec(static_cast<int>(st.range(2)));
  const ModelAndState<float> built = accordion<float>(size);
  std::int64_t found = -1;
  for (auto _ : st) {
    if (viaBvh) {
      TriangleBvh<float> bvh;
      bvh.build(built.state.x, built.model.triangles(), exec, 0);
      bvh.releaseBuildBuffers();
      std::vector<TrianglePair> pairs;
      BvhPairScratch scratch;
      bvh.selfIntersectingPairs(built.state.x, pairs, scratch, exec);
      found = static_cast<std::int64_t>(pairs.size());
    } else {
      found = countSelfIntersections(built.model, built.state.x, exec);
    }
  }
  if (found != 0) st.SkipWithError("the accordion intersects");
  st.counters["triangles"] = static_cast<double>(built.model.triangleCount());
}
BENCHMARK(BM_IntersectionCheck)
    ->ArgsProduct({{128, 256}, {0, 1}, {1, 2}})
    ->ArgNames({"size", "bvh", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

/// The accordion settled on a floor for 0.1 s with self-collision (cached per size).
const State<double>& settledAccordion(Index size) {
  static std::map<Index, State<double>> cache;
  auto found = cache.find(size);
  if (found != cache.end()) return found->second;
  SimulationOptions o;
  o.dt = defaultTimeStep(BuiltinScene::Flag, size);
  o.effects.drag = 1e-3;
  o.collision.obstacles.push_back(Obstacle::plane({0, 0, 0}, {0, 1, 0}));
  o.selfCollision.enabled = true;
  o.threads = 2;
  Simulation<double> sim(accordion<double>(size, 0.006), o);
  if (!sim.run(static_cast<Index>(std::ceil(0.1 / o.dt))).ok())
    throw std::logic_error("the accordion failed to settle");
  return cache.emplace(size, sim.state()).first->second;
}

void BM_FoldStep(benchmark::State& st) {
  const Index size = static_cast<Index>(st.range(0));
  const bool self = st.range(1) != 0;
  const State<double>& settled = settledAccordion(size);
  SimulationOptions o;
  o.dt = defaultTimeStep(BuiltinScene::Flag, size);
  o.effects.drag = 1e-3;
  o.collision.obstacles.push_back(Obstacle::plane({0, 0, 0}, {0, 1, 0}));
  o.selfCollision.enabled = self;
  o.threads = static_cast<int>(st.range(2));
  Simulation<double> sim(accordion<double>(size, 0.006), o);
  SelfCollisionStats total;
  std::int64_t steps = 0;
  for (auto _ : st) {
    st.PauseTiming();  // (the reset is not the step: setState checks every particle and spring)
    sim.setState(settled);
    st.ResumeTiming();
    if (!sim.step().ok()) st.SkipWithError("step failed");
    total += sim.lastSelfCollision();
    ++steps;
  }
  const double per = 1.0 / static_cast<double>(std::max<std::int64_t>(1, steps));
  st.counters["self_contacts"] = static_cast<double>(total.contacts) * per;
  st.counters["passes"] = static_cast<double>(total.passes) * per;
  st.counters["rebuilds"] = static_cast<double>(total.rebuilds) * per;
  st.counters["tests"] = static_cast<double>(total.tests) * per;
}
BENCHMARK(BM_FoldStep)
    ->ArgsProduct({{64}, {0, 1}, {1, 2}})
    ->ArgNames({"size", "self", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

}  // namespace
