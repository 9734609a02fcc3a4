#include "collide/bvh.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "bvh_internal.hpp"

namespace weft {

using namespace bvh_detail;

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
    throw std::invalid_argument("TriangleBvh::build: margin must be finite and >= 0, got " + detail::number(margin));
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
void TriangleBvh<S>::releaseBuildBuffers() {
  const auto release = [](auto& v) { std::remove_reference_t<decltype(v)>().swap(v); };
  release(keys_);
  release(keysSwap_);
  release(codes_);
  release(centroids_);
  release(histogram_);
  release(blockBounds_);
  release(blockBad_);
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
  bottomUp(
      exec, [&](Index s) { leaves[s] = leafBox(s); }, refitNode);
  rootBox_ = boxes[0];
}

template <class S>
template <class Lo, class Hi>
void TriangleBvh<S>::refitCorners(const Lo& lo, const Hi& hi, const Executor& exec) {
  const S m = margin_;
  const std::array<Index, 3>* corners = corners_.data();
  refitWith(
      [&](Index s) {
        const std::array<Index, 3>& c = corners[s];
        Aabb<S> box;
        for (int k = 0; k < 3; ++k) {
          box.lo[k] = std::min(std::min(lo(c[0], k), lo(c[1], k)), lo(c[2], k)) - m;
          box.hi[k] = std::max(std::max(hi(c[0], k), hi(c[1], k)), hi(c[2], k)) + m;
        }
        return box;
      },
      exec);
}

template <class S>
void TriangleBvh<S>::refit(const Vec3Array<S>& x, const Executor& exec) {
  checkPositions("refit", x);
  const Index nv = vertexCount_;
  const S* col[3] = {x.data(), x.data() + nv, x.data() + 2 * nv};
  const auto at = [&](Index i, int k) { return col[k][i]; };
  refitCorners(at, at, exec);
}

template <class S>
void TriangleBvh<S>::refitSwept(const Vec3Array<S>& x0, const Vec3Array<S>& x1, const Executor& exec) {
  checkPositions("refitSwept", x0);
  checkPositions("refitSwept", x1);
  const Index nv = vertexCount_;
  const S* col0[3] = {x0.data(), x0.data() + nv, x0.data() + 2 * nv};
  const S* col1[3] = {x1.data(), x1.data() + nv, x1.data() + 2 * nv};
  refitCorners([&](Index i, int k) { return std::min(col0[k][i], col1[k][i]); },
               [&](Index i, int k) { return std::max(col0[k][i], col1[k][i]); }, exec);
}

template <class S>
void TriangleBvh<S>::refitBoxes(const std::vector<Aabb<S>>& vertexBox, const Executor& exec) {
  if (static_cast<Index>(vertexBox.size()) != vertexCount_)
    throw std::invalid_argument("TriangleBvh::refitBoxes: " + std::to_string(vertexBox.size()) + " boxes for " +
                                std::to_string(vertexCount_) + " vertices");
  const Aabb<S>* v = vertexBox.data();
  refitCorners([&](Index i, int k) { return v[i].lo[k]; }, [&](Index i, int k) { return v[i].hi[k]; }, exec);
}

template class TriangleBvh<float>;
template class TriangleBvh<double>;

}  // namespace weft
