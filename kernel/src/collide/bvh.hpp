// weft/collide/bvh.hpp — an axis-aligned bounding-box hierarchy over a triangle mesh.
//
// Design note
// -----------
// A TriangleBvh is built over vertex positions (a Vec3Array, e.g. a State's x) and
// index triangles (weft::Triangles, e.g. a cloth Model's), so it serves a cloth and a
// rigid obstacle alike. Boxes are the exact min/max of a triangle's corners, inflated by
// a per-build margin (thickness); refitSwept boxes the corners at the start and at the
// end of a step (for continuous collision).
//
// Layout. A binary tree with one triangle per leaf: n - 1 internal nodes in one flat
// array in depth-first pre-order. A node holds the boxes of its two children and their
// references (>= 0: an internal node, < 0: the leaf of slot ~ref), so a traversal tests
// both children from one node: 64 bytes in float (one cache line), 128 in double. The
// left child of node p, when internal, is node p + 1, and a subtree is one contiguous
// range of nodes. Leaves are "slots": slot s holds triangle slotTriangle(s) and its corner
// indices; slots are in the order of the leaves, the Morton order of the triangles. A
// second array holds every node's own box and every leaf's box (2n - 1 boxes): refit reads
// a child's box with one load whatever kind of child it is, and a pair traversal tests a
// leaf against a node with it (leafBox(s)). Binary rather than wide: not measured against
// a 4-wide tree (see "Measured" below for what limits the queries).
//
// Build: linear BVH (Morton codes, Karras' radix-tree splits), chosen over binned SAH
// because its cost is a few linear passes and a sort (the target is 30 M triangles/s on
// 2 threads; binned SAH is O(n log n) with a large constant) and because the tree is a
// pure function of the sorted codes, hence identical for any thread count; cloth
// triangles are uniform in size, where Morton order loses little to SAH (not measured
// against a SAH build).
//   1. One parallel pass: validate indices, the triangles' centroids (sums of corners,
//      into a buffer) and their bounds (per block, combined in block order: min/max are
//      exact in any order).
//   2. Morton codes, 10 bits per axis, the centroid bounds scaled uniformly by their
//      longest side; key = code << 32 | triangle.
//   3. A stable LSD radix sort of the keys on the code, 3 passes of 10 bits, each a
//      parallel histogram per fixed block, a serial prefix sum in (digit, block) order
//      and a parallel scatter per block (stable, so the result is the unique sort by
//      (code, triangle), whatever the thread count).
//   4. Top-down splits of the sorted range at the highest bit in which the first and
//      last codes differ (a branch-free binary search for the first code with that bit;
//      the middle when all codes are equal). A node's position follows from its range
//      alone (the left subtree of [lo, hi] split at s has s - lo internal nodes), so
//      subtrees are built independently: ranges of more than kSubtreeLeaves leaves
//      serially, the rest in parallel, one subtree per task. Each level uses at least one
//      code bit or halves the range: depth <= 30 + log2(n).
//   5. The boxes, by a refit.
// Rebuilding a mesh of the same or smaller size allocates nothing (buffers are sized
// once and reused).
//
// Refit: per subtree of step 4 in parallel, the leaves' boxes then the nodes in reverse
// pre-order (children before parents), then the few nodes above the subtrees serially.
// Each box is a min/max, exact, so the result is bitwise the same for any thread count.
//
// Queries (const, safe to run concurrently; positions must be the ones of the last
// build or refit, or lie inside its boxes):
//   * closestTriangle(x, p, radius): the triangle closest to p within radius, the
//     closest point and the squared distance (Ericson 5.1.5, geometry.hpp); ties go to
//     the lowest triangle index. Serial (a query is small; run many in parallel).
//     Box pruning keeps a slack of a few ulps so the answer is the brute-force one.
//   * overlappingPairs(other) / intersectingPairs(other, x, xOther): all pairs (i of
//     this, j of other) whose leaf boxes overlap, or whose closed triangles intersect
//     (the exact test of geometry.hpp).
//   * selfPairs() / selfIntersectingPairs(x): the same within one BVH, pairs i < j,
//     skipping pairs that share a vertex index; selfOverlappingPairs() keeps those.
//   Pair queries expand pairs of nodes breadth first, serially and in a fixed order, into
//   a front of at least kFrontTasks tasks; the tasks run in parallel. Within a task the
//   pairs are expanded level by level; a leaf side is a pseudo-node (its box and an empty
//   one), so each pair is 2 x 2 box tests (SSE / AVX) and the children go to the next
//   level or, both leaves, to the task's candidates by index arithmetic, without
//   branches on the kinds of nodes. The candidates are then filtered (shared vertex,
//   exact test) in one loop. The tasks' results (each buffer on its own cache line) are
//   concatenated and radix-sorted by (i, j) on the significant bits of the indices. The
//   output is a set, so the result is the same for any thread count. Buffers live in a
//   BvhPairScratch and the output vector: once warmed up, a query allocates nothing.
//
// Measured (bench/bench_collide.cpp; 2-core EPYC VM, float, 1 thread unless said):
//   * sorting the 3.6k result pairs of the cloth/sphere benchmark: std::sort 120 us,
//     the radix sort 35 us (comparisons mispredict);
//   * the exact test on those 3.6k candidates: edge-by-edge line tests 107 ns per
//     intersecting pair and 53 ns per rejected one, Devillers-Guigue 40 and 24 ns;
//   * a 2 x 2 box test: scalar 13.5 ns, SSE 7.8 ns (micro-benchmark);
//   * a pair traversal costs about 16 ns per visited pair of nodes on this machine even
//     when the trees fit in L1/L2 (12.7k visits for the 32k-triangle cloth against the
//     20k-triangle sphere), neither a branch-free nor a breadth-first formulation changed
//     that much: visits are what to reduce next (a 4-wide tree, or leaves of 2-4
//     triangles);
//   * self queries of a cloth are dominated by the pairs of adjacent triangles (sharing a
//     vertex, about 6 per triangle), which overlap by construction and are tested and
//     dropped; normal-cone culling of flat regions would remove them.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include "collide/geometry.hpp"
#include "weft/core/parallel.hpp"
#include "weft/model/model.hpp"

