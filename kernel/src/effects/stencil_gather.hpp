// effects/stencil_gather.hpp (internal) — the gather of the grid stencil: a particle's sum
// over one spring family is that family's value at its own row minus the value `offset`
// rows back (the spring that ends there). Shared by the force field's stencil strategy and
// the Jacobian's stencil products.
#pragma once

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

}  // namespace weft::detail
