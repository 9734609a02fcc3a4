// Internal: the gather over the Model's particle -> spring incidence lists
// (Model::springIncidence), shared by the Gather force strategy and the spring Jacobian.
#pragma once

#include <vector>

#include "weft/model/model.hpp"

namespace weft::detail {

/// (sx, sy, sz) = sum over particle i's incidence entries of +g_s (endpoint a) or -g_s
/// (endpoint b), in the list's fixed order: the gather of per-spring values.
template <class S>
inline void sumIncident(const Index* __restrict offsets, const Index* __restrict incidence, Index i,
                        const S* __restrict gx, const S* __restrict gy, const S* __restrict gz, S& sx, S& sy, S& sz) {
  sx = sy = sz = S(0);
  for (Index k = offsets[i]; k < offsets[i + 1]; ++k) {
    const Index s = incidence[k] >> 1;
    const S sign = (incidence[k] & 1) ? S(-1) : S(1);
    sx += sign * gx[s];
    sy += sign * gy[s];
    sz += sign * gz[s];
  }
}

}  // namespace weft::detail
