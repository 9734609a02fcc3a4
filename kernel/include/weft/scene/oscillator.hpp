// weft/scene/oscillator.hpp — the damped oscillator: the one built-in scene with an exact
// solution, used by the accuracy study (`weft study`), the integrator tests and the hard
// cases alike, so that what the study reports is what the tests check.
//
// Particle 0 is pinned at the origin; particle 1 of mass m starts at rest at
// (rest + amplitude, 0, 0) on one spring (ks = m omega^2, kd, rest length). Without
// gravity the motion stays on the x axis and is the linear ODE
//     m x'' = -ks (x - rest) - kd x',
// underdamped for the defaults (damping ratio zeta = kd / (2 m omega) ~ 0.03), with the
// exact solution u(t) = e^(-sigma t) (a cos(wd t) + b sin(wd t)), sigma = zeta omega,
// wd = omega sqrt(1 - zeta^2), a = amplitude, b = sigma a / wd.
#pragma once

#include <utility>

#include "weft/integrate/integrator.hpp"
#include "weft/model/model_builder.hpp"
#include "weft/scene/simulation.hpp"

namespace weft {

struct DampedOscillator {
  double mass = 0.5;                          // kg
  double omega = 2 * 3.14159265358979323846;  // undamped angular frequency, rad/s
  double damping = 0.2;                       // kd, N s/m
  double rest = 0.5;                          // m
  double amplitude = 0.25;                    // initial displacement, m (< rest: x stays > 0)

  double stiffness() const { return mass * omega * omega; }  // ks, N/m
  double zeta() const;                                       // damping ratio
  double omegaD() const;                                     // damped angular frequency, rad/s

  /// Exact (x, x') of particle 1 at time t (underdamped, released from rest).
  std::pair<double, double> exact(double t) const;

  /// The model and its initial state.
  template <class S>
  ModelAndState<S> build() const;

  /// Options for a single-threaded run without gravity and with the stretch check out of
  /// the way (the oscillator is checked against its exact solution instead).
  SimulationOptions options(IntegratorKind kind, double dt) const;
};

extern template ModelAndState<float> DampedOscillator::build<float>() const;
extern template ModelAndState<double> DampedOscillator::build<double>() const;

}  // namespace weft
