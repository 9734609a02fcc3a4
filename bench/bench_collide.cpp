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
// The cloth is a paraboloid sheet y = 0.8 (x^2 + z^2) - 0.1 over [-0.5, 0.5]^2 and the sphere
// has radius 0.3 at the origin: they cut along one closed curve. Every benchmark reports
// allocs_per_iteration (expected 0: buffers are warmed up before timing).
#include <benchmark/benchmark.h>

#include <random>

#include "bench_common.hpp"
#include "weft/collide/bvh.hpp"
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

template <class S>
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
    clothBvh.intersectingPairs(ballBvh, cloth.x, ball.x, pairs, scratch, exec);
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

void meshesAndThreads(benchmark::internal::Benchmark* b) {
  for (int mesh : {0, 1})
    for (int threads : {1, 2}) b->Args({mesh, threads});
  b->ArgNames({"mesh", "threads"})->UseRealTime()->Unit(benchmark::kMicrosecond);
}

void threads(benchmark::internal::Benchmark* b) {
  b->Arg(1)->Arg(2)->ArgNames({"threads"})->UseRealTime()->Unit(benchmark::kMicrosecond);
}

#define WEFT_BVH(NAME, S, APPLY)                         \
  void NAME##_##S(benchmark::State& st) { NAME<S>(st); } \
  BENCHMARK(NAME##_##S)->Apply(APPLY)

WEFT_BVH(BM_Bvh_Build, float, meshesAndThreads);
WEFT_BVH(BM_Bvh_Build, double, meshesAndThreads);
WEFT_BVH(BM_Bvh_Refit, float, meshesAndThreads);
WEFT_BVH(BM_Bvh_Refit, double, meshesAndThreads);
WEFT_BVH(BM_Bvh_ClothSphereIntersections, float, threads);
WEFT_BVH(BM_Bvh_ClothSphereIntersections, double, threads);
WEFT_BVH(BM_Bvh_ClothSelfIntersections, float, threads);
WEFT_BVH(BM_Bvh_ClothSelfIntersections, double, threads);

}  // namespace
