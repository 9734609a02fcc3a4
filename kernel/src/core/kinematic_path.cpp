#include "weft/core/kinematic_path.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/text.hpp"

namespace weft {

namespace {

double norm(const Vec3d& a) { return std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z); }

double elapsed(const KinematicPath& path, double t) {
  return std::clamp(t, path.startTime, path.endTime) - path.startTime;
}

/// Rodrigues: r cos + (k x r) sin + k (k . r)(1 - cos), k the unit axis, by angle.
Vec3d rotate(const KinematicPath& path, const Vec3d& r, double angle) {
  if (angle == 0) return r;
  const double len = norm(path.axis);
  const Vec3d k{path.axis.x / len, path.axis.y / len, path.axis.z / len};
  const double c = std::cos(angle), s = std::sin(angle);
  const double kr = k.x * r.x + k.y * r.y + k.z * r.z;
  const Vec3d kxr{k.y * r.z - k.z * r.y, k.z * r.x - k.x * r.z, k.x * r.y - k.y * r.x};
  return {r.x * c + kxr.x * s + k.x * kr * (1 - c), r.y * c + kxr.y * s + k.y * kr * (1 - c),
          r.z * c + kxr.z * s + k.z * kr * (1 - c)};
}

std::string text(const Vec3d& v) { return detail::number3(v); }

}  // namespace

Vec3d kinematicPosition(const KinematicPath& path, const Vec3d& p0, double t) {
  const double tau = elapsed(path, t);
  const Vec3d q =
      rotate(path, {p0.x - path.center.x, p0.y - path.center.y, p0.z - path.center.z}, path.angularVelocity * tau);
  return {path.center.x + path.velocity.x * tau + q.x, path.center.y + path.velocity.y * tau + q.y,
          path.center.z + path.velocity.z * tau + q.z};
}

Vec3d kinematicInverse(const KinematicPath& path, const Vec3d& p, double t) {
  const double tau = elapsed(path, t);
  const Vec3d r{p.x - path.center.x - path.velocity.x * tau, p.y - path.center.y - path.velocity.y * tau,
                p.z - path.center.z - path.velocity.z * tau};
  const Vec3d q = rotate(path, r, -path.angularVelocity * tau);
  return {path.center.x + q.x, path.center.y + q.y, path.center.z + q.z};
}

Vec3d kinematicRotate(const KinematicPath& path, const Vec3d& d, double t) {
  return rotate(path, d, path.angularVelocity * elapsed(path, t));
}

void validateKinematicPath(const KinematicPath& p, const std::string& where) {
  const auto finite = [&](const Vec3d& v, const char* field) {
    if (!(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z)))
      throw std::invalid_argument(where + field + " must be finite, got " + text(v));
  };
  finite(p.velocity, "velocity");
  if (!detail::speedWithinLimit(p.velocity.x, p.velocity.y, p.velocity.z))
    detail::rejectField(where + "velocity", text(p.velocity), detail::speedRule());
  finite(p.center, "center");
  finite(p.axis, "axis");
  if (!std::isfinite(p.angularVelocity))
    throw std::invalid_argument(where + "angularVelocity must be finite (rad/s), got " +
                                std::to_string(p.angularVelocity));
  if (p.angularVelocity != 0 && !(norm(p.axis) > 0))
    throw std::invalid_argument(where + "axis must be a non-zero vector when angularVelocity is not 0");
  if (!(std::isfinite(p.startTime) && p.startTime >= 0))
    throw std::invalid_argument(where + "startTime must be finite and >= 0 (s), got " + std::to_string(p.startTime));
  if (!(p.endTime >= p.startTime))
    throw std::invalid_argument(where + "endTime must be >= startTime (s), got " + std::to_string(p.endTime));
}

bool kinematicSpinWithinLimit(const KinematicPath& path, double reach) {
  return std::abs(path.angularVelocity) * reach <= kMaxSpeed;
}

std::string kinematicSpinRule(double reach, const std::string& what) {
  return "at most " + detail::number(kMaxSpeed / reach) + " rad/s in size (" + what + ", " + detail::number(reach) +
         " m from the path's center, moving at " + detail::speedRule() + ")";
}

void validateKinematicSpin(const KinematicPath& path, double reach, const std::string& where, const std::string& what) {
  if (!kinematicSpinWithinLimit(path, reach))
    detail::rejectField(where + "angularVelocity", path.angularVelocity, kinematicSpinRule(reach, what));
}

}  // namespace weft
