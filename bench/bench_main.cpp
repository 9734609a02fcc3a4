// weft_bench: main and the build-configuration context. The allocations the benchmarks report
// (allocs_per_step, expected 0) are counted by tests/support/alloc_counter.cpp, linked in by
// bench/CMakeLists.txt.
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <string>
#include <thread>

int main(int argc, char** argv) {
  benchmark::AddCustomContext("weft_build_type", WEFT_BUILD_TYPE);
  benchmark::AddCustomContext("weft_native", WEFT_NATIVE_BUILD ? "on (-march=native)" : "off");
  benchmark::AddCustomContext("weft_cxx_flags", WEFT_CXX_FLAGS);
  benchmark::AddCustomContext("compiler", "g++ " __VERSION__);
  benchmark::AddCustomContext("eigen_simd", Eigen::SimdInstructionSetsInUse());
  benchmark::AddCustomContext("hardware_threads", std::to_string(std::thread::hardware_concurrency()));
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
