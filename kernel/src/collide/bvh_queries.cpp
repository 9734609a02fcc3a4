// TriangleBvh's queries: the closest triangle to a point within a radius, and the
// overlapping (or exactly intersecting) triangle pairs between two BVHs or within one
// (see weft/collide/bvh.hpp); build and refit are in bvh.cpp.
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "bvh_internal.hpp"
#include "closest_point.hpp"
#include "collide/bvh.hpp"
#include "collide/geometry.hpp"

namespace weft {

std::size_t BvhPairScratch::heldBytes() const {
  std::size_t total = vectorBytes(front_) + vectorBytes(next_) + vectorBytes(taskPairs_) + vectorBytes(threadLevels_) +
                      vectorBytes(keys_) + vectorBytes(keysSwap_) + vectorBytes(histogram_);
  for (const TaskPairs& t : taskPairs_) total += vectorBytes(t.pairs);
  for (const ThreadLevels& t : threadLevels_)
    total += vectorBytes(t.leaves) + vectorBytes(t.level[0]) + vectorBytes(t.level[1]);
  return total;
}

using namespace bvh_detail;

template <class S>
std::optional<ClosestTriangle<S>> TriangleBvh<S>::closestTriangle(const Vec3Array<S>& x, const Vec3<S>& p,
                                                                  S radius) const {
  if (!(radius >= S(0))) {
    throw std::invalid_argument("TriangleBvh::closestTriangle: radius must be >= 0, got " +
                                detail::number(static_cast<double>(radius)));
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
template <bool kSelf, bool kExact, bool kSkipShared>
bool TriangleBvh<S>::pairQuery(const TriangleBvh& other, const Vec3Array<S>* x, const Vec3Array<S>* xOther,
                               std::vector<TrianglePair>& out, BvhPairScratch& scratch, const Executor& exec,
                               std::span<const std::uint8_t> skipWithin, std::int64_t limit) const {
  using Task = std::array<Index, 2>;  // node references; in self queries {a, a} means "all pairs within a"
  out.clear();
  const TriangleBvh& A = *this;
  const TriangleBvh& B = other;
  if (A.empty() || B.empty()) return true;
  if (kSelf && A.triangleCount() < 2) return true;
  if (!kSelf && !A.rootBox_.overlaps(B.rootBox_)) return true;
  if (!skipWithin.empty() && skipWithin.size() != A.nodes_.size())
    throw std::invalid_argument("TriangleBvh: skipWithin holds " + std::to_string(skipWithin.size()) + " flags for " +
                                std::to_string(A.nodes_.size()) + " internal nodes");
  // Whether the pairs within internal node q are wanted (self queries).
  const std::uint8_t* skip = skipWithin.empty() ? nullptr : skipWithin.data();
  const auto within = [skip](Index q) { return q >= 0 && (skip == nullptr || skip[q] == 0); };
  if (kSelf && !within(0)) return true;

  // Pushes the subtasks of a task that is not a pair of leaves: push(task, keep).
  const auto expand = [&](const Task& task, auto&& push) {
    const Index a = task[0], b = task[1];
    if (kSelf && a == b) {
      const BvhNode<S>& node = A.nodes_[static_cast<size_t>(a)];
      push(Task{node.child[0], node.child[0]}, within(node.child[0]));
      push(Task{node.child[1], node.child[1]}, within(node.child[1]));
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
    if constexpr (kSelf && kSkipShared) {
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
  // The limit: every task adds the overlapping leaf pairs and node pairs of each level it
  // expands to shared totals. A total is only ever a sum of some tasks' exact counts, so it
  // passes the limit only if the whole query's count does: stopping is decided by the tree,
  // whatever the order the tasks run in.
  const bool limited = limit < std::numeric_limits<std::int64_t>::max();
  std::atomic<std::int64_t> leafTotal{0}, nodeTotal{0};
  std::atomic<bool> stopped{false};
  const size_t slots = static_cast<size_t>(std::max(1, exec.threadCount()));
  if (scratch.threadLevels_.size() < slots) scratch.threadLevels_.resize(slots);
  exec.parallelFor(tasks, 1, [&](Index begin, Index end) {
    const BvhNode<S>* nodesA = A.nodes_.data();
    const BvhNode<S>* nodesB = B.nodes_.data();
    const Aabb<S>* leavesA = &A.leafBox(0);
    const Aabb<S>* leavesB = &B.leafBox(0);
    // The thread's slot in the executor's arena (0 on the serial path, which may run
    // outside it): no two threads of one pass share a slot.
    const int slot = tbb::this_task_arena::current_thread_index();
    BvhPairScratch::ThreadLevels& mine =
        scratch.threadLevels_[slot >= 0 && static_cast<size_t>(slot) < slots ? static_cast<size_t>(slot) : 0];
    for (Index k = begin; k < end; ++k) {
      BvhPairScratch::TaskPairs& work = scratch.taskPairs_[static_cast<size_t>(k)];
      work.count = 0;
      if (limited && stopped.load(std::memory_order_relaxed)) continue;
      std::vector<Task>* current = &mine.level[0];
      std::vector<Task>* following = &mine.level[1];
      if (current->empty()) current->resize(1);
      if (mine.leaves.size() < 4) mine.leaves.resize(4);
      Index found = 0, count = 0;
      const Task start = front[static_cast<size_t>(k)];
      if ((start[0] & start[1]) < 0) {
        mine.leaves[static_cast<size_t>(found++)] = {~start[0], ~start[1]};
      } else {
        (*current)[static_cast<size_t>(count++)] = start;
      }
      BvhNode<S> pseudoA{}, pseudoB{};
      pseudoA.box[1] = pseudoB.box[1] = emptyBox<S>();
      if (limited && leafTotal.fetch_add(found, std::memory_order_relaxed) + found > limit)
        stopped.store(true, std::memory_order_relaxed);
      while (count > 0) {
        if (limited && stopped.load(std::memory_order_relaxed)) break;
        const size_t bound = 4 * static_cast<size_t>(count);  // a pair has at most 4 subtasks
        if (following->size() < bound) following->resize(bound);
        if (mine.leaves.size() < static_cast<size_t>(found) + bound)
          mine.leaves.resize(static_cast<size_t>(found) + bound);
        const Task* in = current->data();
        Task* nextLevel = following->data();
        TrianglePair* leaves = mine.leaves.data() + found;
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
        if (limited && (leafTotal.fetch_add(f, std::memory_order_relaxed) + f > limit ||
                        nodeTotal.fetch_add(n, std::memory_order_relaxed) + n > limit))
          stopped.store(true, std::memory_order_relaxed);
      }
      if (limited && stopped.load(std::memory_order_relaxed)) continue;
      // The filter and the slot -> triangle mapping, in place, then the task's own copy.
      Index kept = 0;
      for (Index i = 0; i < found; ++i) {
        const TrianglePair pair = mine.leaves[static_cast<size_t>(i)];
        if (!keep(pair.first, pair.second)) continue;
        Index ta = A.slotTriangle_[static_cast<size_t>(pair.first)];
        Index tb = B.slotTriangle_[static_cast<size_t>(pair.second)];
        if (kSelf && ta > tb) std::swap(ta, tb);
        mine.leaves[static_cast<size_t>(kept++)] = {ta, tb};
      }
      if (work.pairs.size() < static_cast<size_t>(kept)) work.pairs.resize(static_cast<size_t>(kept));
      std::copy(mine.leaves.begin(), mine.leaves.begin() + kept, work.pairs.begin());
      work.count = kept;
    }
  });
  // Which slot ran which task depends on the scheduler: every slot is grown to the largest
  // any needed, so that once a query has been warmed up no slot meets a task too large for
  // it (the query then allocates nothing, whatever the scheduling).
  size_t leavesSize = 0, levelSize = 0;
  for (const BvhPairScratch::ThreadLevels& t : scratch.threadLevels_) {
    leavesSize = std::max(leavesSize, t.leaves.size());
    levelSize = std::max({levelSize, t.level[0].size(), t.level[1].size()});
  }
  for (BvhPairScratch::ThreadLevels& t : scratch.threadLevels_) {
    if (t.leaves.size() < leavesSize) t.leaves.resize(leavesSize);
    for (auto& level : t.level)
      if (level.size() < levelSize) level.resize(levelSize);
  }
  if (limited && stopped.load(std::memory_order_relaxed)) return false;
  size_t total = 0;
  for (Index k = 0; k < tasks; ++k) total += static_cast<size_t>(scratch.taskPairs_[static_cast<size_t>(k)].count);
  out.reserve(total);
  for (Index k = 0; k < tasks; ++k) {
    const BvhPairScratch::TaskPairs& work = scratch.taskPairs_[static_cast<size_t>(k)];
    out.insert(out.end(), work.pairs.begin(), work.pairs.begin() + work.count);
  }
  sortPairs(out, scratch.keys_, scratch.keysSwap_, scratch.histogram_);
  return true;
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
bool TriangleBvh<S>::selfOverlappingPairs(std::vector<TrianglePair>& out, BvhPairScratch& scratch, const Executor& exec,
                                          std::span<const std::uint8_t> skipWithin, std::int64_t limit) const {
  if (limit < 0)
    throw std::invalid_argument("TriangleBvh::selfOverlappingPairs: limit must be >= 0, got " + std::to_string(limit));
  return pairQuery<true, false, false>(*this, nullptr, nullptr, out, scratch, exec, skipWithin, limit);
}

template <class S>
void TriangleBvh<S>::selfIntersectingPairs(const Vec3Array<S>& x, std::vector<TrianglePair>& out,
                                           BvhPairScratch& scratch, const Executor& exec) const {
  checkPositions("selfIntersectingPairs", x);
  pairQuery<true, true>(*this, &x, &x, out, scratch, exec);
}

#define WEFT_INSTANTIATE_QUERIES(S)                                                                                    \
  template std::optional<ClosestTriangle<S>> TriangleBvh<S>::closestTriangle(const Vec3Array<S>&, const Vec3<S>&, S)   \
      const;                                                                                                           \
  template void TriangleBvh<S>::overlappingPairs(const TriangleBvh&, std::vector<TrianglePair>&, BvhPairScratch&,      \
                                                 const Executor&) const;                                               \
  template void TriangleBvh<S>::intersectingPairs(const TriangleBvh&, const Vec3Array<S>&, const Vec3Array<S>&,        \
                                                  std::vector<TrianglePair>&, BvhPairScratch&, const Executor&) const; \
  template void TriangleBvh<S>::selfPairs(std::vector<TrianglePair>&, BvhPairScratch&, const Executor&) const;         \
  template bool TriangleBvh<S>::selfOverlappingPairs(std::vector<TrianglePair>&, BvhPairScratch&, const Executor&,     \
                                                     std::span<const std::uint8_t>, std::int64_t) const;               \
  template void TriangleBvh<S>::selfIntersectingPairs(const Vec3Array<S>&, std::vector<TrianglePair>&,                 \
                                                      BvhPairScratch&, const Executor&) const;
WEFT_INSTANTIATE_QUERIES(float)
WEFT_INSTANTIATE_QUERIES(double)
#undef WEFT_INSTANTIATE_QUERIES

}  // namespace weft
