#include "weft/integrate/integrator.hpp"

#include <cmath>
#include <stdexcept>

#include "row_blocks.hpp"

namespace weft {

const char* integratorName(IntegratorKind kind) {
  switch (kind) {
    case IntegratorKind::ExplicitEuler:
      return "euler";
    case IntegratorKind::SymplecticEuler:
      return "symplectic";
    case IntegratorKind::Midpoint:
      return "midpoint";
    case IntegratorKind::Rk4:
      return "rk4";
    case IntegratorKind::VelocityVerlet:
      return "verlet";
  }
  return "unknown";
}

IntegratorKind parseIntegrator(const std::string& name) {
  for (IntegratorKind k : kAllIntegrators)
    if (name == integratorName(k)) return k;
  throw std::invalid_argument("integrator must be one of euler, symplectic, midpoint, rk4, verlet; got '" + name + "'");
}

int integratorOrder(IntegratorKind kind) {
  switch (kind) {
    case IntegratorKind::ExplicitEuler:
      return 1;
    case IntegratorKind::SymplecticEuler:
      return 1;
    case IntegratorKind::Midpoint:
      return 2;
    case IntegratorKind::Rk4:
      return 4;
    case IntegratorKind::VelocityVerlet:
      return 2;
  }
  return 0;
}

int integratorForceEvaluations(IntegratorKind kind) {
  switch (kind) {
    case IntegratorKind::ExplicitEuler:
    case IntegratorKind::SymplecticEuler:
    case IntegratorKind::VelocityVerlet:
      return 1;
    case IntegratorKind::Midpoint:
      return 2;
    case IntegratorKind::Rk4:
      return 4;
  }
  return 0;
}

double integratorStabilityLimit(IntegratorKind kind) {
  switch (kind) {
    case IntegratorKind::SymplecticEuler:
    case IntegratorKind::VelocityVerlet:
      return 2;
    case IntegratorKind::Rk4:
      return 2 * std::sqrt(2.0);
    case IntegratorKind::ExplicitEuler:
    case IntegratorKind::Midpoint:
      return 0;
  }
  return 0;
}

template <class S>
std::unique_ptr<Integrator<S>> makeIntegrator(IntegratorKind kind, Index particleCount) {
  if (particleCount < 0) throw std::invalid_argument("makeIntegrator: particleCount must be >= 0");
  switch (kind) {
    case IntegratorKind::ExplicitEuler:
      return detail::makeExplicitEuler<S>(particleCount);
    case IntegratorKind::SymplecticEuler:
      return detail::makeSymplecticEuler<S>(particleCount);
    case IntegratorKind::Midpoint:
      return detail::makeMidpoint<S>(particleCount);
    case IntegratorKind::Rk4:
      return detail::makeRk4<S>(particleCount);
    case IntegratorKind::VelocityVerlet:
      return detail::makeVelocityVerlet<S>(particleCount);
  }
  throw std::invalid_argument("makeIntegrator: unknown integrator kind");
}

template std::unique_ptr<Integrator<float>> makeIntegrator(IntegratorKind, Index);
template std::unique_ptr<Integrator<double>> makeIntegrator(IntegratorKind, Index);

}  // namespace weft
