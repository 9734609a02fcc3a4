// Shared pieces of the weft benchmarks: scene sizes, thread counts and an allocation
// counter (global operator new is replaced in bench_main.cpp).
#pragma once

#include <cstdint>

namespace weftbench {
/// Number of global operator new calls so far in this process.
std::int64_t allocationCount();
}  // namespace weftbench
