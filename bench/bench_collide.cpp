// BM_Bvh_*: the triangle BVH (weft/collide/bvh.hpp).
//
//   BM_Bvh_Build_<S>, BM_Bvh_Refit_<S>   mesh 0: the 128^2 cloth (32 258 triangles) draped as
//                                        below; mesh 1: a 200 000-triangle icosphere. 1 and 2
//                                        threads; counter triangles_per_second.
//   BM_Bvh_ClothSphereIntersections_<S>  all intersecting triangle pairs (exact test) between
//                                        the 128^2 cloth and a 20 480-triangle sphere it passes
//                                        through (BVHs built beforehand); counters pairs and
//                                        candidates (box-overlap pairs).
//   BM_Bvh_ClothSelfIntersections_<S>    self-intersecting pairs of the 128^2 cloth crumpled by
//                                        noise (pairs sharing a vertex skipped).
//
//   BM_Bvh_ClothSphereOverlaps_<S>      the box-overlap candidates alone (no exact test): what
//                                        Embree's rtcCollide reports, for the peer ratio.
//
// Peers (built only where found; Debian packages, optional): with Embree 3 (libembree-dev),
//   BM_Peer_Embree_Build   the same meshes, float, as RTC_GEOMETRY_TYPE_TRIANGLE; quality:0 is
//                          Embree's Morton builder (RTC_BUILD_QUALITY_LOW, like weft's LBVH),
//                          quality:1 its binned SAH builder (MEDIUM, the default)
//   BM_Peer_Embree_Refit   RTC_BUILD_QUALITY_REFIT after the vertex buffer changed
//   BM_Peer_Embree_ClothSphereOverlaps  rtcCollide between the cloth and the 20k sphere as
//                          user geometries (Embree's collision query needs them): candidates
// Embree runs on TBB; each benchmark runs inside a task_arena of its thread count and
// creates its device with "threads=N".
//
// The cloth is a paraboloid sheet y = 0.8 (x^2 + z^2) - 0.1 over [-0.5, 0.5]^2 and the sphere
// has radius 0.3 at the origin: they cut along one closed curve. Every benchmark reports
// allocs_per_iteration (expected 0: buffers are warmed up before timing).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <limits>
#include <mutex>
#include <random>
#include <string>
#include <utility>
#include <vector>

#ifdef WEFT_HAVE_EMBREE
#include "bench_embree.hpp"
#endif

#include "bench_common.hpp"
#include "collide/bvh.hpp"
#include "weft/collide/shapes.hpp"
#include "weft/weft.hpp"

