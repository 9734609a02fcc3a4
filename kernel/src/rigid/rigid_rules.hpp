// rigid/rigid_rules.hpp (internal) — the rules on a body's position and spin beyond
// finiteness, as messages say them: the body descriptions (rigid_model.cpp) and
// RigidWorld::setState (rigid_world.cpp) apply the same ones.
#pragma once

#include <string>

#include "core/text.hpp"
#include "weft/rigid/rigid_world.hpp"

namespace weft::detail {

inline std::string farthestBodyRule() {
  static_assert(kFarthestBody == 1e150, "the rule's text names the bound");
  return "within +-1e150 m (the squares of distances between bodies must stay finite)";
}

/// |w| reach <= kMaxSpeed: the body's farthest point, `reach` m from its centre of mass.
inline bool spinWithinLimit(const Eigen::Vector3d& w, double reach) {
  return std::hypot(w.x(), w.y(), w.z()) * reach <= kMaxSpeed;
}
inline std::string spinRule(double reach) {
  return "at most " + number(kMaxSpeed / reach) + " rad/s in size (the body's farthest point, " + number(reach) +
         " m from its centre of mass, moving at " + speedRule() + ")";
}

}  // namespace weft::detail
