// weft/core/types.hpp — scalar, index and buffer types shared by every module.
//
// Design note
// -----------
// weft stores per-particle quantities as (n x 3) column-major Eigen matrices: each
// coordinate is one contiguous column, so a stage combination of an integrator
// (x1 = x0 + h * v0) is a single vectorised streaming expression and a row block
// [b, e) of all three columns is what one parallel task touches. Per-spring and
// per-particle scalars are plain Eigen column vectors. The scalar type S is a
// template parameter; the library is explicitly instantiated for float and double.
#pragma once

#include <Eigen/Core>
#include <cstdint>

namespace weft {

/// Index of a particle or a spring. 32 bits: halves the index traffic of the force
/// passes compared to 64-bit indices and is ample for a cloth kernel (2^31 items).
using Index = std::int32_t;

/// (n x 3) column-major matrix: one row per particle, one contiguous column per axis.
template <class S>
using Vec3Array = Eigen::Matrix<S, Eigen::Dynamic, 3, Eigen::ColMajor>;

/// (n) column of scalars.
template <class S>
using ScalarArray = Eigen::Matrix<S, Eigen::Dynamic, 1>;

/// (n) column of indices.
using IndexArray = Eigen::Matrix<Index, Eigen::Dynamic, 1>;

/// A plain 3-vector for the public API (no alignment requirements, no expression
/// templates leaking through the interface).
struct Vec3d {
  double x = 0, y = 0, z = 0;
};

/// The fastest speed a velocity given to the kernel may have (particles, rigid bodies, the
/// points of a spinning body, kinematic paths), m/s: the speed of light. Nothing the kernel
/// models moves faster; a velocity of 1e300 m/s is a finite number, but its kinetic energy
/// (1/2 m v^2) and the solvers' products of speeds are not.
inline constexpr double kMaxSpeed = 299792458.0;

}  // namespace weft
