// Shared pieces of the weft benchmarks: the allocation counter (the counting global operator new
// of tests/support/alloc_counter.hpp, linked into weft_bench), the {size or mesh, threads} arguments
// and the registration of a template instance under the name the results know.
#pragma once

#include <benchmark/benchmark.h>

#include <cstdint>
#include <initializer_list>

#include "support/alloc_counter.hpp"

namespace weftbench {
/// Number of global operator new calls so far in this process.
inline std::int64_t allocationCount() { return weft::test::operatorNewCalls(); }

/// Arguments {value, threads}: each of `values` on 1 and 2 threads, the first argument named
/// `name`, timed in real time (the CPU time of the calling thread misses the workers').
inline void valuesOnOneAndTwoThreads(benchmark::internal::Benchmark* b, const char* name,
                                     std::initializer_list<int> values, benchmark::TimeUnit unit) {
  for (int value : values)
    for (int threads : {1, 2}) b->Args({value, threads});
  b->ArgNames({name, "threads"})->UseRealTime()->Unit(unit);
}
}  // namespace weftbench

/// Defines the benchmark NAME, which runs the template instance given after ARGS (commas and
/// all), and registers it with ARGS applied: the benchmark is listed as NAME, the name in
/// bench/results and summarize.py, not as the instance's spelling.
#define WEFT_BENCHMARK_AS(NAME, ARGS, ...)             \
  void NAME(benchmark::State& st) { __VA_ARGS__(st); } \
  BENCHMARK(NAME)->Apply(ARGS)
