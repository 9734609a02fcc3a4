// weft/scene/fixed_step_clock.hpp — drive a Simulation from a frame loop.
//
// Design note
// -----------
// The original design's rope "behaved differently on different machines" because it was
// stepped by the frame time. A FixedStepClock decouples the two (the accumulator of
// Fiedler's "Fix your timestep"): each frame adds its duration to an accumulator, the
// simulation takes as many fixed steps of dt as fit, and the remainder carries to the
// next frame. The physics therefore depends only on dt and the number of steps: any
// sequence of frame times reaching the same simulated time reaches bitwise the same state.
//
// Elapsed time is accounted as an exact integer number of steps plus a remainder: the
// frame times are summed in long double and the steps due are floor(total / dt), so
// rounding in the accumulation cannot make two frame sequences of the same total take
// different step counts by more than the rounding of that one division.
//
// For display, interpolatedPositions() blends the positions before and after the last
// step by alpha = remainder / dt, so motion looks smooth at any frame rate (what is shown
// lags real time by up to one step, the usual price of interpolating rather than
// extrapolating). The previous
// positions are copied once per advance() (before its last step), into a buffer sized at
// construction: advance() does not allocate.
//
// A frame longer than maxStepsPerAdvance steps (a debugger pause, a hitch) does not make
// the next frames try to catch up for ever (the "spiral of death"): the excess is dropped
// and counted in droppedTime().
#pragma once

#include "weft/scene/simulation.hpp"

namespace weft {

template <class S>
class FixedStepClock {
 public:
  /// `sim` must outlive the clock. maxStepsPerAdvance >= 1.
  explicit FixedStepClock(Simulation<S>& sim, Index maxStepsPerAdvance = 64);

  /// Adds `frameTime` (s, finite, >= 0) and takes the fixed steps now due (at most
  /// maxStepsPerAdvance). Stops at the first failed step and returns its status; the
  /// clock then holds the time it could not simulate until the Simulation steps again.
  /// Throws std::invalid_argument for a negative or non-finite frame time.
  StepStatus advance(double frameTime);

  /// How far the frame time is past state().time, in steps: in [0, 1).
  double alpha() const;
  /// Positions to display now: (1 - alpha) x_before_last_step + alpha x. `out` is resized
  /// to (n x 3) if needed (allocation only then).
  void interpolatedPositions(Vec3Array<S>& out) const;

  /// Frame time received so far, s.
  double frameTime() const { return static_cast<double>(total_); }
  /// Frame time dropped because a frame needed more than maxStepsPerAdvance steps, s.
  double droppedTime() const { return static_cast<double>(dropped_); }
  Index stepsTaken() const { return steps_; }

 private:
  Simulation<S>* sim_;
  Index maxSteps_;
  long double total_ = 0;    // frame time received, s
  long double dropped_ = 0;  // frame time dropped, s
  Index steps_ = 0;          // steps taken by this clock
  // Accounting restarts when the Simulation's dt changes: frame time and steps at that point.
  double dt_ = 0;
  long double baseTime_ = 0;
  Index baseSteps_ = 0;
  Vec3Array<S> previous_;  // (n x 3) positions before the last step, m
  bool hasPrevious_ = false;
};

extern template class FixedStepClock<float>;
extern template class FixedStepClock<double>;

}  // namespace weft
