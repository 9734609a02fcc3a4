// weft/core/parallel.hpp — the one parallel loop of the kernel.
//
// Design note
// -----------
// Every parallel pass in weft goes through Executor::parallelFor. Determinism for any
// thread count follows from three rules, which every caller keeps:
//   1. Block boundaries depend only on the item count and the grain size, never on the
//      thread count: block k is [k * grain, min(count, (k + 1) * grain)).
//   2. Blocks write disjoint memory; there are no floating-point atomics.
//   3. A reduction writes one partial result per block and the caller combines the
//      partials in block order (parallelForBlocks below hands each block its index).
// Under these rules the result of a pass is bitwise the same whether the blocks run on
// one thread or many, in any order. Work runs inside a tbb::task_arena: either one the
// Executor owns (thread count chosen by the caller) or one supplied by an embedding
// program, which weft then honours and never outlives.
#pragma once

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/partitioner.h>
#include <oneapi/tbb/task_arena.h>

#include <memory>

#include "weft/core/types.hpp"

namespace weft {

class Executor {
 public:
  /// Owns an arena of `threadCount` threads (0 = all hardware threads), at most as many as
  /// TBB allows in all (the machine's threads): threadCount() says how many.
  explicit Executor(int threadCount = 0);
  /// Runs on an arena owned by the embedding program; it must outlive this Executor.
  explicit Executor(tbb::task_arena& external);

  Executor(const Executor&) = delete;
  Executor& operator=(const Executor&) = delete;

  /// Number of threads work may be spread over (the arena's concurrency).
  int threadCount() const { return threadCount_; }

  /// Runs f inside the arena. With a single thread it is called directly: the calling
  /// thread would be the arena's only worker anyway, and this skips the arena entry.
  template <class F>
  void run(F&& f) const {
    if (threadCount_ == 1) {
      f();
    } else {
      arena_->execute(std::forward<F>(f));
    }
  }

  /// Number of blocks a pass over `count` items with block size `grain` has.
  static Index blockCount(Index count, Index grain) {
    if (grain < 1) grain = 1;
    return count <= 0 ? 0 : (count + grain - 1) / grain;
  }

  /// Calls body(begin, end) for each block [begin, end) of [0, count); blocks of
  /// `grain` items (the last may be shorter). Blocks may run concurrently.
  template <class Body>
  void parallelFor(Index count, Index grain, Body&& body) const {
    if (grain < 1) grain = 1;
    const Index blocks = blockCount(count, grain);
    if (blocks == 0) return;
    if (threadCount_ == 1 || blocks == 1) {
      for (Index k = 0; k < blocks; ++k) {
        const Index b = k * grain;
        body(b, b + grain < count ? b + grain : count);
      }
      return;
    }
    arena_->execute([&] {
      tbb::parallel_for(
          tbb::blocked_range<Index>(0, blocks, 1),
          [&](const tbb::blocked_range<Index>& r) {
            for (Index k = r.begin(); k != r.end(); ++k) {
              const Index b = k * grain;
              body(b, b + grain < count ? b + grain : count);
            }
          },
          tbb::simple_partitioner());
    });
  }

  /// Calls body(block, begin, end) for each block, for reductions: the body writes a
  /// partial result into slot `block`, and the caller combines slots in order.
  template <class Body>
  void parallelForBlocks(Index count, Index grain, Body&& body) const {
    if (grain < 1) grain = 1;
    parallelFor(Executor::blockCount(count, grain), 1, [&](Index kb, Index ke) {
      for (Index k = kb; k < ke; ++k) {
        const Index b = k * grain;
        body(k, b, b + grain < count ? b + grain : count);
      }
    });
  }

 private:
  std::unique_ptr<tbb::task_arena> owned_;
  tbb::task_arena* arena_ = nullptr;
  int threadCount_ = 1;
};

}  // namespace weft
