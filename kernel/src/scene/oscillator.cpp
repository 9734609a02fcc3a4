#include "weft/scene/oscillator.hpp"

#include <cmath>

namespace weft {

double DampedOscillator::zeta() const { return damping / (2 * mass * omega); }

double DampedOscillator::omegaD() const { return omega * std::sqrt(1 - zeta() * zeta()); }

std::pair<double, double> DampedOscillator::exact(double t) const {
  const double sigma = zeta() * omega, wd = omegaD();
  const double a = amplitude, b = sigma * amplitude / wd;
  const double e = std::exp(-sigma * t), c = std::cos(wd * t), s = std::sin(wd * t);
  const double u = e * (a * c + b * s);
  const double du = e * (-sigma * (a * c + b * s) + (-a * wd * s + b * wd * c));
  return {rest + u, du};
}

template <class S>
ModelAndState<S> DampedOscillator::build() const {
  ModelBuilder<S> builder;
  builder.addParticle({0, 0, 0}, 1.0);
  builder.addParticle({rest + amplitude, 0, 0}, mass);
  builder.pin(0);
  builder.addSpring(0, 1, {stiffness(), damping}, SpringClass::Structural, rest);
  return builder.build();
}

SimulationOptions DampedOscillator::options(IntegratorKind kind, double dt) const {
  SimulationOptions o;
  o.integrator = kind;
  o.dt = dt;
  o.threads = 1;
  o.gravity = {0, 0, 0};
  o.stability.maxStretch = 1e6;
  return o;
}

template ModelAndState<float> DampedOscillator::build<float>() const;
template ModelAndState<double> DampedOscillator::build<double>() const;

}  // namespace weft
