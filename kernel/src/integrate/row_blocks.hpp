// Internal: what the integrators share to combine stages block by block.
#pragma once

#include "weft/integrate/integrator.hpp"

namespace weft::detail {

template <class S>
using Column = Eigen::Map<Eigen::Array<S, Eigen::Dynamic, 1>>;
template <class S>
using ConstColumn = Eigen::Map<const Eigen::Array<S, Eigen::Dynamic, 1>>;

/// Axis c of rows [b, b + n) of an (n x 3) buffer, as an Eigen array (vectorised
/// coefficient-wise expressions, no aliasing between distinct buffers).
template <class S>
Column<S> rows(Vec3Array<S>& m, int c, Index b, Index n) {
  return Column<S>(m.data() + c * m.rows() + b, n);
}
template <class S>
ConstColumn<S> rows(const Vec3Array<S>& m, int c, Index b, Index n) {
  return ConstColumn<S>(m.data() + c * m.rows() + b, n);
}
/// The sink's accelerations of axis c.
template <class S>
ConstColumn<S> accel(const S* ax, const S* ay, const S* az, int c, Index n) {
  return ConstColumn<S>(c == 0 ? ax : c == 1 ? ay : az, n);
}

template <class S>
std::unique_ptr<Integrator<S>> makeExplicitEuler(Index n);
template <class S>
std::unique_ptr<Integrator<S>> makeSymplecticEuler(Index n);
template <class S>
std::unique_ptr<Integrator<S>> makeMidpoint(Index n);
template <class S>
std::unique_ptr<Integrator<S>> makeRk4(Index n);
template <class S>
std::unique_ptr<Integrator<S>> makeVelocityVerlet(Index n);
template <class S>
std::unique_ptr<Integrator<S>> makeRk45(Index n, const IntegratorOptions& options, double omegaMax);
template <class S>
std::unique_ptr<Integrator<S>> makeImplicitEuler(const Model<S>& model, const IntegratorOptions& options);
template <class S>
std::unique_ptr<Integrator<S>> makeProjective(const Model<S>& model, const IntegratorOptions& options);

}  // namespace weft::detail
