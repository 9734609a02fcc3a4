#include "weft/integrate/integrator.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include "core/text.hpp"
#include "row_blocks.hpp"
#include "weft/integrate/stability.hpp"

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
    // |R(iy)| = 1 of R(z) = 1 + z + ... + z^5/120 + z^6/600, Dormand-Prince's fifth-order
    // solution (bisection to 1e-15; tests/test_integrate.cpp measures it).
    {IntegratorKind::Rk45, "rk45", 5, 6, 0.99718900863267},
    {IntegratorKind::ImplicitEuler, "implicit", 1, 1, std::numeric_limits<double>::infinity()},
    {IntegratorKind::Projective, "projective", 1, 1, std::numeric_limits<double>::infinity()},
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

const char* preconditionerName(Preconditioner p) {
  switch (p) {
    case Preconditioner::Jacobi:
      return "jacobi";
    case Preconditioner::BlockJacobi:
      return "block-jacobi";
    case Preconditioner::Projective:
      return "projective";
    case Preconditioner::Multigrid:
      return "multigrid";
    case Preconditioner::Auto:
      return "auto";
  }
  return "unknown";
}

Preconditioner parsePreconditioner(const std::string& name) {
  std::string names;
  for (const Preconditioner p : kAllPreconditioners) {
    if (name == preconditionerName(p)) return p;
    names += names.empty() ? preconditionerName(p) : std::string(", ") + preconditionerName(p);
  }
  throw std::invalid_argument("preconditioner must be one of " + names + "; got '" + name + "'");
}

int integratorOrder(IntegratorKind kind) { return traits(kind).order; }

int integratorForceEvaluations(IntegratorKind kind) { return traits(kind).forceEvaluations; }

double integratorStabilityLimit(IntegratorKind kind) { return traits(kind).stabilityLimit; }

namespace {
std::string str(double v) { return detail::number(v); }  // core/text.hpp
}  // namespace

void validateIntegratorOptions(const IntegratorOptions& o) {
  const auto bad = [](const char* field, const std::string& value, const char* rule) {
    throw std::invalid_argument(std::string("IntegratorOptions.") + field + " " + rule + ", got " + value);
  };
  if (!(std::isfinite(o.relativeTolerance) && o.relativeTolerance >= 0))
    bad("relativeTolerance", str(o.relativeTolerance), "must be finite and >= 0");
  // > 0: a coordinate passing through 0 would otherwise make its scaled error 0 / 0.
  if (!(std::isfinite(o.absoluteTolerance) && o.absoluteTolerance > 0))
    bad("absoluteTolerance", str(o.absoluteTolerance), "must be finite and > 0");
  if (!(std::isfinite(o.minSubstep) && o.minSubstep > 0))
    bad("minSubstep", str(o.minSubstep), "must be finite and > 0 (s)");
  if (o.maxSubsteps < 1 || o.maxSubsteps > kMaxIterationCap)
    bad("maxSubsteps", std::to_string(o.maxSubsteps), "must be in [1, 2^30]");
  if (!(std::isfinite(o.linearTolerance) && o.linearTolerance >= 0 && o.linearTolerance < 1))
    bad("linearTolerance", str(o.linearTolerance), "must be in [0, 1)");
  if (o.maxLinearIterations < 1 || o.maxLinearIterations > kMaxIterationCap)
    bad("maxLinearIterations", std::to_string(o.maxLinearIterations), "must be in [1, 2^30]");
  if (std::find(std::begin(kAllPreconditioners), std::end(kAllPreconditioners), o.preconditioner) ==
      std::end(kAllPreconditioners))
    bad("preconditioner", std::to_string(static_cast<int>(o.preconditioner)), "must be one of kAllPreconditioners");
  if (o.projectiveIterations < 1 || o.projectiveIterations > 10000)
    bad("projectiveIterations", std::to_string(o.projectiveIterations), "must be in 1..10000");
}

template <class S>
std::unique_ptr<Integrator<S>> makeIntegrator(IntegratorKind kind, const Model<S>& model,
                                              const IntegratorOptions& options) {
  validateIntegratorOptions(options);
  const Index particleCount = model.particleCount();
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
    case IntegratorKind::Rk45:
      return detail::makeRk45<S>(particleCount, options, maxAngularFrequency(model));
    case IntegratorKind::ImplicitEuler:
      return detail::makeImplicitEuler<S>(model, options);
    case IntegratorKind::Projective:
      return detail::makeProjective<S>(model, options);
  }
  throw std::invalid_argument("makeIntegrator: unknown integrator kind");
}

template std::unique_ptr<Integrator<float>> makeIntegrator(IntegratorKind, const Model<float>&,
                                                           const IntegratorOptions&);
template std::unique_ptr<Integrator<double>> makeIntegrator(IntegratorKind, const Model<double>&,
                                                            const IntegratorOptions&);

}  // namespace weft
