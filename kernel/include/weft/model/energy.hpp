// weft/model/energy.hpp — the energies of a state, in double.
//
//   kinetic  sum of 1/2 m |v|^2 over every particle
//   spring   sum of 1/2 k (|x_a - x_b| - rest)^2 over every spring (the potential of the
//            springs' elastic force; damping is not potential)
//   gravity  sum of -m g . x over the free particles (zero at the origin; a pinned particle
//            does not fall, its potential is not counted)
// The total is conserved by an exact solution without damping, drag, wind or contacts: what
// `weft run` prints and `weft study` measures drift against.
//
// Beside it, the stretch of a state (quality beside speed: how far the cloth gives under its
// load, compared with other simulators in bench/): the stretch of a spring is
// |x_a - x_b| / rest - 1 (0 at its rest length, 0.1 when 10 % longer, negative when
// compressed), and stretch() reports the largest and the mean over the springs of one class
// (the structural ones unless told otherwise).
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

/// The stretch of the springs of one class in a state.
struct Stretch {
  double max = 0;      // the largest |x_a - x_b| / rest - 1 (0 when no spring is counted)
  double mean = 0;     // the mean of |x_a - x_b| / rest - 1, signed (0 when no spring is counted)
  Index springs = 0;   // springs counted: those of the class with a rest length > 0
  Index longest = -1;  // the spring with the largest stretch, the first on a tie (-1 when none is counted)
};

/// The stretch of the springs of class `kind` (by default the structural ones: a cloth
/// grid's row and column neighbours, a rope's links) in `state` of `model`, computed in
/// double. Springs of rest length 0 have no stretch and are left out. Throws
/// std::invalid_argument when the state's size is not the model's or `kind` is not a class.
template <class S>
Stretch stretch(const Model<S>& model, const State<S>& state, SpringClass kind = SpringClass::Structural);

extern template Stretch stretch(const Model<float>&, const State<float>&, SpringClass);
extern template Stretch stretch(const Model<double>&, const State<double>&, SpringClass);

}  // namespace weft
