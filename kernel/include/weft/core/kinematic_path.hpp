// weft/core/kinematic_path.hpp — a prescribed rigid motion (translation + rotation), used
// by kinematic pins (scene) and by moving obstacles (collide).
//
// Design note
// -----------
// A point whose position at tau = 0 is p0 is at
//     center + velocity tau + R(axis, angularVelocity tau) (p0 - center),
//     tau = clamp(t, startTime, endTime) - startTime,
// R by Rodrigues' formula about the unit axis. The motion is frozen before startTime and
// after endTime. kinematicInverse maps a world point back to where it was at tau = 0 (the
// body frame of a moving obstacle): the transposed rotation of the translated point, so a
// round trip is exact up to rounding.
#pragma once

#include <limits>
#include <string>

#include "weft/core/types.hpp"

namespace weft {

/// A prescribed rigid motion, active between startTime and endTime (s, on the simulation's
/// clock counted from its initial state) and frozen outside.
struct KinematicPath {
  Vec3d velocity{0, 0, 0};                                   // m/s (at most kMaxSpeed)
  Vec3d center{0, 0, 0};                                     // m, the rotation centre at tau = 0
  Vec3d axis{0, 1, 0};                                       // direction of the rotation axis (normalised on use)
  double angularVelocity = 0;                                // rad/s (right hand about axis)
  double startTime = 0;                                      // s (>= 0)
  double endTime = std::numeric_limits<double>::infinity();  // s (>= startTime)
};

/// Position (m) at time t (s, counted from the initial state) of a point starting at p0.
Vec3d kinematicPosition(const KinematicPath& path, const Vec3d& p0, double t);
/// Where the point that is at `p` at time t was at tau = 0 (the inverse of kinematicPosition).
Vec3d kinematicInverse(const KinematicPath& path, const Vec3d& p, double t);
/// A direction at tau = 0 rotated to time t (no translation).
Vec3d kinematicRotate(const KinematicPath& path, const Vec3d& d, double t);

/// Throws std::invalid_argument naming `where` + the field and the value unless every
/// field is finite, the speed is at most kMaxSpeed, the axis is non-zero when the path
/// turns, 0 <= startTime <= endTime.
void validateKinematicPath(const KinematicPath& path, const std::string& where);

/// The spin of a path moving points up to `reach` m from its center (at tau = 0): the path
/// turns them at |angularVelocity| x reach, which must be at most kMaxSpeed, as their
/// translation is (a pin 1e6 m from the centre turning at 1e3 rad/s would move at 1e9 m/s).
/// Throws std::invalid_argument naming `where` + "angularVelocity", the limit, `what` the
/// farthest point is ("its farthest particle") and the value.
void validateKinematicSpin(const KinematicPath& path, double reach, const std::string& where, const std::string& what);
/// The rule validateKinematicSpin applies, as messages say it ("at most ... rad/s in size (...)").
std::string kinematicSpinRule(double reach, const std::string& what);
/// Whether |angularVelocity| x reach <= kMaxSpeed.
bool kinematicSpinWithinLimit(const KinematicPath& path, double reach);

}  // namespace weft
