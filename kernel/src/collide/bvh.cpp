#include "weft/collide/bvh.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "closest_point.hpp"

namespace weft {

namespace {

constexpr int kRadixBits = 10;  // per radix pass and per Morton axis
constexpr Index kRadix = Index(1) << kRadixBits;
constexpr int kRadixPasses = 3;
// Stacks of the build and of the closest-triangle query: a tree has depth <= 30 + 31
// (bvh.hpp, build step 4) and a depth-first walk holds at most depth + 2 entries.
constexpr int kMaxStack = 128;

template <class S>
Aabb<S> emptyBox() {
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

/// Sorts pairs by (first, second): an LSD radix sort on the significant bits of the two
/// indices, 11 bits per pass (comparison sorts mispredict a branch per comparison).
void sortPairs(std::vector<TrianglePair>& pairs, std::vector<std::uint64_t>& keys, std::vector<std::uint64_t>& swap,
               std::vector<Index>& histogram) {
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
std::string text(double value) {
  std::ostringstream out;
  out.precision(17);
  out << value;
  return out.str();
}

}  // namespace

template <class S>
Index TriangleBvh<S>::root() const {
  const Index n = triangleCount();
  return n == 0 ? kNoRoot : (n == 1 ? ~Index(0) : Index(0));
}

template <class S>
void TriangleBvh<S>::checkPositions(const char* what, const Vec3Array<S>& x) const {
  if (x.rows() != vertexCount_) {
    throw std::invalid_argument(std::string("TriangleBvh::") + what + ": x has " + std::to_string(x.rows()) +
                                " rows, the BVH was built over " + std::to_string(vertexCount_) + " vertices");
  }
}

template <class S>
void TriangleBvh<S>::build(const Vec3Array<S>& x, const Triangles& triangles, const Executor& exec, double margin) {
  if (!std::isfinite(margin) || margin < 0) {
    throw std::invalid_argument("TriangleBvh::build: margin must be finite and >= 0, got " + text(margin));
  }
  const Index n = triangles.count();
  if (triangles.b.rows() != n || triangles.c.rows() != n) {
    throw std::invalid_argument("TriangleBvh::build: triangles.a, .b, .c must have the same length, got " +
                                std::to_string(n) + ", " + std::to_string(triangles.b.rows()) + ", " +
                                std::to_string(triangles.c.rows()));
  }
  const Index nv = static_cast<Index>(x.rows());
  const Index* ia = triangles.a.data();
  const Index* ib = triangles.b.data();
  const Index* ic = triangles.c.data();
  const S* xs = x.data();
  const S* ys = xs + nv;
  const S* zs = ys + nv;

  // 1. Validation and the bounds of the centroids (sums of corners: the scale does not matter).
  const Index blocks = Executor::blockCount(n, kBuildGrain);
  blockBounds_.resize(static_cast<size_t>(blocks));
  blockBad_.resize(static_cast<size_t>(blocks));
  centroids_.resize(3 * static_cast<size_t>(n));
  S* cx = centroids_.data();
  S* cy = cx + n;
  S* cz = cy + n;
  exec.parallelForBlocks(n, kBuildGrain, [&](Index k, Index b, Index e) {
    Aabb<S> box = emptyBox<S>();
    Index bad = -1;
    for (Index t = b; t < e; ++t) {
      const Index i = ia[t], j = ib[t], l = ic[t];
      if (static_cast<std::uint32_t>(i) >= static_cast<std::uint32_t>(nv) ||
          static_cast<std::uint32_t>(j) >= static_cast<std::uint32_t>(nv) ||
          static_cast<std::uint32_t>(l) >= static_cast<std::uint32_t>(nv)) {
        if (bad < 0) bad = t;
        cx[t] = cy[t] = cz[t] = 0;
        continue;
      }
      const S c[3] = {xs[i] + xs[j] + xs[l], ys[i] + ys[j] + ys[l], zs[i] + zs[j] + zs[l]};
      cx[t] = c[0];
      cy[t] = c[1];
      cz[t] = c[2];
      for (int a = 0; a < 3; ++a) {
        box.lo[a] = std::min(box.lo[a], c[a]);
        box.hi[a] = std::max(box.hi[a], c[a]);
      }
    }
    blockBounds_[static_cast<size_t>(k)] = box;
    blockBad_[static_cast<size_t>(k)] = bad;
  });
  for (Index k = 0; k < blocks; ++k) {
    const Index t = blockBad_[static_cast<size_t>(k)];
    if (t < 0) continue;
    const char* field = "a";
    Index value = ia[t];
    if (ia[t] >= 0 && ia[t] < nv) {
      field = (ib[t] < 0 || ib[t] >= nv) ? "b" : "c";
      value = field[0] == 'b' ? ib[t] : ic[t];
    }
    throw std::invalid_argument("TriangleBvh::build: triangle " + std::to_string(t) + " corner " + field + " = " +
                                std::to_string(value) + " is not a vertex (x has " + std::to_string(nv) + " rows)");
  }

  vertexCount_ = nv;
  margin_ = static_cast<S>(margin);
  depth_ = 0;
  const size_t sn = static_cast<size_t>(n);
  nodes_.resize(n > 0 ? sn - 1 : 0);
  boxes_.resize(n > 0 ? 2 * sn - 1 : 0);
  slotTriangle_.resize(sn);
  corners_.resize(sn);
  keys_.resize(sn);
  keysSwap_.resize(sn);
  codes_.resize(sn);
  subtrees_.clear();
  subtrees_.reserve(sn / 2 + 1);  // subtrees are disjoint and have >= 2 leaves
  topNodes_.clear();
  topNodes_.reserve(sn);
  if (n == 0) {
    rootBox_ = emptyBox<S>();
    return;
  }

  // 2. Morton codes of the centroids.
  Aabb<S> bounds = blockBounds_[0];
  for (Index k = 1; k < blocks; ++k) bounds = merged(bounds, blockBounds_[static_cast<size_t>(k)]);
  const S extent = std::max({bounds.hi[0] - bounds.lo[0], bounds.hi[1] - bounds.lo[1], bounds.hi[2] - bounds.lo[2]});
  const S scale = extent > S(0) ? S(kRadix) / extent : S(0);
  std::uint64_t* keys = keys_.data();
  exec.parallelFor(n, kBuildGrain, [&](Index b, Index e) {
    for (Index t = b; t < e; ++t) {
      const std::uint32_t code = (spreadBits(quantise(cx[t], bounds.lo[0], scale)) << 2) |
                                 (spreadBits(quantise(cy[t], bounds.lo[1], scale)) << 1) |
                                 spreadBits(quantise(cz[t], bounds.lo[2], scale));
      keys[t] = (std::uint64_t(code) << 32) | std::uint32_t(t);
    }
  });

  // 3. Sort by (code, triangle).
  sortKeys(exec);
  exec.parallelFor(n, kBuildGrain, [&](Index b, Index e) {
    for (Index s = b; s < e; ++s) {
      const std::uint64_t key = keys_[static_cast<size_t>(s)];
      const Index t = static_cast<Index>(key & 0xFFFFFFFFu);
      codes_[static_cast<size_t>(s)] = static_cast<std::uint32_t>(key >> 32);
      slotTriangle_[static_cast<size_t>(s)] = t;
      corners_[static_cast<size_t>(s)] = {ia[t], ib[t], ic[t]};
    }
  });

  // 4. Hierarchy; 5. boxes.
  buildHierarchy(exec);
  refit(x, exec);
}

template <class S>
void TriangleBvh<S>::sortKeys(const Executor& exec) {
  const Index n = static_cast<Index>(keys_.size());
  const Index blocks = Executor::blockCount(n, kSortGrain);
  histogram_.resize(static_cast<size_t>(blocks * kRadix));
  std::uint64_t* src = keys_.data();
  std::uint64_t* dst = keysSwap_.data();
  Index* histogram = histogram_.data();
  bool swapped = false;
  for (int pass = 0; pass < kRadixPasses; ++pass) {
    const int shift = 32 + pass * kRadixBits;
    exec.parallelForBlocks(n, kSortGrain, [&](Index k, Index b, Index e) {
      Index* h = histogram + k * kRadix;
      std::fill(h, h + kRadix, 0);
      for (Index i = b; i < e; ++i) ++h[(src[i] >> shift) & (kRadix - 1)];
    });
    // Offsets in (digit, block) order: the scatter keeps the input order within a digit.
    Index running = 0;
    bool oneDigit = false;
    for (Index d = 0; d < kRadix; ++d) {
      const Index start = running;
      for (Index k = 0; k < blocks; ++k) {
        Index& h = histogram[k * kRadix + d];
        const Index count = h;
        h = running;
        running += count;
      }
      if (running - start == n) oneDigit = true;
    }
    if (oneDigit) continue;  // every key has this digit: the pass would not move anything
    exec.parallelForBlocks(n, kSortGrain, [&](Index k, Index b, Index e) {
      Index* offset = histogram + k * kRadix;
      for (Index i = b; i < e; ++i) {
        const std::uint64_t key = src[i];
        dst[offset[(key >> shift) & (kRadix - 1)]++] = key;
      }
    });
    std::swap(src, dst);
    swapped = !swapped;
  }
  if (swapped) keys_.swap(keysSwap_);
}

template <class S>
void TriangleBvh<S>::buildHierarchy(const Executor& exec) {
  const Index n = triangleCount();
  if (n < 2) return;
  const std::uint32_t* codes = codes_.data();
  // The part above the subtrees, serially, depth first (pre-order: left pushed last).
  Range stack[kMaxStack];
  int top = 0;
  stack[top++] = {0, 0, n - 1, 0};
  while (top > 0) {
    const Range r = stack[--top];
    if (r.hi - r.lo + 1 <= kSubtreeLeaves) {
      subtrees_.push_back({r.node, r.lo, r.hi, r.depth});
      continue;
    }
    topNodes_.push_back(r.node);
    const Index s = findSplit(codes, r.lo, r.hi);
    BvhNode<S>& node = nodes_[static_cast<size_t>(r.node)];
    node.child[0] = s == r.lo ? ~r.lo : r.node + 1;
    node.child[1] = s + 1 == r.hi ? ~r.hi : r.node + 1 + (s - r.lo);
    depth_ = std::max(depth_, r.depth + 1);
    if (node.child[1] >= 0) stack[top++] = {node.child[1], s + 1, r.hi, r.depth + 1};
    if (node.child[0] >= 0) stack[top++] = {node.child[0], r.lo, s, r.depth + 1};
  }
  // The subtrees, one task each.
  exec.parallelFor(static_cast<Index>(subtrees_.size()), 1, [&](Index b, Index e) {
    for (Index k = b; k < e; ++k) {
      Subtree& tree = subtrees_[static_cast<size_t>(k)];
      Range local[kMaxStack];
      int size = 0;
      Index deepest = tree.depth;
      local[size++] = {tree.node, tree.firstSlot, tree.lastSlot, tree.depth};
      while (size > 0) {
        const Range r = local[--size];
        const Index s = findSplit(codes, r.lo, r.hi);
        BvhNode<S>& node = nodes_[static_cast<size_t>(r.node)];
        node.child[0] = s == r.lo ? ~r.lo : r.node + 1;
        node.child[1] = s + 1 == r.hi ? ~r.hi : r.node + 1 + (s - r.lo);
        deepest = std::max(deepest, r.depth + 1);
        local[size] = {node.child[1], s + 1, r.hi, r.depth + 1};  // pushes without branches
        size += node.child[1] >= 0;
        local[size] = {node.child[0], r.lo, s, r.depth + 1};
        size += node.child[0] >= 0;
      }
      tree.depth = deepest;
    }
  });
  for (const Subtree& tree : subtrees_) depth_ = std::max(depth_, tree.depth);
}

template <class S>
template <class LeafBox>
void TriangleBvh<S>::refitWith(const LeafBox& leafBox, const Executor& exec) {
  const Index n = triangleCount();
  if (n == 0) return;
  Aabb<S>* boxes = boxes_.data();
  if (n == 1) {
    boxes[0] = leafBox(0);
    rootBox_ = boxes[0];
    return;
  }
  BvhNode<S>* nodes = nodes_.data();
  Aabb<S>* leaves = boxes + (n - 1);
  const Index leafBase = n - 1;
  // Every node's own box is kept too (boxes[q]), so that a child's box is one load whether
  // the child is a node or a leaf (no branch on the kind of child).
  const auto refitNode = [nodes, boxes, leafBase](Index q) {
    BvhNode<S>& node = nodes[q];
    const Index c0 = node.child[0], c1 = node.child[1];
    const Aabb<S> b0 = boxes[c0 >= 0 ? c0 : leafBase + ~c0];
    const Aabb<S> b1 = boxes[c1 >= 0 ? c1 : leafBase + ~c1];
    node.box[0] = b0;
    node.box[1] = b1;
    boxes[q] = merged(b0, b1);
  };
  exec.parallelFor(static_cast<Index>(subtrees_.size()), 1, [&](Index b, Index e) {
    for (Index k = b; k < e; ++k) {
      const Subtree& tree = subtrees_[static_cast<size_t>(k)];
      for (Index s = tree.firstSlot; s <= tree.lastSlot; ++s) leaves[s] = leafBox(s);
      for (Index q = tree.node + (tree.lastSlot - tree.firstSlot) - 1; q >= tree.node; --q) refitNode(q);
    }
  });
  for (auto it = topNodes_.rbegin(); it != topNodes_.rend(); ++it) {
    const BvhNode<S>& node = nodes[*it];
    for (int c = 0; c < 2; ++c)
      if (node.child[c] < 0) leaves[~node.child[c]] = leafBox(~node.child[c]);
    refitNode(*it);
  }
  rootBox_ = boxes[0];
}

template <class S>
void TriangleBvh<S>::refit(const Vec3Array<S>& x, const Executor& exec) {
  checkPositions("refit", x);
  const Index nv = vertexCount_;
  const S* col[3] = {x.data(), x.data() + nv, x.data() + 2 * nv};
  const S m = margin_;
  const std::array<Index, 3>* corners = corners_.data();
  refitWith(
      [&](Index s) {
        const std::array<Index, 3>& c = corners[s];
        Aabb<S> box;
        for (int k = 0; k < 3; ++k) {
          const S v0 = col[k][c[0]], v1 = col[k][c[1]], v2 = col[k][c[2]];
          box.lo[k] = std::min(std::min(v0, v1), v2) - m;
          box.hi[k] = std::max(std::max(v0, v1), v2) + m;
        }
        return box;
      },
      exec);
}

template <class S>
void TriangleBvh<S>::refitSwept(const Vec3Array<S>& x0, const Vec3Array<S>& x1, const Executor& exec) {
  checkPositions("refitSwept", x0);
  checkPositions("refitSwept", x1);
  const Index nv = vertexCount_;
  const S* col0[3] = {x0.data(), x0.data() + nv, x0.data() + 2 * nv};
  const S* col1[3] = {x1.data(), x1.data() + nv, x1.data() + 2 * nv};
  const S m = margin_;
  const std::array<Index, 3>* corners = corners_.data();
  refitWith(
      [&](Index s) {
        const std::array<Index, 3>& c = corners[s];
        Aabb<S> box;
        for (int k = 0; k < 3; ++k) {
          const S u0 = col0[k][c[0]], u1 = col0[k][c[1]], u2 = col0[k][c[2]];
          const S v0 = col1[k][c[0]], v1 = col1[k][c[1]], v2 = col1[k][c[2]];
          box.lo[k] = std::min(std::min(std::min(u0, u1), std::min(u2, v0)), std::min(v1, v2)) - m;
          box.hi[k] = std::max(std::max(std::max(u0, u1), std::max(u2, v0)), std::max(v1, v2)) + m;
        }
        return box;
      },
      exec);
}

template <class S>
std::optional<ClosestTriangle<S>> TriangleBvh<S>::closestTriangle(const Vec3Array<S>& x, const Vec3<S>& p,
                                                                  S radius) const {
  if (!(radius >= S(0))) {
    throw std::invalid_argument("TriangleBvh::closestTriangle: radius must be >= 0, got " +
                                text(static_cast<double>(radius)));
  }
  checkPositions("closestTriangle", x);
  if (empty()) return std::nullopt;
  const Index nv = vertexCount_;
  const S* col[3] = {x.data(), x.data() + nv, x.data() + 2 * nv};

  // Pruning slack: the computed closest point may lie a few ulps of the coordinates off the
  // triangle, so a box is skipped only when it is farther than the best distance by more.
  constexpr S eps = std::numeric_limits<S>::epsilon();
  S coordinateScale = std::max({std::abs(p[0]), std::abs(p[1]), std::abs(p[2])});
  for (int k = 0; k < 3; ++k)
    coordinateScale = std::max({coordinateScale, std::abs(rootBox_.lo[k]), std::abs(rootBox_.hi[k])});
  const S slack = S(32) * eps * coordinateScale;
  S best2 = radius * radius;
  Index bestTriangle = -1;
  Vec3<S> bestPoint = Vec3<S>::Zero();
  const auto pruneBound = [&] {
    const S r = std::sqrt(best2) + slack;
    return r * r * (S(1) + S(8) * eps);
  };
  S bound = pruneBound();

  const auto boxDistance2 = [&p](const Aabb<S>& box) {
    S d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const S d = std::max(box.lo[k] - p[k], p[k] - box.hi[k]);
      if (d > S(0)) d2 += d * d;
    }
    return d2;
  };
  const auto testLeaf = [&](Index slot) {
    const std::array<Index, 3>& c = corners_[static_cast<size_t>(slot)];
    const Vec3<S> a(col[0][c[0]], col[1][c[0]], col[2][c[0]]);
    const Vec3<S> b(col[0][c[1]], col[1][c[1]], col[2][c[1]]);
    const Vec3<S> cc(col[0][c[2]], col[1][c[2]], col[2][c[2]]);
    const Vec3<S> q = detail::closestOnTriangle(p, a, b, cc);
    const S d2 = (p - q).squaredNorm();
    const Index t = slotTriangle_[static_cast<size_t>(slot)];
    if (d2 < best2 || (d2 == best2 && (bestTriangle < 0 || t < bestTriangle))) {
      best2 = d2;
      bestTriangle = t;
      bestPoint = q;
      bound = pruneBound();
    }
  };

  if (triangleCount() == 1) {
    testLeaf(0);
  } else {
    struct Item {
      Index node;
      S d2;
    };
    Item stack[kMaxStack];
    int top = 0;
    stack[top++] = {0, boxDistance2(rootBox_)};
    while (top > 0) {
      const Item item = stack[--top];
      if (item.d2 > bound) continue;
      const BvhNode<S>& node = nodes_[static_cast<size_t>(item.node)];
      const S d0 = boxDistance2(node.box[0]);
      const S d1 = boxDistance2(node.box[1]);
      const Index c0 = node.child[0], c1 = node.child[1];
      if (c0 < 0 && d0 <= bound) testLeaf(~c0);
      if (c1 < 0 && d1 <= bound) testLeaf(~c1);
      const bool in0 = c0 >= 0 && d0 <= bound;
      const bool in1 = c1 >= 0 && d1 <= bound;
      if (in0 && in1) {  // the nearer one on top
        if (d0 <= d1) {
          stack[top++] = {c1, d1};
          stack[top++] = {c0, d0};
        } else {
          stack[top++] = {c0, d0};
          stack[top++] = {c1, d1};
        }
      } else if (in0) {
        stack[top++] = {c0, d0};
      } else if (in1) {
        stack[top++] = {c1, d1};
      }
    }
  }
  if (bestTriangle < 0) return std::nullopt;
  return ClosestTriangle<S>{bestTriangle, bestPoint, best2};
}

template <class S>
template <bool kSelf, bool kExact>
void TriangleBvh<S>::pairQuery(const TriangleBvh& other, const Vec3Array<S>* x, const Vec3Array<S>* xOther,
                               std::vector<TrianglePair>& out, BvhPairScratch& scratch, const Executor& exec) const {
  using Task = std::array<Index, 2>;  // node references; in self queries {a, a} means "all pairs within a"
  out.clear();
  const TriangleBvh& A = *this;
  const TriangleBvh& B = other;
  if (A.empty() || B.empty()) return;
  if (kSelf && A.triangleCount() < 2) return;
  if (!kSelf && !A.rootBox_.overlaps(B.rootBox_)) return;

  // Pushes the subtasks of a task that is not a pair of leaves: push(task, keep).
  const auto expand = [&](const Task& task, auto&& push) {
    const Index a = task[0], b = task[1];
    if (kSelf && a == b) {
      const BvhNode<S>& node = A.nodes_[static_cast<size_t>(a)];
      push(Task{node.child[0], node.child[0]}, node.child[0] >= 0);
      push(Task{node.child[1], node.child[1]}, node.child[1] >= 0);
      push(Task{node.child[0], node.child[1]}, overlap(node.box[0], node.box[1]));
    } else if (a >= 0 && b >= 0) {
      const BvhNode<S>& na = A.nodes_[static_cast<size_t>(a)];
      const BvhNode<S>& nb = B.nodes_[static_cast<size_t>(b)];
      push(Task{na.child[0], nb.child[0]}, overlap(na.box[0], nb.box[0]));
      push(Task{na.child[0], nb.child[1]}, overlap(na.box[0], nb.box[1]));
      push(Task{na.child[1], nb.child[0]}, overlap(na.box[1], nb.box[0]));
      push(Task{na.child[1], nb.child[1]}, overlap(na.box[1], nb.box[1]));
    } else if (a >= 0) {
      const BvhNode<S>& na = A.nodes_[static_cast<size_t>(a)];
      const Aabb<S>& leaf = B.leafBox(~b);
      push(Task{na.child[0], b}, overlap(na.box[0], leaf));
      push(Task{na.child[1], b}, overlap(na.box[1], leaf));
    } else {
      const BvhNode<S>& nb = B.nodes_[static_cast<size_t>(b)];
      const Aabb<S>& leaf = A.leafBox(~a);
      push(Task{a, nb.child[0]}, overlap(leaf, nb.box[0]));
      push(Task{a, nb.child[1]}, overlap(leaf, nb.box[1]));
    }
  };
  // Whether the leaves of slots sa, sb make a reported pair (the boxes overlap already).
  const S* ax[3] = {nullptr, nullptr, nullptr};
  const S* bx[3] = {nullptr, nullptr, nullptr};
  if constexpr (kExact) {
    for (int k = 0; k < 3; ++k) {
      ax[k] = x->data() + k * A.vertexCount_;
      bx[k] = xOther->data() + k * B.vertexCount_;
    }
  }
  const auto keep = [&](Index sa, Index sb) {
    const std::array<Index, 3>& ca = A.corners_[static_cast<size_t>(sa)];
    const std::array<Index, 3>& cb = B.corners_[static_cast<size_t>(sb)];
    if constexpr (kSelf) {
      if ((ca[0] == cb[0]) | (ca[0] == cb[1]) | (ca[0] == cb[2]) | (ca[1] == cb[0]) | (ca[1] == cb[1]) |
          (ca[1] == cb[2]) | (ca[2] == cb[0]) | (ca[2] == cb[1]) | (ca[2] == cb[2]))
        return false;
    }
    if constexpr (kExact) {
      Vec3<double> p[6];
      for (int i = 0; i < 3; ++i) {
        p[i] = Vec3<double>(ax[0][ca[i]], ax[1][ca[i]], ax[2][ca[i]]);
        p[3 + i] = Vec3<double>(bx[0][cb[i]], bx[1][cb[i]], bx[2][cb[i]]);
      }
      return trianglesIntersect(p[0], p[1], p[2], p[3], p[4], p[5]);
    }
    return true;
  };

  // The front: breadth-first expansion in a fixed order.
  std::vector<Task>& front = scratch.front_;
  std::vector<Task>& next = scratch.next_;
  front.clear();
  front.push_back(kSelf ? Task{0, 0} : Task{A.root(), B.root()});
  while (static_cast<Index>(front.size()) < kFrontTasks) {
    next.clear();
    bool expanded = false;
    for (const Task& task : front) {
      if ((task[0] & task[1]) < 0) {  // both leaves
        next.push_back(task);
      } else {
        expand(task, [&](const Task& t, bool keepTask) {
          if (keepTask) next.push_back(t);
        });
        expanded = true;
      }
    }
    front.swap(next);
    if (!expanded) break;
  }

  // The tasks, each into its own buffers. Within a task the node pairs are expanded level by
  // level (breadth first): the pairs of a level are independent, so their node loads overlap,
  // where a depth-first stack chains every load to the previous pair's tests. A leaf side is a
  // pseudo-node whose first box is the leaf's and whose second is empty (it overlaps nothing),
  // so every pair tests 2 x 2 boxes; a child pair goes to the next level or, if both are
  // leaves, to the leaf pairs, by index arithmetic only (no branch on the kinds of nodes).
  const Index tasks = static_cast<Index>(front.size());
  if (static_cast<Index>(scratch.taskPairs_.size()) < tasks) scratch.taskPairs_.resize(static_cast<size_t>(tasks));
  exec.parallelFor(tasks, 1, [&](Index begin, Index end) {
    const BvhNode<S>* nodesA = A.nodes_.data();
    const BvhNode<S>* nodesB = B.nodes_.data();
    const Aabb<S>* leavesA = &A.leafBox(0);
    const Aabb<S>* leavesB = &B.leafBox(0);
    for (Index k = begin; k < end; ++k) {
      BvhPairScratch::TaskPairs& work = scratch.taskPairs_[static_cast<size_t>(k)];
      std::vector<Task>* current = &work.level[0];
      std::vector<Task>* following = &work.level[1];
      if (current->empty()) current->resize(1);
      if (work.pairs.size() < 4) work.pairs.resize(4);
      Index found = 0, count = 0;
      const Task start = front[static_cast<size_t>(k)];
      if ((start[0] & start[1]) < 0) {
        work.pairs[static_cast<size_t>(found++)] = {~start[0], ~start[1]};
      } else {
        (*current)[static_cast<size_t>(count++)] = start;
      }
      BvhNode<S> pseudoA{}, pseudoB{};
      pseudoA.box[1] = pseudoB.box[1] = emptyBox<S>();
      while (count > 0) {
        const size_t bound = 4 * static_cast<size_t>(count);  // a pair has at most 4 subtasks
        if (following->size() < bound) following->resize(bound);
        if (work.pairs.size() < static_cast<size_t>(found) + bound)
          work.pairs.resize(static_cast<size_t>(found) + bound);
        const Task* in = current->data();
        Task* nextLevel = following->data();
        TrianglePair* leaves = work.pairs.data() + found;
        Index n = 0, f = 0;
        for (Index i = 0; i < count; ++i) {
          const Index a = in[i][0], b = in[i][1];
          if (kSelf && a == b) {  // all pairs within node a
            expand(in[i], [&](const Task& t, bool keepTask) {
              nextLevel[n] = t;
              n += keepTask & ((t[0] & t[1]) >= 0);
              leaves[f] = {~t[0], ~t[1]};
              f += keepTask & ((t[0] & t[1]) < 0);
            });
            continue;
          }
          pseudoA.box[0] = leavesA[a < 0 ? ~a : 0];
          pseudoA.child[0] = a;
          pseudoB.box[0] = leavesB[b < 0 ? ~b : 0];
          pseudoB.child[0] = b;
          const BvhNode<S>* na = a >= 0 ? nodesA + a : &pseudoA;
          const BvhNode<S>* nb = b >= 0 ? nodesB + b : &pseudoB;
          for (int ci = 0; ci < 2; ++ci) {
            for (int cj = 0; cj < 2; ++cj) {
              const Index ta = na->child[ci], tb = nb->child[cj];
              const bool hit = overlap(na->box[ci], nb->box[cj]);
              const bool bothLeaves = (ta & tb) < 0;
              nextLevel[n] = {ta, tb};
              n += hit & !bothLeaves;
              leaves[f] = {~ta, ~tb};
              f += hit & bothLeaves;
            }
          }
        }
        found += f;
        count = n;
        std::swap(current, following);
      }
      // The filter and the slot -> triangle mapping, in place.
      Index kept = 0;
      for (Index i = 0; i < found; ++i) {
        const TrianglePair slots = work.pairs[static_cast<size_t>(i)];
        if (!keep(slots.first, slots.second)) continue;
        Index ta = A.slotTriangle_[static_cast<size_t>(slots.first)];
        Index tb = B.slotTriangle_[static_cast<size_t>(slots.second)];
        if (kSelf && ta > tb) std::swap(ta, tb);
        work.pairs[static_cast<size_t>(kept++)] = {ta, tb};
      }
      work.count = kept;
    }
  });
  size_t total = 0;
  for (Index k = 0; k < tasks; ++k) total += static_cast<size_t>(scratch.taskPairs_[static_cast<size_t>(k)].count);
  out.reserve(total);
  for (Index k = 0; k < tasks; ++k) {
    const BvhPairScratch::TaskPairs& work = scratch.taskPairs_[static_cast<size_t>(k)];
    out.insert(out.end(), work.pairs.begin(), work.pairs.begin() + work.count);
  }
  sortPairs(out, scratch.keys_, scratch.keysSwap_, scratch.histogram_);
}

template <class S>
void TriangleBvh<S>::overlappingPairs(const TriangleBvh& other, std::vector<TrianglePair>& out, BvhPairScratch& scratch,
                                      const Executor& exec) const {
  pairQuery<false, false>(other, nullptr, nullptr, out, scratch, exec);
}

template <class S>
void TriangleBvh<S>::intersectingPairs(const TriangleBvh& other, const Vec3Array<S>& x, const Vec3Array<S>& xOther,
                                       std::vector<TrianglePair>& out, BvhPairScratch& scratch,
                                       const Executor& exec) const {
  checkPositions("intersectingPairs", x);
  other.checkPositions("intersectingPairs (other)", xOther);
  pairQuery<false, true>(other, &x, &xOther, out, scratch, exec);
}

template <class S>
void TriangleBvh<S>::selfPairs(std::vector<TrianglePair>& out, BvhPairScratch& scratch, const Executor& exec) const {
  pairQuery<true, false>(*this, nullptr, nullptr, out, scratch, exec);
}

template <class S>
void TriangleBvh<S>::selfIntersectingPairs(const Vec3Array<S>& x, std::vector<TrianglePair>& out,
                                           BvhPairScratch& scratch, const Executor& exec) const {
  checkPositions("selfIntersectingPairs", x);
  pairQuery<true, true>(*this, &x, &x, out, scratch, exec);
}

template class TriangleBvh<float>;
template class TriangleBvh<double>;

}  // namespace weft
