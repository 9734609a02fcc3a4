#include "camera.hpp"

#include <algorithm>
#include <cmath>

namespace weftrender {

namespace {
// Camera axes at (azimuth, elevation): towards the eye f, right r, up u.
void axes(float azimuth, float elevation, Eigen::Vector3f& f, Eigen::Vector3f& r, Eigen::Vector3f& u) {
  f = Eigen::Vector3f(std::cos(elevation) * std::sin(azimuth), std::sin(elevation),
                      std::cos(elevation) * std::cos(azimuth));
  r = Eigen::Vector3f(std::cos(azimuth), 0.f, -std::sin(azimuth));
  u = f.cross(r);
}
}  // namespace

Eigen::Vector3f OrbitCamera::eye() const {
  Eigen::Vector3f f, r, u;
  axes(azimuth, elevation, f, r, u);
  return target + distance * f;
}

Eigen::Matrix4f OrbitCamera::view() const {
  Eigen::Vector3f f, r, u;
  axes(azimuth, elevation, f, r, u);
  const Eigen::Vector3f e = target + distance * f;
  Eigen::Matrix4f m = Eigen::Matrix4f::Identity();
  m.block<1, 3>(0, 0) = r.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = f.transpose();
  m(0, 3) = -r.dot(e);
  m(1, 3) = -u.dot(e);
  m(2, 3) = -f.dot(e);
  return m;
}

Eigen::Matrix4f OrbitCamera::projection(float aspect, float sceneRadius) const {
  // The near plane as far out as the scene allows (depth precision), never behind the eye;
  // the far plane beyond the ground grid (6 radii around the target).
  const float radius = std::max(sceneRadius, 1e-3f);
  const float n = std::max(0.01f * distance, std::min(distance - 2.f * radius, 0.1f * distance));
  const float f = distance + 10.f * radius;
  const float t = 1.f / std::tan(0.5f * fovY);
  Eigen::Matrix4f p = Eigen::Matrix4f::Zero();
  p(0, 0) = t / aspect;
  p(1, 1) = t;
  p(2, 2) = (f + n) / (n - f);
  p(2, 3) = 2.f * f * n / (n - f);
  p(3, 2) = -1.f;
  return p;
}

OrbitCamera frameBounds(const Bounds& box, float aspect, float azimuth, float elevation, float margin) {
  OrbitCamera camera;
  camera.azimuth = azimuth;
  camera.elevation = elevation;
  if (box.empty()) return camera;
  camera.target = box.centre();
  Eigen::Vector3f f, r, u;
  axes(azimuth, elevation, f, r, u);
  const float tanY = margin * std::tan(0.5f * camera.fovY), tanX = tanY * aspect;
  float d = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3f c((corner & 1 ? box.hi : box.lo).x() - camera.target.x(),
                            (corner & 2 ? box.hi : box.lo).y() - camera.target.y(),
                            (corner & 4 ? box.hi : box.lo).z() - camera.target.z());
    d = std::max({d, c.dot(f) + std::abs(c.dot(r)) / tanX, c.dot(f) + std::abs(c.dot(u)) / tanY});
  }
  // A box of zero size (one particle): a metre away.
  camera.distance = d > 0 ? d : 1.f;
  return camera;
}

}  // namespace weftrender