namespace weft {

/// Axis-aligned box, closed: [lo, hi] per axis.
template <class S>
struct Aabb {
  S lo[3];
  S hi[3];

  bool overlaps(const Aabb& o) const {
    return lo[0] <= o.hi[0] && o.lo[0] <= hi[0] && lo[1] <= o.hi[1] && o.lo[1] <= hi[1] && lo[2] <= o.hi[2] &&
           o.lo[2] <= hi[2];
  }
  bool contains(const Aabb& o) const {
    return lo[0] <= o.lo[0] && o.hi[0] <= hi[0] && lo[1] <= o.lo[1] && o.hi[1] <= hi[1] && lo[2] <= o.lo[2] &&
           o.hi[2] <= hi[2];
  }
};

/// An internal node: the boxes of its two children and their references.
template <class S>
struct alignas(64) BvhNode {
  Aabb<S> box[2];
  Index child[2];  // >= 0: internal node index; < 0: leaf of slot ~child (= -1 - slot)
};

/// A pair of triangles: `first` of the BVH queried, `second` of the other one (self
/// queries: first < second).
struct TrianglePair {
  Index first = 0;
  Index second = 0;
  friend auto operator<=>(const TrianglePair&, const TrianglePair&) = default;
};

template <class S>
struct ClosestTriangle {
  Index triangle = -1;
  Vec3<S> point;          // the closest point on the triangle, m
  S squaredDistance = 0;  // |point - query|^2, m^2
};

/// Reusable work buffers of the parallel pair queries (keep one per querying thread).
/// Bytes a vector holds (its capacity), for memory reports.
template <class T>
std::size_t vectorBytes(const std::vector<T>& v) {
  return v.capacity() * sizeof(T);
}

class BvhPairScratch {
 public:
  /// Bytes its buffers hold (capacities): they grow with the largest query so far.
  std::size_t heldBytes() const;

