#pragma once
// What the sanitizer builds of the suite trade for time. CI runs the whole suite under
// AddressSanitizer + UndefinedBehaviorSanitizer and the tests labelled `threaded` under
// ThreadSanitizer; both are 5-20x slower than Release (ThreadSanitizer on two threads up
// to 40x), so a few long tests run shorter there or, under ThreadSanitizer, not at all.

#include <gtest/gtest.h>

namespace weft::test {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
/// True in the AddressSanitizer and ThreadSanitizer builds: long loops of random trials run
/// a share of their trials there (the memory and threading paths are the same in every
/// trial; the Release build runs them all).
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif

#if defined(__SANITIZE_THREAD__)
/// True in the ThreadSanitizer build.
inline constexpr bool kThreadSanitizer = true;
#else
inline constexpr bool kThreadSanitizer = false;
#endif

}  // namespace weft::test

/// Skips the test under ThreadSanitizer, which looks for data races and not for physics:
/// for tests that check a physical outcome (a drape at rest, a cloth that never intersects)
/// over seconds of simulated time, while a shorter test named in `why` runs the same
/// parallel passes on one and two threads and compares the bits. The Release and
/// AddressSanitizer builds run the test.
#define WEFT_SKIP_UNDER_TSAN(why) \
  if (::weft::test::kThreadSanitizer) GTEST_SKIP() << "skipped under ThreadSanitizer: " << (why)
