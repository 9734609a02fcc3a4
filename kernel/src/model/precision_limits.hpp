// kernel/src/model/precision_limits.hpp — what ModelBuilder<S>::build() requires of the values it
// converts to the precision S, in one place: build() checks them, and the builders that add
// a whole object (addClothMesh, addRope, addClothGrid) check the values they compute before
// they add anything, so that an object they accept also builds.
#pragma once

#include <cmath>
#include <limits>

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

  static bool representable(double value) { return std::abs(value) <= kLargest; }
  static bool coordinate(double value) { return std::abs(value) <= kFarthest; }
  /// A mass whose inverse (the integrators' 1/m) is finite in S.
  static bool invertibleMass(double mass) { return mass > 0 && 1.0 / mass <= kLargest; }
};

}  // namespace weft::detail
