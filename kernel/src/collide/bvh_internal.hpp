// Internal to weft's collide module (not installed): what the BVH's build and refit
// (bvh.cpp) and its queries (bvh_queries.cpp) share — box helpers, the Morton-code
// quantisation, the SIMD box-overlap test and the pair sort. All inline: the walks call
// them per node.
#pragma once

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "collide/bvh.hpp"
#include "core/text.hpp"

namespace weft::bvh_detail {

constexpr int kRadixBits = 10;  // per radix pass and per Morton axis
constexpr Index kRadix = Index(1) << kRadixBits;
constexpr int kRadixPasses = 3;
// Stacks of the build and of the closest-triangle query: a tree has depth <= 30 + 31
// (bvh.hpp, build step 4) and a depth-first walk holds at most depth + 2 entries.
constexpr int kMaxStack = 128;

template <class S>
inline Aabb<S> emptyBox() {
  constexpr S inf = std::numeric_limits<S>::infinity();
  return {{inf, inf, inf}, {-inf, -inf, -inf}};
}

template <class S>
inline Aabb<S> merged(const Aabb<S>& a, const Aabb<S>& b) {
  Aabb<S> m;
  for (int k = 0; k < 3; ++k) {
    m.lo[k] = std::min(a.lo[k], b.lo[k]);
    m.hi[k] = std::max(a.hi[k], b.hi[k]);
  }
  return m;
}

/// The 10 low bits of v spread to every third bit.
inline std::uint32_t spreadBits(std::uint32_t v) {
  v = (v * 0x00010001u) & 0xFF0000FFu;
  v = (v * 0x00000101u) & 0x0F00F00Fu;
  v = (v * 0x00000011u) & 0xC30C30C3u;
  v = (v * 0x00000005u) & 0x49249249u;
  return v;
}

/// Quantised coordinate in [0, 1023]; NaN goes to 0.
template <class S>
inline std::uint32_t quantise(S value, S lo, S scale) {
  S q = (value - lo) * scale;
  q = q > S(0) ? (q < S(kRadix - 1) ? q : S(kRadix - 1)) : S(0);
  return static_cast<std::uint32_t>(q);
}

/// Karras' split of the sorted range [lo, hi] (lo < hi): the last index of the left half.
inline Index findSplit(const std::uint32_t* codes, Index lo, Index hi) {
  const std::uint32_t first = codes[lo];
  const std::uint32_t last = codes[hi];
  if (first == last) return lo + (hi - lo) / 2;
  // The codes are sorted and share their bits above the highest differing one, h: the right
  // half starts at the first code with bit h set, i.e. >= the first's prefix followed by h.
  const std::uint32_t bit = 0x80000000u >> std::countl_zero(first ^ last);
  const std::uint32_t threshold = (first & ~(bit - 1) & ~bit) | bit;
  const std::uint32_t* base = codes + lo + 1;  // codes[lo] < threshold <= codes[hi]
  Index count = hi - lo;
  while (count > 1) {  // branch-free lower bound
    const Index half = count / 2;
    base += -static_cast<Index>(base[half - 1] < threshold) & half;  // (a mask: compilers branch on a ?:)
    count -= half;
  }
  base += *base < threshold;
  return static_cast<Index>(base - codes) - 1;
}

struct Range {
  Index node, lo, hi, depth;
};

/// Box overlap without short-circuit branches (a traversal's tests are unpredictable), with
/// SSE (float) or AVX2 (double) where available: 4-lane unaligned loads of the box's scalars
/// 0-3 {lo0, lo1, lo2, hi0} and 2-5 {lo2, hi0, hi1, hi2}, both inside the box, then two
/// comparisons (1.7x faster than the scalar form in a micro-benchmark on this machine).
/// NaN or empty boxes overlap nothing.
template <class S>
inline bool overlap(const Aabb<S>& a, const Aabb<S>& b) {
  return (a.lo[0] <= b.hi[0]) & (b.lo[0] <= a.hi[0]) & (a.lo[1] <= b.hi[1]) & (b.lo[1] <= a.hi[1]) &
         (a.lo[2] <= b.hi[2]) & (b.lo[2] <= a.hi[2]);
}
static_assert(sizeof(Aabb<float>) == 6 * sizeof(float) && sizeof(Aabb<double>) == 6 * sizeof(double));
#if defined(__SSE__)
template <>
inline bool overlap(const Aabb<float>& a, const Aabb<float>& b) {
  const float* pa = reinterpret_cast<const float*>(&a);  // lo[0..2], hi[0..2]: six contiguous floats
  const float* pb = reinterpret_cast<const float*>(&b);
  const __m128 aLo = _mm_loadu_ps(pa);
  const __m128 bLo = _mm_loadu_ps(pb);
  const __m128 aHi4 = _mm_loadu_ps(pa + 2);
  const __m128 bHi4 = _mm_loadu_ps(pb + 2);
  const __m128 aHi = _mm_shuffle_ps(aHi4, aHi4, _MM_SHUFFLE(3, 3, 2, 1));  // hi0 hi1 hi2 hi2
  const __m128 bHi = _mm_shuffle_ps(bHi4, bHi4, _MM_SHUFFLE(3, 3, 2, 1));
  const __m128 ok = _mm_and_ps(_mm_cmple_ps(aLo, bHi), _mm_cmple_ps(bLo, aHi));
  return (_mm_movemask_ps(ok) & 7) == 7;
}
#endif
#if defined(__AVX2__)
template <>
inline bool overlap(const Aabb<double>& a, const Aabb<double>& b) {
  const double* pa = reinterpret_cast<const double*>(&a);
  const double* pb = reinterpret_cast<const double*>(&b);
  const __m256d aLo = _mm256_loadu_pd(pa);
  const __m256d bLo = _mm256_loadu_pd(pb);
  const __m256d aHi4 = _mm256_loadu_pd(pa + 2);
  const __m256d bHi4 = _mm256_loadu_pd(pb + 2);
  const __m256d aHi = _mm256_permute4x64_pd(aHi4, _MM_SHUFFLE(3, 3, 2, 1));
  const __m256d bHi = _mm256_permute4x64_pd(bHi4, _MM_SHUFFLE(3, 3, 2, 1));
  const __m256d ok = _mm256_and_pd(_mm256_cmp_pd(aLo, bHi, _CMP_LE_OQ), _mm256_cmp_pd(bLo, aHi, _CMP_LE_OQ));
  return (_mm256_movemask_pd(ok) & 7) == 7;
}
#endif

/// Sorts pairs by (first, second). With at least a pair per four values of `first` (a
/// self-collision list: a few pairs a triangle), a counting sort on `first` (one scatter)
/// and an insertion sort of each run of equal firsts by `second` (a few pairs each);
/// otherwise an LSD radix sort on the significant bits of the two indices, 11 bits per pass
/// (comparison sorts mispredict a branch per comparison). The same order either way.
inline void sortPairs(std::vector<TrianglePair>& pairs, std::vector<std::uint64_t>& keys,
                      std::vector<std::uint64_t>& swap, std::vector<Index>& histogram) {
  const size_t n = pairs.size();
  if (n < 256) {
    std::sort(pairs.begin(), pairs.end());
    return;
  }
  std::uint32_t maxFirst = 0, maxSecond = 0;
  for (const TrianglePair& p : pairs) {
    maxFirst = std::max(maxFirst, static_cast<std::uint32_t>(p.first));
    maxSecond = std::max(maxSecond, static_cast<std::uint32_t>(p.second));
  }
  if (static_cast<size_t>(maxFirst) < 4 * n) {
    // histogram[f] = where the run of first f starts, then (as the scatter fills it) ends.
    const size_t buckets = static_cast<size_t>(maxFirst) + 1;
    histogram.assign(buckets + 1, 0);
    for (const TrianglePair& p : pairs) ++histogram[static_cast<size_t>(p.first) + 1];
    for (size_t b = 1; b <= buckets; ++b) histogram[b] += histogram[b - 1];
    swap.resize(n);
    std::uint64_t* out = swap.data();
    for (const TrianglePair& p : pairs)
      out[static_cast<size_t>(histogram[static_cast<size_t>(p.first)]++)] =
          std::uint64_t(static_cast<std::uint32_t>(p.first)) << 32 | static_cast<std::uint32_t>(p.second);
    // Each run by second (the key's low half; the high half is equal).
    size_t begin = 0;
    for (size_t f = 0; f < buckets; ++f) {
      const size_t end = static_cast<size_t>(histogram[f]);
      if (end - begin > 32) {
        std::sort(out + begin, out + end);
      } else {
        for (size_t i = begin + 1; i < end; ++i) {
          const std::uint64_t key = out[i];
          size_t j = i;
          for (; j > begin && out[j - 1] > key; --j) out[j] = out[j - 1];
          out[j] = key;
        }
      }
      begin = end;
    }
    for (size_t i = 0; i < n; ++i)
      pairs[i] = {static_cast<Index>(out[i] >> 32), static_cast<Index>(out[i] & 0xFFFFFFFFu)};
    return;
  }
  const int secondBits = std::bit_width(maxSecond);
  const int bits = std::bit_width(maxFirst) + secondBits;
  constexpr int kBits = 11;
  constexpr std::uint64_t kMask = (1u << kBits) - 1;
  keys.resize(n);
  swap.resize(n);
  histogram.resize(size_t(1) << kBits);
  for (size_t i = 0; i < n; ++i)
    keys[i] = (std::uint64_t(static_cast<std::uint32_t>(pairs[i].first)) << secondBits) |
              static_cast<std::uint32_t>(pairs[i].second);
  for (int shift = 0; shift < bits; shift += kBits) {
    std::fill(histogram.begin(), histogram.end(), 0);
    for (size_t i = 0; i < n; ++i) ++histogram[(keys[i] >> shift) & kMask];
    Index running = 0;
    for (Index& h : histogram) {
      const Index count = h;
      h = running;
      running += count;
    }
    for (size_t i = 0; i < n; ++i) swap[static_cast<size_t>(histogram[(keys[i] >> shift) & kMask]++)] = keys[i];
    keys.swap(swap);
  }
  const std::uint64_t secondMask = (std::uint64_t(1) << secondBits) - 1;
  for (size_t i = 0; i < n; ++i)
    pairs[i] = {static_cast<Index>(keys[i] >> secondBits), static_cast<Index>(keys[i] & secondMask)};
}

/// A number in an error message, all its digits.

}  // namespace weft::bvh_detail
