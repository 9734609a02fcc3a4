// weft/core/state.hpp — what a step writes.
//
// Design note
// -----------
// A State holds the dynamic quantities of one run: positions, velocities and the
// simulated time. It is deliberately small and copyable, so several states can share
// one Model (batches, the accuracy study, rollback snapshots). Integrators compute the
// next state into their own workspace and swap it in only after the stability check
// passed, so a State never holds the NaN of a failed step. Swapping exchanges storage
// (no copy, no allocation): do not keep raw pointers into x or v across steps.
#pragma once

#include <cstdint>

#include "weft/core/types.hpp"

namespace weft {

template <class S>
struct State {
  Vec3Array<S> x;   // (n x 3) positions, m
  Vec3Array<S> v;   // (n x 3) velocities, m/s
  double time = 0;  // simulated time, s (double whatever S is, so long runs keep their clock)

  Index particleCount() const { return static_cast<Index>(x.rows()); }
};

/// 64-bit FNV-1a hash of the bits of positions and velocities (time excluded): equal
/// hashes mean bitwise-equal states. Used by the determinism tests and `weft run`.
template <class S>
std::uint64_t stateHash(const State<S>& state);

extern template std::uint64_t stateHash(const State<float>&);
extern template std::uint64_t stateHash(const State<double>&);

}  // namespace weft
