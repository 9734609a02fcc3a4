// weft_bench: main, build-configuration context, and an operator new counter so that
// every step benchmark can report allocations per step (expected: 0).
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <atomic>
#include <cstdlib>
#include <new>
#include <string>
#include <thread>

#include "bench_common.hpp"

namespace {
std::atomic<std::int64_t> gAllocations{0};
}

namespace weftbench {
std::int64_t allocationCount() { return gAllocations.load(std::memory_order_relaxed); }
}  // namespace weftbench

void* operator new(std::size_t size) {
  gAllocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, std::align_val_t align) {
  gAllocations.fetch_add(1, std::memory_order_relaxed);
  const std::size_t a = static_cast<std::size_t>(align);
  if (void* p = std::aligned_alloc(a, (size + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size, std::align_val_t align) { return operator new(size, align); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

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