 private:
  template <class>
  friend class TriangleBvh;
  /// One task's pairs, on a cache line of its own: tasks on different threads append to
  /// their vectors concurrently, and neighbouring vector headers would share a line.
  struct alignas(64) TaskPairs {
    std::vector<TrianglePair> pairs;  // [0, count): the task's reported pairs
    Index count = 0;                  // (vectors are only grown: their sizes are capacities)
  };
  /// One thread's expansion buffers, reused by every task it runs: the leaf pairs whose
  /// boxes overlap are filtered there, so a query that reports few of them (the exact
  /// intersection test) holds only the largest task's candidates per thread, not all.
  struct alignas(64) ThreadLevels {
    std::vector<TrianglePair> leaves;            // leaf pairs whose boxes overlap (slots)
    std::vector<std::array<Index, 2>> level[2];  // breadth-first levels of node pairs
  };
  std::vector<std::array<Index, 2>> front_, next_;  // tasks (pairs of node references)
  std::vector<TaskPairs> taskPairs_;
  std::vector<ThreadLevels> threadLevels_;      // one per thread slot of the executor
  std::vector<std::uint64_t> keys_, keysSwap_;  // the sort of the result (sortPairs)
  std::vector<Index> histogram_;
};

template <class S>
class TriangleBvh {
 public:
  static constexpr Index kBuildGrain = 4096;    // triangles per block of the linear build passes
  static constexpr Index kSortGrain = 8192;     // keys per block of the radix sort
  static constexpr Index kSubtreeLeaves = 512;  // subtrees at most this large are built and refit as one task
  static constexpr Index kFrontTasks = 64;      // pair queries: expand to at least this many tasks
  static constexpr Index kNoRoot = std::numeric_limits<Index>::min();  // root() of an empty BVH

  TriangleBvh() = default;

  /// Builds over positions x (one row per vertex) and `triangles` (corner indices in
  /// [0, x.rows())), boxes inflated by `margin` (m, finite, >= 0). std::invalid_argument
  /// names a bad index or margin.
  void build(const Vec3Array<S>& x, const Triangles& triangles, const Executor& exec, double margin = 0);
  /// Frees the buffers only build() uses (sort keys, Morton codes, centroids: about 32
  /// bytes a triangle), for a tree built once and then queried, such as the end-of-run
  /// intersection check; refits and queries do not need them, the next build() makes them
  /// again.
  void releaseBuildBuffers();
  /// Recomputes every box for new positions of the same vertices (same topology).
  void refit(const Vec3Array<S>& x, const Executor& exec);
  /// Boxes covering each triangle at x0 and at x1 (the start and end of a step), inflated by the margin.
  void refitSwept(const Vec3Array<S>& x0, const Vec3Array<S>& x1, const Executor& exec);
  /// Boxes covering each triangle's corners' boxes (one per vertex), inflated by the margin.
  void refitBoxes(const std::vector<Aabb<S>>& vertexBox, const Executor& exec);

  Index triangleCount() const { return static_cast<Index>(slotTriangle_.size()); }
  Index vertexCount() const { return vertexCount_; }
  S margin() const { return margin_; }
  bool empty() const { return slotTriangle_.empty(); }

