// The exact self-intersection check, countSelfIntersections (weft/collide/self_collision.hpp):
// how many pairs of a model's triangles that share no particle intersect at x.
//
// It runs once at the end of every `weft run` (and after every step of the hard-scene
// tests), never inside a step, so its tree is made for one query and for little memory
// rather than for refits:
//   * the triangles are sorted by the Morton code of their centroids and cut into leaves of
//     kLeafTriangles consecutive triangles;
//   * the tree over the leaves is implicit: a complete binary tree in heap order (node i has
//     children 2i + 1 and 2i + 2, the leaves on the last level, the ones past the last real
//     leaf empty), so a node is its box alone;
//   * the pair walk counts as it goes: no list of candidate or intersecting pairs is kept.
// At 256² (130k triangles) that is 1.0 MB of keys and 0.8 MB of boxes (float), where the
// refittable TriangleBvh with its pair query held about 22 MB; the walk is about 10 % slower
// than that BVH's (BM_IntersectionCheck). The walk's tasks each count
// their own pairs and the counts are summed: an integer, the same for any thread count and
// any schedule. A pair is counted when its triangles share no particle, their boxes overlap
// and geometry.hpp's exact test says they share a point, the same definition the BVH's
// selfIntersectingPairs uses.
#include <oneapi/tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "collide/bvh_internal.hpp"
#include "collide/geometry.hpp"
#include "weft/collide/self_collision.hpp"

namespace weft {

namespace {

using bvh_detail::emptyBox;
using bvh_detail::merged;
using bvh_detail::overlap;

constexpr Index kLeafTriangles = 8;
constexpr Index kGrain = 4096;

template <class S>
class IntersectionCheck {
 public:
  IntersectionCheck(const Model<S>& model, const Vec3Array<S>& x, const Executor& exec)
      : n_(model.triangleCount()),
        nv_(static_cast<Index>(x.rows())),
        ia_(model.triangles().a.data()),
        ib_(model.triangles().b.data()),
        ic_(model.triangles().c.data()),
        xs_{x.data(), x.data() + nv_, x.data() + 2 * nv_},
        exec_(exec) {}

  std::int64_t count() {
    if (n_ < 2) return 0;
    sortTriangles();
    buildBoxes();
    return walk();
  }

 private:
  Aabb<S> triangleBox(Index t) const {
    const Index c[3] = {ia_[t], ib_[t], ic_[t]};
    Aabb<S> box;
    for (int k = 0; k < 3; ++k) {
      const S v0 = xs_[k][c[0]], v1 = xs_[k][c[1]], v2 = xs_[k][c[2]];
      box.lo[k] = std::min(std::min(v0, v1), v2);
      box.hi[k] = std::max(std::max(v0, v1), v2);
    }
    return box;
  }

  // Triangles in Morton order of their centroids (sums of corners: the scale does not
  // matter): key = code << 32 | triangle, so the order is a function of the input alone.
  void sortTriangles() {
    const Index blocks = Executor::blockCount(n_, kGrain);
    std::vector<Aabb<S>> blockBounds(static_cast<size_t>(blocks));
    const auto centroid = [&](Index t, int k) { return xs_[k][ia_[t]] + xs_[k][ib_[t]] + xs_[k][ic_[t]]; };
    exec_.parallelForBlocks(n_, kGrain, [&](Index block, Index b, Index e) {
      Aabb<S> box = emptyBox<S>();
      for (Index t = b; t < e; ++t)
        for (int k = 0; k < 3; ++k) {
          const S c = centroid(t, k);
          if (!std::isfinite(c)) continue;  // placed anywhere: its box decides what it meets
          box.lo[k] = std::min(box.lo[k], c);
          box.hi[k] = std::max(box.hi[k], c);
        }
      blockBounds[static_cast<size_t>(block)] = box;
    });
    Aabb<S> bounds = emptyBox<S>();
    for (const Aabb<S>& b : blockBounds) bounds = merged(bounds, b);
    S extent = 0;
    for (int k = 0; k < 3; ++k) extent = std::max(extent, bounds.hi[k] - bounds.lo[k]);
    const S scale = extent > S(0) && std::isfinite(extent) ? S(bvh_detail::kRadix) / extent : S(0);
    for (int k = 0; k < 3; ++k)
      if (!(bounds.lo[k] <= bounds.hi[k])) bounds.lo[k] = 0;  // no finite centroid at all
    keys_.resize(static_cast<size_t>(n_));
    exec_.parallelFor(n_, kGrain, [&](Index b, Index e) {
      for (Index t = b; t < e; ++t) {
        std::uint32_t code = 0;
        for (int k = 0; k < 3; ++k)
          code |= bvh_detail::spreadBits(bvh_detail::quantise(centroid(t, k), bounds.lo[k], scale)) << (2 - k);
        keys_[static_cast<size_t>(t)] = (std::uint64_t(code) << 32) | std::uint32_t(t);
      }
    });
    // Keys are distinct, so the order is the same however they are sorted. (One thread:
    // std::sort on the calling thread; parallel_sort outside the arena would use all.)
    if (exec_.threadCount() == 1)
      std::sort(keys_.begin(), keys_.end());
    else
      exec_.run([&] { tbb::parallel_sort(keys_.begin(), keys_.end()); });
    leaves_ = Executor::blockCount(n_, kLeafTriangles);
    width_ = static_cast<Index>(std::bit_ceil(static_cast<std::uint64_t>(leaves_)));
  }

