// Internal: the parallel pass used by every stage combination.
#pragma once

#include "weft/integrate/integrator.hpp"

namespace weft::detail {

/// Calls f(begin, length) over fixed row blocks of [0, n); f applies Eigen expressions
/// to .middleRows(begin, length) of its (n x 3) buffers.
template <class F>
inline void forRowBlocks(const Executor& exec, Index n, F&& f) {
  exec.parallelFor(n, Integrator<double>::kRowGrain, [&](Index b, Index e) { f(b, e - b); });
}

template <class S>
std::unique_ptr<Integrator<S>> makeExplicitEuler(Index n);
template <class S>
std::unique_ptr<Integrator<S>> makeSymplecticEuler(Index n);
template <class S>
std::unique_ptr<Integrator<S>> makeMidpoint(Index n);
template <class S>
std::unique_ptr<Integrator<S>> makeRk4(Index n);

}  // namespace weft::detail