  /// Root reference: 0 (node 0) for 2 or more triangles, ~0 (the leaf of slot 0) for one, kNoRoot if empty.
  Index root() const;
  const Aabb<S>& rootBox() const { return rootBox_; }
  /// The n - 1 internal nodes, depth-first pre-order.
  const std::vector<BvhNode<S>>& nodes() const { return nodes_; }
  const Aabb<S>& leafBox(Index slot) const { return boxes_[static_cast<size_t>(triangleCount() - 1 + slot)]; }
  Index slotTriangle(Index slot) const { return slotTriangle_[static_cast<size_t>(slot)]; }
  /// Longest root-to-leaf path, in edges.
  Index depth() const { return depth_; }
  Index subtreeCount() const { return static_cast<Index>(subtrees_.size()); }

  /// Calls leaf(slot) for every slot and node(q) for every internal node q, each once, a
  /// node after its children: the subtrees of the build as parallel tasks, then the nodes
  /// above them in one (the order of a refit). For 2 or more triangles.
  template <class Leaf, class Node>
  void bottomUp(const Executor& exec, const Leaf& leaf, const Node& node) const;

  /// Calls f(triangle) for every triangle whose leaf box (with the margin) overlaps `box`,
  /// each once, in an order fixed by the tree. Allocates nothing; f may stop nothing.
  template <class F>
  void forEachOverlapping(const Aabb<S>& box, F&& f) const;

  /// The triangle closest to `point` with squared distance <= radius^2 (radius >= 0, may
  /// be infinite), or none.
  std::optional<ClosestTriangle<S>> closestTriangle(const Vec3Array<S>& x, const Vec3<S>& point, S radius) const;

  /// Pairs (i of this, j of other) whose boxes overlap, sorted. Boxes carry their BVH's
  /// margin, so with margins m and m' this finds every pair closer than m + m' (and more):
  /// the candidates of a proximity or, after refitSwept, a continuous test.
  void overlappingPairs(const TriangleBvh& other, std::vector<TrianglePair>& out, BvhPairScratch& scratch,
                        const Executor& exec) const;
  /// Pairs (i of this at x, j of other at xOther) whose closed triangles intersect, sorted.
  void intersectingPairs(const TriangleBvh& other, const Vec3Array<S>& x, const Vec3Array<S>& xOther,
                         std::vector<TrianglePair>& out, BvhPairScratch& scratch, const Executor& exec) const;
  /// Pairs i < j of this BVH sharing no vertex whose boxes overlap, sorted.
  void selfPairs(std::vector<TrianglePair>& out, BvhPairScratch& scratch, const Executor& exec) const;
  /// Pairs i < j of this BVH whose boxes overlap, those sharing a vertex included, sorted
  /// (the candidates of the self-collision pass, which also tests a vertex against the
  /// triangles next to its own). `skipWithin`, when not empty, holds one flag per internal
  /// node (nodes() order): a set flag drops every pair with both triangles in that node's
  /// subtree (the self-collision pass's flat regions), without visiting them.
  /// `limit` bounds the search: when more than `limit` pairs overlap, or the traversal meets
  /// more than `limit` pairs of internal nodes whose boxes overlap, it stops early and returns
  /// false (`out` is then empty). Both counts are properties of the tree, not of the
  /// scheduling, so the answer is the same on any number of threads.
  bool selfOverlappingPairs(std::vector<TrianglePair>& out, BvhPairScratch& scratch, const Executor& exec,
                            std::span<const std::uint8_t> skipWithin = {},
                            std::int64_t limit = std::numeric_limits<std::int64_t>::max()) const;
  /// Pairs i < j sharing no vertex whose closed triangles intersect at x, sorted.
  void selfIntersectingPairs(const Vec3Array<S>& x, std::vector<TrianglePair>& out, BvhPairScratch& scratch,
                             const Executor& exec) const;

 private:
  struct Subtree {
    Index node;       // root of the subtree (an internal node)
    Index firstSlot;  // its leaves are slots [firstSlot, lastSlot]
    Index lastSlot;
    Index depth;  // depth of its root; after the build, of its deepest leaf
  };

