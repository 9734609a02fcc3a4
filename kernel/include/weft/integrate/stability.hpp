// weft/integrate/stability.hpp — the per-step stability check.
//
// Design note
// -----------
// Instability is observed, not hoped for. After each step the Simulation checks the
// candidate state before accepting it: every position and velocity finite, and no spring
// stretched beyond maxStretch times its rest length (the early sign of an explicit method
// past its stability limit, long before values overflow). A failure returns a StepStatus
// naming the first offending particle (lowest index, so the report is the same for any
// thread count) and the state stays at the last good step.
//
// The check runs every step, so it is built like the force passes: a parallel,
// vectorised detection pass (per block: any non-finite value? any overstretched spring?,
// with contiguous loads along the grid families when the model is a grid), and only if a
// block reports a problem, an exact serial scan that finds the first offender by index.
#pragma once

#include <string>
#include <vector>

#include "weft/core/parallel.hpp"
#include "weft/integrate/integrator.hpp"
#include "weft/model/model.hpp"

namespace weft {

struct StabilityOptions {
  bool enabled = true;
  /// A spring longer than maxStretch x its rest length fails the check (<= 0: no
  /// stretch check; else at least 1, or a spring at rest would fail). Springs of rest
  /// length 0 are covered by the finiteness check only.
  double maxStretch = 10;
};
/// Throws std::invalid_argument ("<where>.maxStretch must be ..., got ...") for a NaN
/// maxStretch or one in (0, 1).
void validateStabilityOptions(const StabilityOptions& options, const char* where = "stability");

enum class StepCode {
  Ok = 0,
  NonFinite,          // a position or velocity is NaN or infinite
  Overstretched,      // a spring exceeds maxStretch x rest length
  StepSizeUnderflow,  // adaptive error control gave up (IntegratorOptions minSubstep / maxSubsteps)
  CapacityExceeded,   // a buffer sized at construction is full (RigidOptions::maxPairs); `value` is the capacity
  TooManyCandidates,  // self-collision listed more candidate pairs than its limit; `value` is the limit per
                      // triangle (SelfCollisionOptions::maxCandidatesPerTriangle)
};
const char* stepCodeName(StepCode code);

struct StepStatus {
  StepCode code = StepCode::Ok;
  Index particle = -1;  // first offending particle (of an overstretched spring: its free end)
  Index spring = -1;    // offending spring (Overstretched)
  Index body = -1;      // offending rigid body (NonFinite of a body), or -1
  double value = 0;     // the offending value (NonFinite), stretch ratio (Overstretched) or
                        // trial substeps taken (StepSizeUnderflow)
  double time = 0;      // simulated time at the start of the failed step, s
  bool ok() const { return code == StepCode::Ok; }
  /// One line for people (allocates; not for the hot path).
  std::string message() const;
};

template <class S>
class StabilityCheck {
 public:
  StabilityCheck(const Model<S>& model, const StabilityOptions& options);
  /// Checks a candidate state; returns Ok or the first failure. Never allocates.
  StepStatus check(const Vec3Array<S>& x, const Vec3Array<S>& v, const Executor& exec);
  const StabilityOptions& options() const { return options_; }

  static constexpr Index kGrain = 4096;

 private:
  const Model<S>* model_;
  StabilityOptions options_;
  StepStatus locate(const Vec3Array<S>& x, const Vec3Array<S>& v) const;
  std::vector<char> blockBad_;  // per block of the detection pass: found a problem
};

extern template class StabilityCheck<float>;
extern template class StabilityCheck<double>;

/// Upper bound on the highest angular frequency (rad/s) of the model's undamped springs
/// about their rest state: block Gershgorin on M^-1/2 K M^-1/2, whose block for a spring
/// (k n n^T) has norm k, gives omega_max^2 <= max_i sum_s k_s (w_i + sqrt(w_i w_j)) over
/// the springs s = (i, j) of particle i (w = inverse mass). Exact for one mass on a spring
/// to a pinned point and for the interior of a uniform chain; the tension of stretched
/// springs and damping are not included. 0 for a model without springs.
template <class S>
double maxAngularFrequency(const Model<S>& model);

/// The largest time step at which `kind` is stable on the model's stiffest mode by the
/// bound above: integratorStabilityLimit(kind) / maxAngularFrequency(model). 0 for the
/// methods with no stable step on an undamped spring (explicit Euler, midpoint); +inf for
/// a model without springs.
template <class S>
double estimateStableTimeStep(const Model<S>& model, IntegratorKind kind);

extern template double maxAngularFrequency(const Model<float>&);
extern template double maxAngularFrequency(const Model<double>&);
extern template double estimateStableTimeStep(const Model<float>&, IntegratorKind);
extern template double estimateStableTimeStep(const Model<double>&, IntegratorKind);

}  // namespace weft