  Index triangle(Index slot) const { return static_cast<Index>(keys_[static_cast<size_t>(slot)] & 0xFFFFFFFFu); }
  bool isLeaf(Index node) const { return node >= width_ - 1; }
  // A leaf's triangles: slots [first, last) of the sorted order.
  Index firstSlot(Index node) const { return (node - (width_ - 1)) * kLeafTriangles; }
  Index lastSlot(Index node) const { return std::min(n_, firstSlot(node) + kLeafTriangles); }

  // Boxes of the leaves, then of each level up to the root, each level in parallel.
  void buildBoxes() {
    boxes_.assign(static_cast<size_t>(2 * width_ - 1), emptyBox<S>());
    exec_.parallelFor(leaves_, kGrain / kLeafTriangles, [&](Index b, Index e) {
      for (Index l = b; l < e; ++l) {
        const Index node = width_ - 1 + l;
        Aabb<S> box = emptyBox<S>();
        for (Index s = firstSlot(node); s < lastSlot(node); ++s) box = merged(box, triangleBox(triangle(s)));
        boxes_[static_cast<size_t>(node)] = box;
      }
    });
    for (Index levelFirst = width_ / 2 - 1, levelSize = width_ / 2; levelSize >= 1;
         levelSize /= 2, levelFirst = (levelFirst - 1) / 2) {
      exec_.parallelFor(levelSize, kGrain, [&](Index b, Index e) {
        for (Index i = levelFirst + b; i < levelFirst + e; ++i)
          boxes_[static_cast<size_t>(i)] =
              merged(boxes_[static_cast<size_t>(2 * i + 1)], boxes_[static_cast<size_t>(2 * i + 2)]);
      });
      if (levelFirst == 0) break;
    }
  }

  // Pairs of triangles from leaves a and b (a == b: the pairs within the leaf).
  std::int64_t leafPairs(Index a, Index b) const {
    std::array<Aabb<S>, kLeafTriangles> boxA, boxB;
    std::array<std::array<Index, 3>, kLeafTriangles> cornersA, cornersB;
    const Index a0 = firstSlot(a), na = lastSlot(a) - a0;
    const Index b0 = firstSlot(b), nb = lastSlot(b) - b0;
    for (Index i = 0; i < na; ++i) {
      const Index t = triangle(a0 + i);
      boxA[static_cast<size_t>(i)] = triangleBox(t);
      cornersA[static_cast<size_t>(i)] = {ia_[t], ib_[t], ic_[t]};
    }
    for (Index j = 0; j < nb; ++j) {
      const Index t = triangle(b0 + j);
      boxB[static_cast<size_t>(j)] = triangleBox(t);
      cornersB[static_cast<size_t>(j)] = {ia_[t], ib_[t], ic_[t]};
    }
    std::int64_t found = 0;
    for (Index i = 0; i < na; ++i) {
      const std::array<Index, 3>& ca = cornersA[static_cast<size_t>(i)];
      for (Index j = a == b ? i + 1 : 0; j < nb; ++j) {
        if (!overlap(boxA[static_cast<size_t>(i)], boxB[static_cast<size_t>(j)])) continue;
        const std::array<Index, 3>& cb = cornersB[static_cast<size_t>(j)];
        if ((ca[0] == cb[0]) | (ca[0] == cb[1]) | (ca[0] == cb[2]) | (ca[1] == cb[0]) | (ca[1] == cb[1]) |
            (ca[1] == cb[2]) | (ca[2] == cb[0]) | (ca[2] == cb[1]) | (ca[2] == cb[2]))
          continue;  // adjacent: they share a particle
        Vec3<double> p[6];
        for (int k = 0; k < 3; ++k) {
          p[k] = Vec3<double>(xs_[0][ca[k]], xs_[1][ca[k]], xs_[2][ca[k]]);
          p[3 + k] = Vec3<double>(xs_[0][cb[k]], xs_[1][cb[k]], xs_[2][cb[k]]);
        }
        found += trianglesIntersect(p[0], p[1], p[2], p[3], p[4], p[5]) ? 1 : 0;
      }
    }
    return found;
  }