  void checkPositions(const char* what, const Vec3Array<S>& x) const;
  template <class LeafBox>
  void refitWith(const LeafBox& leafBox, const Executor& exec);
  /// refitWith a leaf box over its three corners: lo(vertex, axis) and hi(vertex, axis)
  /// bound each corner, and the margin is added.
  template <class Lo, class Hi>
  void refitCorners(const Lo& lo, const Hi& hi, const Executor& exec);
  void sortKeys(const Executor& exec);
  void buildHierarchy(const Executor& exec);
  /// Returns false when it stopped at `limit` (see selfOverlappingPairs).
  template <bool kSelf, bool kExact, bool kSkipShared = kSelf>
  bool pairQuery(const TriangleBvh& other, const Vec3Array<S>* x, const Vec3Array<S>* xOther,
                 std::vector<TrianglePair>& out, BvhPairScratch& scratch, const Executor& exec,
                 std::span<const std::uint8_t> skipWithin = {},
                 std::int64_t limit = std::numeric_limits<std::int64_t>::max()) const;

  Index vertexCount_ = 0;
  S margin_ = 0;
  Index depth_ = 0;
  Aabb<S> rootBox_{};
  std::vector<BvhNode<S>> nodes_;              // (n - 1)
  std::vector<Aabb<S>> boxes_;                 // (2n - 1) node q's own box at q, slot s's at n - 1 + s
  std::vector<Index> slotTriangle_;            // (n) per slot
  std::vector<std::array<Index, 3>> corners_;  // (n) per slot
  std::vector<Subtree> subtrees_;              // parallel tasks of build and refit, pre-order
  std::vector<Index> topNodes_;                // internal nodes above the subtrees, pre-order
  // Build scratch, kept for rebuilds.
  std::vector<std::uint64_t> keys_, keysSwap_;  // (n) code << 32 | triangle
  std::vector<std::uint32_t> codes_;            // (n) sorted codes
  std::vector<S> centroids_;                    // (3n) sums of corners, x then y then z
  std::vector<Index> histogram_;                // (sort blocks x 1024)
  std::vector<Aabb<S>> blockBounds_;            // per build block
  std::vector<Index> blockBad_;                 // per build block: first bad triangle or -1
};

extern template class TriangleBvh<float>;
extern template class TriangleBvh<double>;

template <class S>
template <class Leaf, class Node>
void TriangleBvh<S>::bottomUp(const Executor& exec, const Leaf& leaf, const Node& node) const {
  exec.parallelFor(static_cast<Index>(subtrees_.size()), 1, [&](Index b, Index e) {
    for (Index k = b; k < e; ++k) {
      const Subtree& tree = subtrees_[static_cast<size_t>(k)];
      for (Index s = tree.firstSlot; s <= tree.lastSlot; ++s) leaf(s);
      // (A subtree's nodes follow its root in pre-order, one fewer than its leaves.)
      for (Index q = tree.node + (tree.lastSlot - tree.firstSlot) - 1; q >= tree.node; --q) node(q);
    }
  });
  for (auto it = topNodes_.rbegin(); it != topNodes_.rend(); ++it) {
    for (const Index c : nodes_[static_cast<size_t>(*it)].child)
      if (c < 0) leaf(~c);
    node(*it);
  }
}

template <class S>
template <class F>
void TriangleBvh<S>::forEachOverlapping(const Aabb<S>& box, F&& f) const {
  if (empty() || !rootBox_.overlaps(box)) return;
  if (triangleCount() == 1) {
    f(slotTriangle_[0]);
    return;
  }
  // A tree has depth <= 61 (build step 4): a depth-first walk holds at most depth + 2 nodes.
  Index stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const BvhNode<S>& node = nodes_[static_cast<size_t>(stack[--top])];
    for (int k = 0; k < 2; ++k) {
      if (!node.box[k].overlaps(box)) continue;
      const Index c = node.child[k];
      if (c < 0)
        f(slotTriangle_[static_cast<size_t>(~c)]);
      else
        stack[top++] = c;
    }
  }
}

}  // namespace weft
