#include "weft/scene/fixed_step_clock.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "core/text.hpp"

namespace weft {

template <class S>
FixedStepClock<S>::FixedStepClock(Simulation<S>& sim, Index maxStepsPerAdvance)
    : sim_(&sim), maxSteps_(maxStepsPerAdvance), dt_(sim.timeStep()), previous_(sim.model().particleCount(), 3) {
  if (maxStepsPerAdvance < 1)
    throw std::invalid_argument("FixedStepClock: maxStepsPerAdvance must be >= 1, got " +
                                std::to_string(maxStepsPerAdvance));
}

template <class S>
StepStatus FixedStepClock<S>::advance(double frameTime) {
  if (!(std::isfinite(frameTime) && frameTime >= 0))
    detail::rejectField("FixedStepClock::advance: frameTime", frameTime, "finite and >= 0 (s)");
  if (sim_->timeStep() != dt_) {  // a new dt: what was simulated so far stays, count afresh
    baseTime_ = total_ - dropped_;
    baseSteps_ = steps_;
    dt_ = sim_->timeStep();
  }
  total_ += frameTime;
  const long double elapsed = total_ - dropped_ - baseTime_;
  Index due = static_cast<Index>(std::floor(elapsed / dt_)) - (steps_ - baseSteps_);
  if (due > maxSteps_) {
    dropped_ += static_cast<long double>(due - maxSteps_) * dt_;
    due = maxSteps_;
  }
  StepStatus status = sim_->status();
  for (Index k = 0; k < due; ++k) {
    if (k + 1 == due) {
      previous_ = sim_->state().x;  // same size: a copy, no allocation
      hasPrevious_ = true;
    }
    status = sim_->step();
    if (!status.ok()) break;
    ++steps_;
  }
  return status;
}

template <class S>
double FixedStepClock<S>::alpha() const {
  const long double elapsed = total_ - dropped_ - baseTime_;
  const long double carried = elapsed - static_cast<long double>(steps_ - baseSteps_) * dt_;
  const double a = static_cast<double>(carried / dt_);
  return a < 0 ? 0.0 : a >= 1 ? std::nextafter(1.0, 0.0) : a;  // >= 1 only while a step is failing
}

template <class S>
void FixedStepClock<S>::interpolatedPositions(Vec3Array<S>& out) const {
  const Vec3Array<S>& x = sim_->state().x;
  if (!hasPrevious_) {
    out = x;
    return;
  }
  const S a = static_cast<S>(alpha());
  out = (S(1) - a) * previous_ + a * x;
}

template class FixedStepClock<float>;
template class FixedStepClock<double>;

}  // namespace weft
