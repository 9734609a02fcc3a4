// tests/test_core.cpp — Executor (the one parallel loop) and stateHash.
#include <gtest/gtest.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "support/test_support.hpp"
#include "weft/core/parallel.hpp"
#include "weft/core/state.hpp"

namespace weft::test {
namespace {

using Block = std::pair<Index, Index>;

struct LoopCase {
  Index count;
  Index grain;
};

// Counts that are multiples of the grain, one more, one less, smaller than one block,
// zero, and several blocks.
constexpr LoopCase kLoopCases[] = {{0, 1},       {1, 1},        {1, 64},      {7, 3},    {64, 64},
                                   {65, 64},     {63, 64},      {100, 7},     {1000, 1}, {4096, 4096},
                                   {4097, 4096}, {10000, 1024}, {12345, 4096}};

/// Every block [b, e) that parallelFor hands out, sorted, and checks each index is seen once.
std::vector<Block> runAndCollect(const Executor& exec, Index count, Index grain) {
  std::vector<std::atomic<int>> seen(static_cast<size_t>(count));
  for (auto& s : seen) s.store(0);
  std::mutex mutex;
  std::vector<Block> blocks;
  exec.parallelFor(count, grain, [&](Index b, Index e) {
    for (Index i = b; i < e; ++i) seen[static_cast<size_t>(i)].fetch_add(1, std::memory_order_relaxed);
    std::lock_guard<std::mutex> lock(mutex);
    blocks.emplace_back(b, e);
  });
  for (Index i = 0; i < count; ++i)
    EXPECT_EQ(seen[static_cast<size_t>(i)].load(), 1) << "index " << i << " of count " << count << ", grain " << grain;
  std::sort(blocks.begin(), blocks.end());
  return blocks;
}

/// The documented block boundaries: block k is [k grain, min(count, (k + 1) grain)).
std::vector<Block> expectedBlocks(Index count, Index grain) {
  std::vector<Block> blocks;
  for (Index b = 0; b < count; b += grain) blocks.emplace_back(b, std::min(count, b + grain));
  return blocks;
}

class ExecutorThreads : public ::testing::TestWithParam<int> {};

TEST_P(ExecutorThreads, ParallelForCoversEveryIndexExactlyOnce) {
  const Executor exec(GetParam());
  EXPECT_EQ(exec.threadCount(), GetParam());
  for (const LoopCase& c : kLoopCases) {
    SCOPED_TRACE(::testing::Message() << "count " << c.count << ", grain " << c.grain);
    const std::vector<Block> blocks = runAndCollect(exec, c.count, c.grain);
    EXPECT_EQ(static_cast<Index>(blocks.size()), Executor::blockCount(c.count, c.grain));
  }
}

TEST_P(ExecutorThreads, BlockBoundariesDependOnlyOnCountAndGrain) {
  const Executor exec(GetParam());
  for (const LoopCase& c : kLoopCases) {
    SCOPED_TRACE(::testing::Message() << "count " << c.count << ", grain " << c.grain);
    EXPECT_EQ(runAndCollect(exec, c.count, c.grain), expectedBlocks(c.count, c.grain));
  }
}

TEST_P(ExecutorThreads, ParallelForBlocksNumbersBlocksInOrder) {
  const Executor exec(GetParam());
  for (const LoopCase& c : kLoopCases) {
    SCOPED_TRACE(::testing::Message() << "count " << c.count << ", grain " << c.grain);
    const Index blocks = Executor::blockCount(c.count, c.grain);
    // One slot per block, as a reduction uses it: each written exactly once.
    std::vector<Block> slot(static_cast<size_t>(blocks), Block{-1, -1});
    std::vector<std::atomic<int>> writes(static_cast<size_t>(blocks));
    for (auto& w : writes) w.store(0);
    exec.parallelForBlocks(c.count, c.grain, [&](Index k, Index b, Index e) {
      ASSERT_GE(k, 0);
      ASSERT_LT(k, blocks);
      slot[static_cast<size_t>(k)] = {b, e};
      writes[static_cast<size_t>(k)].fetch_add(1);
    });
    for (auto& w : writes) EXPECT_EQ(w.load(), 1);
    EXPECT_EQ(slot, expectedBlocks(c.count, c.grain));
  }
}

TEST_P(ExecutorThreads, RunExecutesTheFunctionOnce) {
  const Executor exec(GetParam());
  int calls = 0;
  exec.run([&] { ++calls; });
  EXPECT_EQ(calls, 1);
}

INSTANTIATE_TEST_SUITE_P(Threads, ExecutorThreads, ::testing::Values(1, 2),
                         [](const auto& info) { return std::to_string(info.param) + "_threads"; });

TEST(Executor, SameBlocksForOneAndTwoThreads) {
  const Executor one(1), two(2);
  for (const LoopCase& c : kLoopCases) {
    SCOPED_TRACE(::testing::Message() << "count " << c.count << ", grain " << c.grain);
    EXPECT_EQ(runAndCollect(one, c.count, c.grain), runAndCollect(two, c.count, c.grain));
  }
}

TEST(Executor, ZeroThreadsMeansAllHardwareThreads) {
  const Executor exec(0);
  const int hardware = static_cast<int>(std::thread::hardware_concurrency());
  EXPECT_EQ(exec.threadCount(), hardware > 0 ? hardware : 1);
}

TEST(Executor, NegativeThreadCountThrows) {
  try {
    Executor exec(-1);
    FAIL() << "Executor(-1) did not throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("threadCount"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("-1"), std::string::npos) << e.what();
  }
}

TEST(Executor, HonoursAnExternalArena) {
  for (int concurrency : {1, 2, 3}) {
    SCOPED_TRACE(::testing::Message() << "arena concurrency " << concurrency);
    tbb::task_arena arena(concurrency);
    const Executor exec(arena);
    EXPECT_EQ(exec.threadCount(), arena.max_concurrency());
    EXPECT_EQ(exec.threadCount(), concurrency);

    EXPECT_EQ(runAndCollect(exec, 5000, 100), expectedBlocks(5000, 100));
    // A one-thread executor calls the body directly on the caller; otherwise the work of a
    // multi-block pass runs inside the given arena.
    if (concurrency > 1) {
      std::atomic<int> wrongArena{0};
      exec.parallelFor(5000, 100, [&](Index, Index) {
        if (tbb::this_task_arena::max_concurrency() != concurrency) ++wrongArena;
      });
      EXPECT_EQ(wrongArena.load(), 0);
    }
  }
}

TEST(Executor, ExternalArenaIsInitialisedIfNeeded) {
  tbb::task_arena arena(2, 1, tbb::task_arena::priority::normal);
  ASSERT_FALSE(arena.is_active());
  const Executor exec(arena);
  EXPECT_TRUE(arena.is_active());
  EXPECT_EQ(exec.threadCount(), 2);
}

TEST(Executor, BlockCount) {
  EXPECT_EQ(Executor::blockCount(0, 8), 0);
  EXPECT_EQ(Executor::blockCount(-5, 8), 0);
  EXPECT_EQ(Executor::blockCount(1, 8), 1);
  EXPECT_EQ(Executor::blockCount(8, 8), 1);
  EXPECT_EQ(Executor::blockCount(9, 8), 2);
  EXPECT_EQ(Executor::blockCount(16, 8), 2);
}

// ---------------------------------------------------------------------------------------
// stateHash
// ---------------------------------------------------------------------------------------

template <class S>
class StateHash : public ::testing::Test {};
TYPED_TEST_SUITE(StateHash, ScalarTypes);

template <class S>
State<S> randomState(Index n) {
  State<S> s;
  s.x = Vec3Array<S>::Zero(n, 3);
  s.v = Vec3Array<S>::Zero(n, 3);
  addNoise<S>(s.x, 1.0, 11);
  addNoise<S>(s.v, 0.1, 12);
  return s;
}

/// Flips bit `bit` of the S stored at `value`.
template <class S>
void flipBit(S& value, int bit) {
  using Bits = std::conditional_t<std::is_same_v<S, float>, std::uint32_t, std::uint64_t>;
  value = std::bit_cast<S>(static_cast<Bits>(std::bit_cast<Bits>(value) ^ (Bits(1) << bit)));
}

TYPED_TEST(StateHash, EqualForCopies) {
  using S = TypeParam;
  const State<S> a = randomState<S>(37);
  const State<S> b = a;  // NOLINT(performance-unnecessary-copy-initialization)
  EXPECT_EQ(stateHash(a), stateHash(b));
  EXPECT_EQ(stateHash(a), stateHash(a));
}

TYPED_TEST(StateHash, ChangesWhenOneBitOfOneVelocityChanges) {
  using S = TypeParam;
  const State<S> a = randomState<S>(37);
  const std::uint64_t h = stateHash(a);
  for (Index i : {0, 17, 36})
    for (int c = 0; c < 3; ++c)
      for (int bit : {0, 1, static_cast<int>(8 * sizeof(S)) - 1}) {
        State<S> b = a;
        flipBit(b.v(i, c), bit);
        EXPECT_NE(stateHash(b), h) << "velocity (" << i << ", " << c << "), bit " << bit;
      }
}

TYPED_TEST(StateHash, ChangesWhenOneBitOfOnePositionChanges) {
  using S = TypeParam;
  const State<S> a = randomState<S>(37);
  State<S> b = a;
  flipBit(b.x(20, 1), 0);
  EXPECT_NE(stateHash(b), stateHash(a));
}

TYPED_TEST(StateHash, DistinguishesPositionsFromVelocitiesAndIgnoresTime) {
  using S = TypeParam;
  const State<S> a = randomState<S>(5);
  State<S> swapped = a;
  swapped.x.swap(swapped.v);
  EXPECT_NE(stateHash(swapped), stateHash(a));
  State<S> later = a;
  later.time = 42;
  EXPECT_EQ(stateHash(later), stateHash(a));  // documented: time excluded
}

TYPED_TEST(StateHash, DependsOnTheParticleCount) {
  using S = TypeParam;
  State<S> empty, one;
  one.x = Vec3Array<S>::Zero(1, 3);
  one.v = Vec3Array<S>::Zero(1, 3);
  EXPECT_NE(stateHash(empty), stateHash(one));
}

}  // namespace
}  // namespace weft::test
