// weft/effects/spring_force.hpp — the damped spring force law, in one place.
//
// Design note
// -----------
// Witkin & Baraff, "Physically Based Modeling" (SIGGRAPH course notes), particle
// dynamics, eq. for a damped spring between particles a and b:
//
//     f_a = -[ ks (|dx| - r) + kd (dv . dx) / |dx| ] dx / |dx|,   f_b = -f_a,
//     dx = x_a - x_b,  dv = v_a - v_b.
//
// Written on scalar components so that every force strategy (gathered, coloured,
// stencil) vectorises the same arithmetic over springs. One square root and one
// division per spring: |dx| = sqrt(|dx|^2) and 1/|dx| are formed once, everything else is
// multiplies. |dx| is the correctly rounded square root on purpose: the stiff term
// ks (|dx| - r) cancels, so an ulp of |dx| becomes an absolute force error amplified by
// ks/m. (|dx|^2 / sqrt(|dx|^2) saves nothing measurable in the full force pass, and after
// 100 RK4 steps of the 64^2 flag it differed from a textbook implementation by 1.3e-12
// m/s instead of 3.3e-13.)
// A spring whose length reaches zero has no direction; the force is then zero instead
// of NaN (the guard is a select, not a branch, so the loop still vectorises, and the
// division is always performed on a safe denominator so no speculation is needed).
#pragma once

#include <cmath>
#include <limits>

namespace weft {

/// Force on endpoint a of a damped spring (the force on b is its negation).
/// dx = x_a - x_b, dv = v_a - v_b; rest length r, stiffness ks, damping kd.
template <class S>
inline void dampedSpringForce(S dx, S dy, S dz, S dvx, S dvy, S dvz, S rest, S ks, S kd, S& fx, S& fy, S& fz) {
  const S len2 = dx * dx + dy * dy + dz * dz;
  // Below the smallest normal number 1/|dx| could overflow: treat as zero length.
  const bool hasDirection = len2 > std::numeric_limits<S>::min();
  const S len = std::sqrt(len2);
  const S invLen = (hasDirection ? S(1) : S(0)) / (hasDirection ? len : S(1));
  const S dvDotDx = dvx * dx + dvy * dy + dvz * dz;
  const S magnitude = ks * (len - rest) + kd * dvDotDx * invLen;
  const S scale = -magnitude * invLen;
  fx = scale * dx;
  fy = scale * dy;
  fz = scale * dz;
}

/// Potential energy of a spring of length len: ks (len - r)^2 / 2.
template <class S>
inline S springEnergy(S len, S rest, S ks) {
  const S e = len - rest;
  return S(0.5) * ks * e * e;
}

}  // namespace weft
