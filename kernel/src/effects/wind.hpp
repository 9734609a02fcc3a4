// Internal: the wind effect of the ForceField (see weft/effects/effects.hpp for the model).
#pragma once

#include <vector>

#include "weft/core/parallel.hpp"
#include "weft/effects/effects.hpp"
#include "weft/model/model.hpp"

namespace weft::detail {

/// sin(theta) for any finite theta, as a polynomial after reducing to [-pi/2, pi/2]
/// (absolute error below 4e-6): the same bits on every machine (no libm call), and
/// branch-free, so loops over it vectorise. Used for the wind's gusts, where only
/// smoothness matters.
template <class S>
inline S portableSine(S theta) {
  constexpr S kInvTwoPi = S(0.15915494309189533577);
  constexpr S kTwoPi = S(6.28318530717958647693);
  constexpr S kPi = S(3.14159265358979323846);
  constexpr S kHalfPi = S(1.57079632679489661923);
  const S q = theta * kInvTwoPi;
  const S r = q - std::floor(q + S(0.5));  // [-0.5, 0.5]
  S y = kTwoPi * r;                        // [-pi, pi]
  y = y > kHalfPi ? kPi - y : (y < -kHalfPi ? -kPi - y : y);
  const S y2 = y * y;
  return y * (S(1) + y2 * (S(-1.0 / 6) + y2 * (S(1.0 / 120) + y2 * (S(-1.0 / 5040) + y2 * S(1.0 / 362880)))));
}

/// The seeded gust field: velocity(x, t) = sum_j A_j sin(k_j . (x - U t) - omega_j t + phi_j)
/// (U the mean wind).
struct GustModes {
  std::vector<double> kx, ky, kz;  // wave vectors, rad/m
  std::vector<double> omega;       // rad/s, including the advection k . U
  std::vector<double> phase;       // rad
  std::vector<double> ax, ay, az;  // amplitude vectors, m/s
  GustModes() = default;
  explicit GustModes(const WindEffect& wind);
  int count() const { return static_cast<int>(kx.size()); }
};

template <class S>
class WindForce {
 public:
  WindForce(const Model<S>& model, const WindEffect& wind);

  /// Relative air velocities at (x, v) and time t, then the triangle forces. Two passes.
  void prepare(const Vec3Array<S>& x, const Vec3Array<S>& v, double time, const Executor& exec);
  /// a_i += w_i f_i for particles [begin, begin + count); a pointers offset to `begin`.
  void add(Index begin, Index count, S* ax, S* ay, S* az) const;

  /// The air velocity at a point (m/s), for tests and tools.
  Vec3d airVelocity(const Vec3d& x, double time) const;

 private:
  const Model<S>* model_;
  WindEffect wind_;
  GustModes modes_;
  std::vector<S> mkx_, mky_, mkz_, max_, may_, maz_;  // modes in S
  std::vector<S> psi_;                                // per-evaluation phase of each mode, S
  Vec3Array<S> relative_;                             // (n x 3) u_i, m/s
  Vec3Array<S> triangleForce_;                        // (t x 3) a third of each triangle's force, N
  const Incidence* incidence_ = nullptr;              // the Model's particle -> triangles (ascending)
  // Grid path (the model's triangles are a cloth grid's): per cell, a third of the force of
  // its two triangles, 6 arrays (triangle x axis) of n + W + 1 slots; 0 = generic path.
  Index gridWidth_ = 0, gridHeight_ = 0;
  std::vector<S> cellForce_;
};

extern template class WindForce<float>;
extern template class WindForce<double>;

}  // namespace weft::detail
