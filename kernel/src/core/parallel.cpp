#include "weft/core/parallel.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <thread>

namespace weft {

Executor::Executor(int threadCount) {
  if (threadCount < 0) {
    throw std::invalid_argument("Executor: threadCount must be >= 0 (0 = all hardware threads), got " +
                                std::to_string(threadCount));
  }
  if (threadCount == 0) {
    threadCount = static_cast<int>(std::thread::hardware_concurrency());
    if (threadCount <= 0) threadCount = 1;
  }
  // TBB never runs more threads than it allows in all (the machine's, unless a
  // global_control says less): say so rather than promise what will not run.
  const auto allowed =
      static_cast<int>(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  threadCount_ = allowed > 0 ? std::min(threadCount, allowed) : threadCount;
  threadCount = threadCount_;
  owned_ = std::make_unique<tbb::task_arena>(threadCount);
  owned_->initialize();
  arena_ = owned_.get();
}

Executor::Executor(tbb::task_arena& external) : arena_(&external) {
  if (!external.is_active()) external.initialize();
  threadCount_ = external.max_concurrency();
  if (threadCount_ <= 0) threadCount_ = 1;
}

}  // namespace weft
