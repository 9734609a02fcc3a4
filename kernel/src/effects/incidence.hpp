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

}  // namespace weft::detail
