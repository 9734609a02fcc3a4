// BM_Machine_*: what this machine can do, measured in the same binary as the kernel, so that
// docs/benchmarks.md can place the spring pass against the machine's limits (its roofline).
//
//   BM_Machine_Fma<S>/threads          peak fused multiply-add throughput: 32 independent
//       chains of a = a * m + c per lane (the compiler vectorises them at the build's SIMD
//       width); counter flops_per_second (2 per FMA).
//   BM_Machine_SqrtDiv<S>/threads      the spring's own bottleneck: y = 1 / sqrt(x) as
//       dampedSpringForce computes it (a square root, then a division), over an L1-resident
//       array; counter per_second (springs per second if nothing else cost anything).
//   BM_Machine_Triad<S>/kib/threads     a[i] = b[i] + s c[i] over three arrays of `kib` KiB
//       in all (per thread: each thread its own arrays): 192 KiB sits in L2, 1536 KiB fills
//       most of one core's L2, 262144 KiB (256 MiB) streams from memory; counter
//       bytes_per_second (three arrays of S per element: b and c read, a written).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "weft/core/parallel.hpp"

namespace {

template <class S>
[[gnu::noinline]] void fmaChains(std::size_t rounds, S* acc, S m, S c) {
  constexpr int kChains = 32 * 64 / static_cast<int>(sizeof(S));  // 32 vector registers' worth at 512 bits
  S a[kChains];
  for (int j = 0; j < kChains; ++j) a[j] = acc[j];
  for (std::size_t r = 0; r < rounds; ++r)
    for (int j = 0; j < kChains; ++j) a[j] = a[j] * m + c;
  for (int j = 0; j < kChains; ++j) acc[j] = a[j];
}

template <class S>
void BM_Machine_Fma(benchmark::State& st) {
  constexpr int kChains = 32 * 64 / static_cast<int>(sizeof(S));
  const int threads = static_cast<int>(st.range(0));
  weft::Executor exec(threads);
  constexpr std::size_t kRounds = 1 << 14;
  std::vector<std::vector<S>> acc(static_cast<std::size_t>(threads), std::vector<S>(kChains, S(1)));
  for (auto _ : st) {
    exec.parallelFor(threads, 1, [&](weft::Index b, weft::Index e) {
      for (weft::Index t = b; t < e; ++t)
        fmaChains<S>(kRounds, acc[static_cast<std::size_t>(t)].data(), S(0.999999), S(1e-6));
    });
    benchmark::DoNotOptimize(acc.data());
  }
  const double flops = 2.0 * kChains * static_cast<double>(kRounds) * threads;
  st.counters["flops_per_second"] = benchmark::Counter(flops, benchmark::Counter::kIsIterationInvariantRate);
}

template <class S>
[[gnu::noinline]] void sqrtDiv(std::size_t n, const S* __restrict x, S* __restrict y) {
  for (std::size_t i = 0; i < n; ++i) y[i] = S(1) / std::sqrt(x[i]);
}

template <class S>
void BM_Machine_SqrtDiv(benchmark::State& st) {
  const int threads = static_cast<int>(st.range(0));
  weft::Executor exec(threads);
  constexpr std::size_t kN = 4096;  // 16 or 32 KiB per array: L1
  std::vector<std::vector<S>> x(static_cast<std::size_t>(threads), std::vector<S>(kN, S(2)));
  std::vector<std::vector<S>> y(static_cast<std::size_t>(threads), std::vector<S>(kN, S(0)));
  constexpr int kRepeats = 64;
  for (auto _ : st) {
    exec.parallelFor(threads, 1, [&](weft::Index b, weft::Index e) {
      for (weft::Index t = b; t < e; ++t)
        for (int r = 0; r < kRepeats; ++r)
          sqrtDiv<S>(kN, x[static_cast<std::size_t>(t)].data(), y[static_cast<std::size_t>(t)].data());
    });
    benchmark::DoNotOptimize(y.data());
  }
  st.counters["per_second"] =
      benchmark::Counter(static_cast<double>(kN) * kRepeats * threads, benchmark::Counter::kIsIterationInvariantRate);
}

template <class S>
[[gnu::noinline]] void triad(std::size_t n, S* __restrict a, const S* __restrict b, const S* __restrict c, S s) {
  for (std::size_t i = 0; i < n; ++i) a[i] = b[i] + s * c[i];
}

template <class S>
void BM_Machine_Triad(benchmark::State& st) {
  const std::size_t bytes = static_cast<std::size_t>(st.range(0)) * 1024;
  const int threads = static_cast<int>(st.range(1));
  weft::Executor exec(threads);
  const std::size_t n = bytes / (3 * sizeof(S));
  struct Arrays {
    std::vector<S> a, b, c;
  };
  std::vector<Arrays> arrays(static_cast<std::size_t>(threads),
                             Arrays{std::vector<S>(n, S(0)), std::vector<S>(n, S(1)), std::vector<S>(n, S(2))});
  // Enough passes per iteration that a small array's pass is not all loop overhead.
  const std::size_t passes = std::max<std::size_t>(1, (std::size_t(64) << 20) / bytes);
  for (auto _ : st) {
    exec.parallelFor(threads, 1, [&](weft::Index b, weft::Index e) {
      for (weft::Index t = b; t < e; ++t) {
        Arrays& x = arrays[static_cast<std::size_t>(t)];
        for (std::size_t p = 0; p < passes; ++p) triad<S>(n, x.a.data(), x.b.data(), x.c.data(), S(0.5));
      }
    });
    benchmark::DoNotOptimize(arrays.data());
  }
  const double moved = 3.0 * sizeof(S) * static_cast<double>(n) * static_cast<double>(passes) * threads;
  st.counters["bytes_per_second"] = benchmark::Counter(moved, benchmark::Counter::kIsIterationInvariantRate);
}

BENCHMARK(BM_Machine_Fma<float>)->Arg(1)->Arg(2)->ArgName("threads")->UseRealTime()->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Machine_Fma<double>)->Arg(1)->Arg(2)->ArgName("threads")->UseRealTime()->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Machine_SqrtDiv<float>)->Arg(1)->Arg(2)->ArgName("threads")->UseRealTime()->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Machine_SqrtDiv<double>)->Arg(1)->Arg(2)->ArgName("threads")->UseRealTime()->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Machine_Triad<float>)
    ->ArgsProduct({{192, 1536, 262144}, {1, 2}})
    ->ArgNames({"kib", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

}  // namespace
