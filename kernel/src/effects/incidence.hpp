// Internal: the particle-to-spring incidence lists shared by the Gather force strategy
// and the spring Jacobian.
#pragma once

#include <vector>

#include "weft/model/model.hpp"

namespace weft::detail {

/// CSR incidence of the springs: particle i's entries are incidence[offsets[i] ..
/// offsets[i + 1]), each 2 s + side (side 1: the particle is endpoint b of spring s), with
/// the springs in index order, so that every per-particle sum over them has a fixed order.
template <class S>
void buildIncidence(const Model<S>& model, IndexArray& offsets, IndexArray& incidence) {
  const Index n = model.particleCount();
  const Index m = model.springCount();
  const Springs<S>& sp = model.springs();
  offsets.setZero(n + 1);
  for (Index s = 0; s < m; ++s) {
    ++offsets[sp.a[s] + 1];
    ++offsets[sp.b[s] + 1];
  }
  for (Index i = 0; i < n; ++i) offsets[i + 1] += offsets[i];
  incidence.resize(2 * m);
  std::vector<Index> fill(offsets.data(), offsets.data() + n);
  for (Index s = 0; s < m; ++s) {
    incidence[fill[sp.a[s]]++] = 2 * s;
    incidence[fill[sp.b[s]]++] = 2 * s + 1;
  }
}

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