namespace {

template <class S>
struct Mesh {
  weft::Vec3Array<S> x;
  weft::Triangles triangles;
};

/// The 128^2 cloth draped as a paraboloid through the sphere.
template <class S>
const Mesh<S>& drapedCloth() {
  static const Mesh<S> mesh = [] {
    weft::ModelBuilder<S> builder;
    weft::ClothGridSpec spec;
    spec.width = 128;
    spec.height = 128;
    spec.origin = {-0.5, 0, -0.5};
    spec.spacing = 1.0 / 127;
    weft::addClothGrid(builder, spec);
    auto built = builder.build();
    for (weft::Index i = 0; i < built.state.x.rows(); ++i) {
      const double x = built.state.x(i, 0), z = built.state.x(i, 2);
      built.state.x(i, 1) = static_cast<S>(0.8 * (x * x + z * z) - 0.1);
    }
    return Mesh<S>{built.state.x, built.model.triangles()};
  }();
  return mesh;
}

/// The 128^2 cloth crumpled: the draped sheet plus noise of 0.6 spacings.
template <class S>
const Mesh<S>& crumpledCloth() {
  static const Mesh<S> mesh = [] {
    Mesh<S> m = drapedCloth<S>();
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> u(-0.6 / 127, 0.6 / 127);
    for (weft::Index i = 0; i < m.x.rows(); ++i)
      for (int k = 0; k < 3; ++k) m.x(i, k) = static_cast<S>(m.x(i, k) + u(rng));
    return m;
  }();
  return mesh;
}

template <class S>
const Mesh<S>& sphere(weft::Index divisions) {
  static const Mesh<S> small = [] {
    const weft::TriangleMesh m = weft::makeIcosphere({0, 0, 0}, 0.3, 32);  // 20 480 triangles
    return Mesh<S>{weft::meshPositions<S>(m), weft::meshTriangles(m)};
  }();
  static const Mesh<S> large = [] {
    const weft::TriangleMesh m = weft::makeIcosphere({0, 0, 0}, 0.3, 100);  // 200 000 triangles
    return Mesh<S>{weft::meshPositions<S>(m), weft::meshTriangles(m)};
  }();
  return divisions == 32 ? small : large;
}

template <class S>
const Mesh<S>& meshByIndex(int index, benchmark::State& st) {
  st.SetLabel(index == 0 ? "cloth128" : "sphere200k");
  return index == 0 ? drapedCloth<S>() : sphere<S>(100);
}

void reportAllocations(benchmark::State& st, std::int64_t before) {
  st.counters["allocs_per_iteration"] =
      static_cast<double>(weftbench::allocationCount() - before) / static_cast<double>(st.iterations());
}

template <class S>
void BM_Bvh_Build(benchmark::State& st) {
  const Mesh<S>& mesh = meshByIndex<S>(static_cast<int>(st.range(0)), st);
  weft::Executor exec(static_cast<int>(st.range(1)));
  weft::TriangleBvh<S> bvh;
  bvh.build(mesh.x, mesh.triangles, exec);  // sizes the buffers
  const std::int64_t before = weftbench::allocationCount();
  for (auto _ : st) {
    bvh.build(mesh.x, mesh.triangles, exec);
    benchmark::DoNotOptimize(bvh.rootBox());
  }
  reportAllocations(st, before);
  st.counters["triangles_per_second"] =
      benchmark::Counter(static_cast<double>(bvh.triangleCount()), benchmark::Counter::kIsIterationInvariantRate);
  st.counters["depth"] = bvh.depth();
}

template <class S>
void BM_Bvh_Refit(benchmark::State& st) {
  const Mesh<S>& mesh = meshByIndex<S>(static_cast<int>(st.range(0)), st);
  weft::Executor exec(static_cast<int>(st.range(1)));
  weft::TriangleBvh<S> bvh;
  bvh.build(mesh.x, mesh.triangles, exec);
  const std::int64_t before = weftbench::allocationCount();
  for (auto _ : st) {
    bvh.refit(mesh.x, exec);
    benchmark::DoNotOptimize(bvh.rootBox());
  }
  reportAllocations(st, before);
  st.counters["triangles_per_second"] =
      benchmark::Counter(static_cast<double>(bvh.triangleCount()), benchmark::Counter::kIsIterationInvariantRate);
}

/// kExact: the intersecting pairs (exact test); otherwise the box-overlap candidates alone.
template <class S, bool kExact = true>
void BM_Bvh_ClothSphereIntersections(benchmark::State& st) {
  const Mesh<S>& cloth = drapedCloth<S>();
  const Mesh<S>& ball = sphere<S>(32);
  weft::Executor exec(static_cast<int>(st.range(0)));
  weft::TriangleBvh<S> clothBvh, ballBvh;
  clothBvh.build(cloth.x, cloth.triangles, exec);
  ballBvh.build(ball.x, ball.triangles, exec);
  weft::BvhPairScratch scratch;
  std::vector<weft::TrianglePair> pairs;
  clothBvh.overlappingPairs(ballBvh, pairs, scratch, exec);
  const double candidates = static_cast<double>(pairs.size());
  clothBvh.intersectingPairs(ballBvh, cloth.x, ball.x, pairs, scratch, exec);
  const std::int64_t before = weftbench::allocationCount();
  for (auto _ : st) {
    if constexpr (kExact)
      clothBvh.intersectingPairs(ballBvh, cloth.x, ball.x, pairs, scratch, exec);
    else
      clothBvh.overlappingPairs(ballBvh, pairs, scratch, exec);
    benchmark::DoNotOptimize(pairs.data());
  }
  reportAllocations(st, before);
  st.counters["pairs"] = static_cast<double>(pairs.size());
  st.counters["candidates"] = candidates;
}

template <class S>
void BM_Bvh_ClothSelfIntersections(benchmark::State& st) {
  const Mesh<S>& cloth = crumpledCloth<S>();
  weft::Executor exec(static_cast<int>(st.range(0)));
  weft::TriangleBvh<S> bvh;
  bvh.build(cloth.x, cloth.triangles, exec);
  weft::BvhPairScratch scratch;
  std::vector<weft::TrianglePair> pairs;
  bvh.selfPairs(pairs, scratch, exec);
  const double candidates = static_cast<double>(pairs.size());
  bvh.selfIntersectingPairs(cloth.x, pairs, scratch, exec);
  const std::int64_t before = weftbench::allocationCount();
  for (auto _ : st) {
    bvh.selfIntersectingPairs(cloth.x, pairs, scratch, exec);
    benchmark::DoNotOptimize(pairs.data());
  }
  reportAllocations(st, before);
  st.counters["pairs"] = static_cast<double>(pairs.size());
  st.counters["candidates"] = candidates;
}

#ifdef WEFT_HAVE_EMBREE
using weftbench::EmbreeMesh;

void BM_Peer_Embree_Build(benchmark::State& st) {
  const Mesh<float>& mesh = meshByIndex<float>(static_cast<int>(st.range(0)), st);
  const int threads = static_cast<int>(st.range(1));
  const RTCBuildQuality quality = st.range(2) == 0 ? RTC_BUILD_QUALITY_LOW : RTC_BUILD_QUALITY_MEDIUM;
  weft::Executor exec(threads);
  exec.run([&] {
    EmbreeMesh e(mesh.x, mesh.triangles, threads, false, quality);
    e.commit();
    for (auto _ : st) e.commit();
  });
  st.counters["triangles_per_second"] =
      benchmark::Counter(static_cast<double>(mesh.triangles.count()), benchmark::Counter::kIsIterationInvariantRate);
}

void BM_Peer_Embree_Refit(benchmark::State& st) {
  const Mesh<float>& mesh = meshByIndex<float>(static_cast<int>(st.range(0)), st);
  const int threads = static_cast<int>(st.range(1));
  weft::Executor exec(threads);
  exec.run([&] {
    EmbreeMesh e(mesh.x, mesh.triangles, threads, false, RTC_BUILD_QUALITY_REFIT);
    e.commit();
    for (auto _ : st) e.commit();
  });
  st.counters["triangles_per_second"] =
      benchmark::Counter(static_cast<double>(mesh.triangles.count()), benchmark::Counter::kIsIterationInvariantRate);
}

void BM_Peer_Embree_ClothSphereOverlaps(benchmark::State& st) {
  const int threads = static_cast<int>(st.range(0));
  weft::Executor exec(threads);
  weftbench::EmbreeCollisions pairs;
  exec.run([&] {
    EmbreeMesh cloth(drapedCloth<float>().x, drapedCloth<float>().triangles, threads, true, RTC_BUILD_QUALITY_MEDIUM);
    EmbreeMesh ball(sphere<float>(32).x, sphere<float>(32).triangles, threads, true, RTC_BUILD_QUALITY_MEDIUM);
    cloth.commit();
    ball.commit();
    for (auto _ : st) pairs.collide(cloth.scene, ball.scene);
  });
  st.counters["candidates"] = static_cast<double>(pairs.found().size());
}
#endif

void meshesAndThreads(benchmark::internal::Benchmark* b) {
  weftbench::valuesOnOneAndTwoThreads(b, "mesh", {0, 1}, benchmark::kMicrosecond);
}

void threads(benchmark::internal::Benchmark* b) {
  b->Arg(1)->Arg(2)->ArgNames({"threads"})->UseRealTime()->Unit(benchmark::kMicrosecond);
}

#define WEFT_BVH(NAME, S, APPLY) WEFT_BENCHMARK_AS(NAME##_##S, APPLY, NAME<S>)

WEFT_BVH(BM_Bvh_Build, float, meshesAndThreads);
WEFT_BVH(BM_Bvh_Build, double, meshesAndThreads);
WEFT_BVH(BM_Bvh_Refit, float, meshesAndThreads);
WEFT_BVH(BM_Bvh_Refit, double, meshesAndThreads);
WEFT_BVH(BM_Bvh_ClothSphereIntersections, float, threads);
WEFT_BVH(BM_Bvh_ClothSphereIntersections, double, threads);
template <class S>
void BM_Bvh_ClothSphereOverlaps(benchmark::State& st) {
  BM_Bvh_ClothSphereIntersections<S, false>(st);
}
WEFT_BVH(BM_Bvh_ClothSphereOverlaps, float, threads);
WEFT_BVH(BM_Bvh_ClothSphereOverlaps, double, threads);
WEFT_BVH(BM_Bvh_ClothSelfIntersections, float, threads);
WEFT_BVH(BM_Bvh_ClothSelfIntersections, double, threads);

#ifdef WEFT_HAVE_EMBREE
BENCHMARK(BM_Peer_Embree_Build)
    ->ArgsProduct({{0, 1}, {1, 2}, {0, 1}})
    ->ArgNames({"mesh", "threads", "quality"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Peer_Embree_Refit)->Apply(meshesAndThreads);
BENCHMARK(BM_Peer_Embree_ClothSphereOverlaps)->Apply(threads);
#endif

}  // namespace
