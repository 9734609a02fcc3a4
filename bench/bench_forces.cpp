// BM_Forces_*: one force evaluation (springs + gravity -> accelerations) on the flag,
// for every strategy, sizes 32^2 .. 256^2, float and double, 1 and 2 threads.
#include <benchmark/benchmark.h>

#include "bench_common.hpp"
#include "weft/weft.hpp"

namespace {

template <class S, weft::ForceStrategy Strategy>
void BM_Forces(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  const int threads = static_cast<int>(st.range(1));
  auto built = weft::makeFlag<S>(size);
  // Disturb the flat grid so every spring is stretched and moving (a realistic load).
  built.state.x += Eigen::Matrix<S, Eigen::Dynamic, 3>::Random(built.state.x.rows(), 3) * S(1e-3);
  built.state.v = Eigen::Matrix<S, Eigen::Dynamic, 3>::Random(built.state.v.rows(), 3) * S(0.1);
  weft::Executor exec(threads);
  weft::ForceField<S> forces(built.model, Strategy, {0, -9.81, 0});
  weft::Vec3Array<S> a(built.model.particleCount(), 3);
  exec.run([&] { forces.accelerations(built.state.x, built.state.v, a, exec); });  // warm up
  for (auto _ : st) {
    exec.run([&] { forces.accelerations(built.state.x, built.state.v, a, exec); });
    benchmark::DoNotOptimize(a.data());
    benchmark::ClobberMemory();
  }
  const double springs = static_cast<double>(built.model.springCount());
  st.counters["springs"] = springs;
  st.counters["springs_per_second"] = benchmark::Counter(springs, benchmark::Counter::kIsIterationInvariantRate);
  st.counters["colours"] = static_cast<double>(forces.colourCount());
}

void sizesAndThreads(benchmark::internal::Benchmark* b) {
  weftbench::valuesOnOneAndTwoThreads(b, "size", {32, 64, 128, 256}, benchmark::kMicrosecond);
}

using weft::ForceStrategy;
#define WEFT_FORCES(NAME, S, STRATEGY) WEFT_BENCHMARK_AS(NAME, sizesAndThreads, BM_Forces<S, STRATEGY>)

WEFT_FORCES(BM_Forces_Gather_float, float, ForceStrategy::Gather);
WEFT_FORCES(BM_Forces_Gather_double, double, ForceStrategy::Gather);
WEFT_FORCES(BM_Forces_Coloured_float, float, ForceStrategy::Coloured);
WEFT_FORCES(BM_Forces_Coloured_double, double, ForceStrategy::Coloured);
WEFT_FORCES(BM_Forces_GridStencil_float, float, ForceStrategy::GridStencil);
WEFT_FORCES(BM_Forces_GridStencil_double, double, ForceStrategy::GridStencil);

}  // namespace
