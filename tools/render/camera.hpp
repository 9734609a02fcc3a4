// tools/render/camera.hpp — the orbit camera of `weft render` and `weft view`, and the
// automatic framing of a scene.
//
// Design note
// -----------
// The camera circles a target point: azimuth about the world's up axis (+y; 0 looks along
// -z, from +z), elevation above the horizon, distance from the target, vertical field of
// view fovY. Framing a box (frameBounds) puts the target at the box's centre and takes the
// smallest distance at which every corner of the box projects inside `margin` of the
// image's half width and half height (for each corner c in camera axes (right r, up u,
// towards the eye f): d >= c.f + |c.r| / (margin tan(fovX / 2)) and the same with |c.u|
// and fovY). The box is the scene over the whole run (weft render records every frame
// before drawing any), so the camera stands still and nothing leaves the picture.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products
#include <limits>

namespace weftrender {

/// An axis-aligned box (empty until a point is added).
struct Bounds {
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
  Eigen::Vector3f hi = Eigen::Vector3f::Constant(-std::numeric_limits<float>::infinity());
  bool empty() const { return !(lo.x() <= hi.x()); }
  void add(const Eigen::Vector3f& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void add(const Bounds& b) {
    if (!b.empty()) {
      add(b.lo);
      add(b.hi);
    }
  }
  Eigen::Vector3f centre() const { return 0.5f * (lo + hi); }
  /// Half the diagonal, m (0 when empty).
  float radius() const { return empty() ? 0.f : 0.5f * (hi - lo).norm(); }
};

struct OrbitCamera {
  Eigen::Vector3f target = Eigen::Vector3f::Zero();  // m
  float azimuth = 0.6f;                              // rad about +y; 0: the eye on +z
  float elevation = 0.35f;                           // rad above the horizon
  float distance = 3.f;                              // m from the target
  float fovY = 0.6f;                                 // rad, vertical field of view

  Eigen::Vector3f eye() const;
  /// World to camera (right-handed, looking along -z).
  Eigen::Matrix4f view() const;
  /// Perspective projection for width / height `aspect`, clip planes from the distance and
  /// the scene's radius (m).
  Eigen::Matrix4f projection(float aspect, float sceneRadius) const;
};

/// The camera at `azimuth`, `elevation` that frames `box` in an image of width / height
/// `aspect`, every corner within `margin` (0..1) of the half extents.
OrbitCamera frameBounds(const Bounds& box, float aspect, float azimuth, float elevation, float margin = 0.85f);

}  // namespace weftrender
