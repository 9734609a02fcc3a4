#include "weft/integrate/integrator.hpp"

#include <iterator>
#include <stdexcept>
#include <string>

#include "row_blocks.hpp"

namespace weft {

namespace {

// Everything the kernel states about each method, in one row per kind (indexed by the
// enum's value, in the order of kAllIntegrators).
struct IntegratorTraits {
  IntegratorKind kind;
  const char* name;
  int order;
  int forceEvaluations;   // per step in steady state
  double stabilityLimit;  // omega h on the imaginary axis; 0 = none without damping
};

constexpr IntegratorTraits kTraits[] = {
    {IntegratorKind::ExplicitEuler, "euler", 1, 1, 0.0},
    {IntegratorKind::SymplecticEuler, "symplectic", 1, 1, 2.0},
    {IntegratorKind::Midpoint, "midpoint", 2, 2, 0.0},
    {IntegratorKind::Rk4, "rk4", 4, 4, 2.8284271247461903},  // 2 sqrt(2)
    {IntegratorKind::VelocityVerlet, "verlet", 2, 1, 2.0},
};
static_assert(std::size(kTraits) == std::size(kAllIntegrators), "one traits row per integrator");

const IntegratorTraits& traits(IntegratorKind kind) {
  const auto i = static_cast<std::size_t>(kind);
  if (i >= std::size(kTraits) || kTraits[i].kind != kind)
    throw std::invalid_argument("unknown integrator kind " + std::to_string(static_cast<int>(kind)));
  return kTraits[i];
}

}  // namespace

const char* integratorName(IntegratorKind kind) { return traits(kind).name; }

IntegratorKind parseIntegrator(const std::string& name) {
  std::string names;
  for (const IntegratorTraits& t : kTraits) {
    if (name == t.name) return t.kind;
    names += names.empty() ? t.name : std::string(", ") + t.name;
  }
  throw std::invalid_argument("integrator must be one of " + names + "; got '" + name + "'");
}

int integratorOrder(IntegratorKind kind) { return traits(kind).order; }

int integratorForceEvaluations(IntegratorKind kind) { return traits(kind).forceEvaluations; }

double integratorStabilityLimit(IntegratorKind kind) { return traits(kind).stabilityLimit; }

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