  // A task is a pair of nodes (a, b), a <= b; (a, a) stands for the pairs within a's subtree.
  using Task = std::array<Index, 2>;

  // Children of a task whose nodes' boxes overlap (for a != b), into `out`; returns how many.
  // A self task (a, a) of an inner node gives (l, l), (r, r) and (l, r); a pair of inner
  // nodes all four child pairs, a leaf against an inner node the inner node's two children.
  int expand(const Task& task, Task* out) const {
    const Index a = task[0], b = task[1];
    int count = 0;
    const auto push = [&](Index p, Index q) {
      const bool keep = p == q ? !(boxes_[static_cast<size_t>(p)].lo[0] > boxes_[static_cast<size_t>(p)].hi[0])
                               : overlap(boxes_[static_cast<size_t>(p)], boxes_[static_cast<size_t>(q)]);
      out[count] = {p, q};
      count += keep ? 1 : 0;
    };
    if (a == b) {
      push(2 * a + 1, 2 * a + 1);
      push(2 * a + 2, 2 * a + 2);
      push(2 * a + 1, 2 * a + 2);
    } else if (!isLeaf(a) && !isLeaf(b)) {
      for (Index p = 2 * a + 1; p <= 2 * a + 2; ++p)
        for (Index q = 2 * b + 1; q <= 2 * b + 2; ++q) push(p, q);
    } else if (isLeaf(a)) {
      push(a, 2 * b + 1);
      push(a, 2 * b + 2);
    } else {
      push(2 * a + 1, b);
      push(2 * a + 2, b);
    }
    return count;
  }

  std::int64_t walk() const {
    // The front: tasks expanded breadth first (a fixed order) until there are enough for the
    // threads, then each task walks its subtree depth first.
    std::vector<Task> front{{0, 0}}, next;
    const size_t enough = 64 * static_cast<size_t>(std::max(1, exec_.threadCount()));
    while (front.size() < enough) {
      next.clear();
      bool expanded = false;
      for (const Task& task : front) {
        if (isLeaf(task[0]) && isLeaf(task[1])) {
          next.push_back(task);
          continue;
        }
        Task children[4];
        const int k = expand(task, children);
        next.insert(next.end(), children, children + k);
        expanded = true;
      }
      front.swap(next);
      if (!expanded) break;
    }
    std::vector<std::int64_t> counts(front.size(), 0);
    exec_.parallelFor(static_cast<Index>(front.size()), 1, [&](Index begin, Index end) {
      // A tree has at most 28 levels below the root (2^31 / kLeafTriangles leaves). Each
      // expansion takes one task and leaves at most 4, and takes one node or both a level
      // down: at most 2 x 28 expansions deep, so far fewer than 256 tasks pending.
      std::array<Task, 256> stack;
      for (Index k = begin; k < end; ++k) {
        std::int64_t found = 0;
        int top = 0;
        stack[static_cast<size_t>(top++)] = front[static_cast<size_t>(k)];
        while (top > 0) {
          const Task task = stack[static_cast<size_t>(--top)];
          if (isLeaf(task[0]) && isLeaf(task[1])) {
            found += leafPairs(task[0], task[1]);
            continue;
          }
          top += expand(task, &stack[static_cast<size_t>(top)]);
        }
        counts[static_cast<size_t>(k)] = found;
      }
    });
    std::int64_t total = 0;
    for (const std::int64_t c : counts) total += c;
    return total;
  }

  const Index n_, nv_;
  const Index *ia_, *ib_, *ic_;
  const S* xs_[3];
  const Executor& exec_;
  std::vector<std::uint64_t> keys_;  // (code << 32 | triangle), sorted
  std::vector<Aabb<S>> boxes_;       // the implicit tree, heap order
  Index leaves_ = 0, width_ = 0;     // leaves, and the last level's width (a power of two)
};

}  // namespace

template <class S>
std::int64_t countSelfIntersections(const Model<S>& model, const Vec3Array<S>& x, const Executor& exec) {
  if (x.rows() != model.particleCount() || x.cols() != 3)
    throw std::invalid_argument("countSelfIntersections: x must be " + std::to_string(model.particleCount()) +
                                " x 3 (the model's particles), got " + std::to_string(x.rows()) + " x " +
                                std::to_string(x.cols()));
  return IntersectionCheck<S>(model, x, exec).count();
}

template std::int64_t countSelfIntersections(const Model<float>&, const Vec3Array<float>&, const Executor&);
template std::int64_t countSelfIntersections(const Model<double>&, const Vec3Array<double>&, const Executor&);

}  // namespace weft
