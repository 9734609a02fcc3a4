// tests/support/alloc_counter.hpp — counts calls to the global operator new, so that a test or a
// benchmark can check that warmed-up code allocates nothing.
//
// The counting is done by replacements of every global operator new / new[] (plain, nothrow,
// aligned, aligned nothrow) and the matching operator deletes, in alloc_counter.cpp. A program
// gets them by linking the OBJECT library weft_alloc_counter (tests/support/CMakeLists.txt):
// test_alloc, test_collide_bvh and weft_bench do; every other program keeps the standard allocator.
//
// The replacements allocate with malloc / aligned_alloc. Eigen's heap goes through malloc
// directly and is not counted here: test_alloc counts the malloc family itself (--wrap).
#pragma once

#include <cstdint>

namespace weft::test {

/// Calls to the global operator new / new[] so far in this process, on every thread.
std::int64_t operatorNewCalls();

}  // namespace weft::test
