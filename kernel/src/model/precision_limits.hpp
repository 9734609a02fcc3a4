// kernel/src/model/precision_limits.hpp — what ModelBuilder<S>::build() requires of the values it
// converts to the precision S, in one place: build() checks them, and the builders that add
// a whole object (addClothMesh, addRope, addClothGrid) check the values they compute before
// they add anything, so that an object they accept also builds. The time step's rule is
// here too: Simulation<S> and the scene reader check it with the same function.
#pragma once

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <string>
#include <string_view>

#include "core/text.hpp"

namespace weft::detail {

template <class S>
struct PrecisionLimits {
  static constexpr const char* kName = sizeof(S) == sizeof(float) ? "float" : "double";
  /// The largest magnitude S holds.
  static constexpr double kLargest = static_cast<double>(std::numeric_limits<S>::max());
  /// The largest coordinate: the squares of differences of positions (spring lengths,
  /// areas, distances) stay finite, |coordinate| <= 1e18 m in float, 1e150 m in double
  /// (below sqrt(max) / 4).
  static constexpr double kFarthest = sizeof(S) == sizeof(float) ? 1e18 : 1e150;

  /// The shortest spacing between particles a builder lays out: the squares of spring
  /// lengths stay normal numbers, 1e-18 m in float, 1e-150 m in double (above sqrt(min)).
  static constexpr double kShortest = sizeof(S) == sizeof(float) ? 1e-18 : 1e-150;
  static bool spacing(double value) { return value >= kShortest; }
  /// What spacing() requires, as messages say it.
  static std::string spacingRule() {
    return "at least " + number(kShortest) + " m in " + kName +
           " precision (the squares of spring lengths must stay normal numbers)";
  }

  /// How far from the origin a spring of rest length `rest` may lie: rounding a coordinate c
  /// to S moves it by at most eps |c| / 2, so the difference of two ends within r of the
  /// origin errs by at most eps r per axis and the length by sqrt(3) eps r. Within
  /// rest / (10 sqrt(3) eps) that is at most a tenth of the rest length; farther, the spring
  /// cannot hold its shape (a float cloth of 4 cm spacing reaches 19 km; at 1e6 m a
  /// coordinate steps by 6 cm and the cloth springs apart from rest). Zero for a spring of
  /// rest length 0, which has no length to keep (the rule then does not apply).
  static double springReach(double rest) {
    return rest / (10 * std::sqrt(3.0) * static_cast<double>(std::numeric_limits<S>::epsilon()));
  }
  /// Whether a spring of rest length `rest` whose ends' largest |coordinate| is `farthest`
  /// keeps its length under rounding to S (springReach).
  static bool springResolved(double rest, double farthest) { return !(rest > 0) || farthest <= springReach(rest); }
  /// What springResolved() requires, as messages say it.
  static std::string springRule(double rest) {
    return "at most " + number(springReach(rest)) + " m in " + kName + " precision (the spring's rest length, " +
           number(rest) + " m, / (10 sqrt(3) epsilon): farther from the origin, rounding the coordinates to " + kName +
           " changes its length by more than a tenth; use double precision or build the model nearer the origin)";
  }

  /// The most rounding to S can change the length of a spring of rest length `rest` whose
  /// ends' largest |coordinate| is `farthest`, as a share of the rest length:
  /// sqrt(3) eps farthest / rest (0 for a spring of rest length 0). springResolved() holds
  /// it to a tenth; Simulation::warnings() speaks of a spring past kRoundingWarning.
  static double roundingShare(double rest, double farthest) {
    return rest > 0 ? std::sqrt(3.0) * static_cast<double>(std::numeric_limits<S>::epsilon()) * farthest / rest : 0;
  }
  /// The rounding share past which a run is warned of: one percent of a spring's length.
  /// (Measured on a float cloth of 4 cm spacing hanging from two pins: max_stretch 0.013 at
  /// the origin, 0.050 at 10 km, where the share is 5 %.)
  static constexpr double kRoundingWarning = 0.01;

  /// Throws std::invalid_argument ("<where>: the largest |coordinate| of the ends of spring
  /// [s] (particles a and b) must be ...") unless springResolved; `ends` are the six
  /// coordinates of its two ends (ModelBuilder::build and Simulation::setState).
  /// `where` is a view, not a string: callers check every spring, and a string made per call
  /// would allocate once a spring (the message is made only when a spring fails).
  static void requireSpringResolved(std::string_view where, long long s, long long a, long long b, double rest,
                                    std::initializer_list<double> ends) {
    double farthest = 0;
    for (const double c : ends) farthest = std::max(farthest, std::abs(c));
    if (!springResolved(rest, farthest))
      rejectField(std::string(where) + ": the largest |coordinate| of the ends of spring [" + std::to_string(s) +
                      "] (particles " + std::to_string(a) + " and " + std::to_string(b) + ")",
                  farthest, springRule(rest));
  }

  static bool representable(double value) { return std::abs(value) <= kLargest; }
  static bool coordinate(double value) { return std::abs(value) <= kFarthest; }
  /// What coordinate() requires, as messages say it.
  static std::string coordinateRule() {
    return "within +-" + number(kFarthest) + " m in " + kName +
           " precision (the squares of distances between particles must stay finite)";
  }
  /// A mass whose inverse (the integrators' 1/m) is finite in S.
  static bool invertibleMass(double mass) { return mass > 0 && 1.0 / mass <= kLargest; }
  /// The smallest positive normal number of S.
  static constexpr double kSmallestNormal = static_cast<double>(std::numeric_limits<S>::min());
  /// A time step S holds as a normal number (in float, 1e39 s would step by infinity and
  /// 1e-46 s by 0).
  static bool timeStep(double dt) { return dt >= kSmallestNormal && dt <= kLargest; }
  /// What timeStep() requires, as messages say it.
  static std::string timeStepRule() {
    return std::string("within the range of ") + kName + " precision ([" + number(kSmallestNormal) + ", " +
           number(kLargest) + "] s)";
  }
};

}  // namespace weft::detail
