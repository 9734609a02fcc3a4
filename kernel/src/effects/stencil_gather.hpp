// effects/stencil_gather.hpp (internal) — the gather of the grid stencil: a particle's sum
// over one spring family is that family's value at its own row minus the value `offset`
// rows back (the spring that ends there). Shared by the force field's stencil strategy, the
// Jacobian's stencil products and projective dynamics' grid pass, with the per-thread
// windows those passes compute a chunk's springs into.
#pragma once

#include <algorithm>
#include <stdexcept>
#include <string>
#include <vector>

#include "weft/core/parallel.hpp"
#include "weft/core/types.hpp"

namespace weft::detail {

/// t[i] += f[i] - f[i - offset] over [0, count): one family's share of the stencil gather.
/// Not inlined: one copy, so the additions round the same on every path and thread count.
template <class S>
[[gnu::noinline]] void addStencilFamily(Index count, Index offset, const S* __restrict fx, const S* __restrict fy,
                                        const S* __restrict fz, S* __restrict tx, S* __restrict ty, S* __restrict tz) {
  for (Index i = 0; i < count; ++i) {
    tx[i] += fx[i] - fx[i - offset];
    ty[i] += fy[i] - fy[i - offset];
    tz[i] += fz[i] - fz[i - offset];
  }
}

/// Windows a pass of `chunks` tasks on `exec` uses: 1 when it runs serially (one thread or
/// one chunk: Executor::parallelFor then calls the body directly, maybe outside the arena),
/// else one per thread of the arena.
inline std::size_t stencilWindowCount(const Executor& exec, Index chunks) {
  return exec.threadCount() == 1 || chunks == 1 ? 1 : static_cast<std::size_t>(exec.threadCount());
}

/// Makes `slots` windows of `perWindow` values unless there are that many already (a pass
/// writes every slot it reads before reading it, so their contents never matter).
template <class S>
void reserveStencilWindows(std::vector<S>& windows, std::size_t slots, std::size_t perWindow) {
  if (windows.size() < slots * perWindow) windows.assign(slots * perWindow, S(0));
}

/// The window of the task calling it, among `slots` (stencilWindowCount): the thread's
/// slot in the executor's arena, or window 0 on the serial path. `who` names the pass in
/// the logic_error thrown if the task runs outside the arena.
template <class S>
S* stencilWindow(std::vector<S>& windows, std::size_t slots, std::size_t perWindow, const char* who) {
  const int thread = slots == 1 ? 0 : tbb::this_task_arena::current_thread_index();
  if (thread < 0 || static_cast<std::size_t>(thread) >= slots)
    throw std::logic_error(std::string(who) + ": a stencil chunk ran outside the executor's arena");
  return windows.data() + static_cast<std::size_t>(thread) * perWindow;
}

/// A grid pass run a chunk of particles at a time, each chunk computing the springs of its
/// rows and of the rows above that its gather reaches into its thread's window (the
/// Jacobian's products, projective dynamics' local step): particles per chunk (at least
/// `base` in double, twice that in float, the same bytes, and 16 rows; a multiple of
/// `align`), and slots per family and axis of a window (`pad` zeros, the largest family
/// offset, then the rows a chunk touches), padded so consecutive arrays start 5 cache
/// lines apart modulo 4 KiB (a gather streams 36 of them at once; at power-of-two strides
/// they would share the L1 sets).
struct StencilChunks {
  Index chunk = 0;
  Index window = 0;
};
template <class S>
StencilChunks stencilChunks(Index width, Index pad, Index base, Index align) {
  const Index W = std::max<Index>(width, 1);
  StencilChunks c;
  c.chunk = std::max<Index>(base * static_cast<Index>(8 / sizeof(S)), 16 * W);
  c.chunk = (c.chunk + align - 1) / align * align;
  // A chunk [b, b + chunk) reads the rows from that of b - pad to that of b + chunk - 1.
  c.window = pad + ((c.chunk + pad - 1) / W + 2) * W;
  const Index perLine = static_cast<Index>(64 / sizeof(S)), perPage = static_cast<Index>(4096 / sizeof(S));
  c.window = (c.window + perLine - 1) / perLine * perLine;
  c.window += ((5 * perLine - c.window % perPage) % perPage + perPage) % perPage;
  return c;
}

}  // namespace weft::detail
