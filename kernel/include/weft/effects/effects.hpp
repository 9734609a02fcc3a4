// weft/effects/effects.hpp — the optional effects beyond springs and gravity.
//
// Design note
// -----------
// Each effect is absent at its default value, and an absent effect costs nothing: the
// ForceField builds the data an effect needs (a triangle incidence list, a spatial hash)
// only when the effect is present, runs its passes only then, and the per-particle part
// of the force pass tests once per block of particles whether any effect is active,
// never per particle. Present effects are evaluated inside the force pass:
//
//   drag        a_i -= w_i c v_i, in the block that finishes particle i's acceleration.
//   wind        pass 1 (particles): air velocity relative to each particle,
//                 u_i = wind(x_i, t) - v_i;
//               pass 2 (triangles): the aerodynamic force of each triangle from the mean
//                 relative velocity u of its corners, its area A and unit normal n:
//                   drag along the normal  f_D = 1/2 rho C_D A |u| (u.n) n
//                   lift                   f_L = 1/2 rho C_L A (|u| (u.n) n - (u.n)^2 u / |u|)
//                 (f_L is perpendicular to u, in the plane of u and n, and grows like
//                 sin(2 alpha) with the angle of attack alpha; f_D + f_L is the flat-plate
//                 model of cloth aerodynamics), a third of it on each corner;
//               then each particle gathers its triangles' shares in a fixed order (CSR, as
//                 for springs). A particle on no triangle (a rope) gets a quadratic drag
//                 f = 1/2 rho C_D A_p |u_i| u_i instead, with A_p = particleArea.
//               wind(x, t) = mean + gusts: a sum of `gustModes` plane waves with seeded
//                 random directions, wavelengths around gustScale and periods around
//                 gustPeriod, frozen into the mean flow (advected at the mean velocity);
//                 smooth in space and time, rms gustStrength, and the same for a seed on
//                 every machine and thread count (own generator, own sine polynomial).
//   repulsion   the original design's "universal repulsive force": particles i, j closer
//               than radius r push apart with f = k (r - d) (x_i - x_j) / d. Pairs come from
//               a spatial hash of cell size 2r rebuilt at every evaluation (never all
//               pairs); each particle sums its neighbours' pushes over the 8 cells its
//               ball overlaps, in a fixed order, so the result does not depend on the
//               thread count.
//               Spring-joined particles are not excluded: choose r below the rest spacing.
//
// Only drag enters implicit Euler's matrix (h c I); wind and repulsion are explicit forces
// there (evaluated at the start of the step).
#pragma once

#include <cstdint>

#include "weft/core/types.hpp"

namespace weft {

/// Wind on cloth (per triangle) and on particles without triangles (per particle).
struct WindEffect {
  bool enabled = false;
  Vec3d velocity{0, 0, 0};       // mean wind, m/s
  double airDensity = 1.2;       // rho, kg/m^3 (> 0)
  double dragCoefficient = 1.0;  // C_D along the normal (>= 0)
  double liftCoefficient = 0.5;  // C_L (>= 0)
  double particleArea = 1e-3;    // A_p, m^2, for particles on no triangle (>= 0)
  double gustStrength = 0;       // rms gust speed, m/s (>= 0; 0 = steady wind)
  double gustScale = 1.0;        // typical gust wavelength, m (>= 1e-6)
  double gustPeriod = 1.0;       // typical gust period, s (> 0)
  int gustModes = 8;             // plane waves summed (1..64)
  std::uint64_t seed = 1;        // gust pattern
};

/// Universal repulsion between particles closer than `radius`.
struct RepulsionEffect {
  double radius = 0;     // r, m (>= 0; 0 = off)
  double stiffness = 0;  // k, N/m (>= 0; 0 = off)
  bool enabled() const { return radius > 0 && stiffness > 0; }
};

/// The effects of a step beyond springs and gravity. All absent by default.
struct ParticleEffects {
  double drag = 0;  // viscous drag c (N s/m, finite, >= 0): f = -c v on every free particle
  WindEffect wind;
  RepulsionEffect repulsion;
  bool any() const { return drag != 0 || wind.enabled || repulsion.enabled(); }
};

/// Throws std::invalid_argument naming the field (prefixed by `where`, e.g.
/// "SimulationOptions.effects") and the value of the first bad parameter.
void validateEffects(const ParticleEffects& effects, const char* where = "effects");

}  // namespace weft
