// BM_Rigid_*: rigid-body steps (weft/rigid/rigid_world.hpp).
//
//   BM_Rigid_Pile/method:M/threads:T/redo:R
//                                      one step of the `pile` scene (1000 convex bodies in
//                                      a bin) after 1.5 s of settling (bodies falling and
//                                      landing, most of them touching), narrow phase M
//                                      (0 exact, 1 OFG, 2 witness), T threads, with
//                                      RigidOptions::redoDeepSteps R (1, the default: the
//                                      end-of-step check and the steps taken again in
//                                      halves; 0 without, witness only). Counters:
//                                      bodies, contacts, pairs (candidates), touching_pairs;
//                                      in_bin, below_floor, mean_height and mean_speed of the
//                                      settled state (pile_summary.hpp, beside
//                                      BM_Peer_Bullet_Pile's); allocs_per_iteration (0);
//                                      redone_steps (a share of the timed steps).
//   BM_Rigid_Stack/threads:T           one step of the 10-box stack at rest.
// The world is reset to the settled state every 60 steps so each configuration times the
// same motion.
#include <benchmark/benchmark.h>

#include <memory>

#include "bench_common.hpp"
#include "pile_summary.hpp"
#include "weft/weft.hpp"

namespace {

struct Settled {
  weft::RigidOptions options;
  weft::RigidState state;
};

const Settled& settledPile(weft::NarrowPhaseMethod method, bool redo) {
  static std::unique_ptr<Settled> cache[3][2];
  std::unique_ptr<Settled>& s = cache[static_cast<int>(method)][redo];
  if (!s) {
    s = std::make_unique<Settled>();
    s->options = weft::pileScene(1000);
    s->options.narrowPhase.method = method;
    s->options.redoDeepSteps = redo;
    weft::Executor exec(2);
    weft::RigidWorld world(s->options, {0, -9.81, 0});
    for (int i = 0; i < 90; ++i) world.step(weft::rigidSceneTimeStep(), exec);
    s->state = world.state();
  }
  return *s;
}

void BM_Rigid_Pile(benchmark::State& st) {
  const auto method = static_cast<weft::NarrowPhaseMethod>(st.range(0));
  const Settled& settled = settledPile(method, st.range(2) != 0);
  weft::Executor exec(static_cast<int>(st.range(1)));
  weft::RigidWorld world(settled.options, {0, -9.81, 0});
  world.setState(settled.state);
  for (int i = 0; i < 5; ++i) world.step(weft::rigidSceneTimeStep(), exec);  // warm start, caches
  int k = 0;
  std::int64_t allocations = 0, redone = 0;
  for (auto _ : st) {
    if (++k == 60) {
      st.PauseTiming();
      world.setState(settled.state);
      k = 0;
      st.ResumeTiming();
    }
    const std::int64_t before = weftbench::allocationCount();
    benchmark::DoNotOptimize(world.step(weft::rigidSceneTimeStep(), exec));
    allocations += weftbench::allocationCount() - before;
    redone += world.lastStats().redoneSteps;
  }
  st.counters["bodies"] = static_cast<double>(world.model().bodyCount());
  st.counters["contacts"] = static_cast<double>(world.lastStats().contacts);
  st.counters["pairs"] = static_cast<double>(world.lastStats().candidatePairs);
  st.counters["touching_pairs"] = static_cast<double>(world.lastStats().touchingPairs);
  // The settled state, as BM_Peer_Bullet_Pile reports its own.
  weftbench::PileSummary summary;
  for (weft::Index b = 0; b < world.model().bodyCount(); ++b) {
    if (world.model().motion[b] != weft::BodyMotion::Dynamic) continue;
    const Eigen::Vector3d& x = settled.state.x[b];
    summary.add(x.x(), x.y(), x.z(), settled.state.v[b].norm());
  }
  summary.report(st);
  st.counters["allocs_per_iteration"] = static_cast<double>(allocations) / static_cast<double>(st.iterations());
  st.counters["redone_steps"] = static_cast<double>(redone) / static_cast<double>(st.iterations());
  st.SetLabel(weft::narrowPhaseMethodName(method));
}
BENCHMARK(BM_Rigid_Pile)
    ->ArgNames({"method", "threads", "redo"})
    ->ArgsProduct({{0, 1, 2}, {1, 2}, {1}})
    ->Args({2, 1, 0})
    ->Args({2, 2, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_Rigid_Stack(benchmark::State& st) {
  weft::Executor exec(static_cast<int>(st.range(0)));
  weft::RigidWorld world(weft::stackScene(10), {0, -9.81, 0});
  for (int i = 0; i < 60; ++i) world.step(weft::rigidSceneTimeStep(), exec);
  for (auto _ : st) benchmark::DoNotOptimize(world.step(weft::rigidSceneTimeStep(), exec));
  st.counters["contacts"] = static_cast<double>(world.lastStats().contacts);
}
BENCHMARK(BM_Rigid_Stack)->ArgNames({"threads"})->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond)->UseRealTime();

}  // namespace
