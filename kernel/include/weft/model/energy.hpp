// weft/model/energy.hpp — the energies of a state, in double.
//
//   kinetic  sum of 1/2 m |v|^2 over every particle
//   spring   sum of 1/2 k (|x_a - x_b| - rest)^2 over every spring (the potential of the
//            springs' elastic force; damping is not potential)
//   gravity  sum of -m g . x over the free particles (zero at the origin; a pinned particle
//            does not fall, its potential is not counted)
// The total is conserved by an exact solution without damping, drag, wind or contacts: what
// `weft run` prints and `weft study` measures drift against.
#pragma once

#include "weft/core/state.hpp"
#include "weft/core/types.hpp"
#include "weft/model/model.hpp"

namespace weft {

struct Energy {
  double kinetic = 0, spring = 0, gravity = 0;  // J
  double total() const { return kinetic + spring + gravity; }
};

/// The energies of `state` of `model` under `gravity` (m/s^2). Throws std::invalid_argument
/// when the state's size is not the model's.
template <class S>
Energy energy(const Model<S>& model, const State<S>& state, const Vec3d& gravity);

extern template Energy energy(const Model<float>&, const State<float>&, const Vec3d&);
extern template Energy energy(const Model<double>&, const State<double>&, const Vec3d&);

}  // namespace weft
