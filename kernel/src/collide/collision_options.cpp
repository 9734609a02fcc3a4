// Validation of CollisionOptions: every field checked, with its path and value in the
// message.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "contact_math.hpp"
#include "core/text.hpp"
#include "weft/collide/obstacles.hpp"

namespace weft {

using detail::norm;
using detail::v;

void validateCollisionReach(const CollisionOptions& c, double epsilon, const char* precision, const char* where) {
  // The rounding of a coordinate of size M is about M epsilon: a distance to a surface that
  // far out, and a particle put back onto it, are off by more than the contact can tell
  // apart once that reaches a fraction of the thickness (a sphere of radius 1e20 m rounds
  // every particle on it to the same few points, and self-collision then meets all pairs).
  const double farthest = c.thickness / (4 * epsilon);
  const auto check = [&](const std::string& field, double reach) {
    if (!(reach <= farthest))
      throw std::invalid_argument(std::string(where) + "." + field + " must be at most " + detail::number(farthest) +
                                  " m in " + precision +
                                  " precision (farther from the origin, rounding moves a contact by more than a "
                                  "quarter of the thickness, " +
                                  detail::number(c.thickness) + " m), got " + detail::number(reach) + " m");
  };
  const auto length = [](const Vec3d& a) { return std::hypot(a.x, a.y, a.z); };
  for (size_t k = 0; k < c.obstacles.size(); ++k) {
    const Obstacle& o = c.obstacles[k];
    const std::string f = "obstacles[" + std::to_string(k) + "] (" + obstacleKindName(o.kind) + ")";
    switch (o.kind) {
      case ObstacleKind::Plane: {  // the distance n . (x - point) rounds each x_k - point_k
        const double n = length(o.normal);
        check(f + ": sum |normal_k point_k| / |normal|",
              (std::abs(o.normal.x * o.point.x) + std::abs(o.normal.y * o.point.y) + std::abs(o.normal.z * o.point.z)) /
                  n);
        break;
      }
      case ObstacleKind::Sphere:
        check(f + ": |point| + radius", length(o.point) + o.radius);
        break;
      case ObstacleKind::Capsule:
        check(f + ": the farther end's distance + radius", std::max(length(o.point), length(o.end)) + o.radius);
        break;
      case ObstacleKind::Box:
        check(f + ": |point| + |halfExtents|", length(o.point) + length(o.halfExtents));
        break;
    }
  }
  for (size_t k = 0; k < c.meshes.size(); ++k) {
    const MeshObstacle& m = c.meshes[k];
    double reach = 0;
    for (const Vec3d& p : m.mesh.vertices) reach = std::max(reach, length(p));
    check("meshes[" + std::to_string(k) + "]" + (m.name.empty() ? "" : " (" + m.name + ")") +
              ": the farthest vertex's distance",
          reach);
  }
}

void validateCollision(const CollisionOptions& c, const char* where) {
  const std::string w = std::string(where) + ".";
  const auto fail = [&](const std::string& field, double value, const char* rule) {
    detail::rejectField(w + field, value, rule);  // core/text.hpp
  };
  const auto finite = [&](const std::string& field, const Vec3d& p) {
    if (!std::isfinite(p.x)) fail(field + ".x", p.x, "finite");
    if (!std::isfinite(p.y)) fail(field + ".y", p.y, "finite");
    if (!std::isfinite(p.z)) fail(field + ".z", p.z, "finite");
  };
  if (!(std::isfinite(c.thickness) && c.thickness > 0)) fail("thickness", c.thickness, "finite and > 0 (m)");
  if (!(std::isfinite(c.epsilon) && c.epsilon > 0 && c.epsilon < c.thickness))
    fail("epsilon", c.epsilon, "finite, > 0 and < thickness (m)");
  if (!(std::isfinite(c.restingSpeed) && c.restingSpeed >= 0)) fail("restingSpeed", c.restingSpeed, "finite and >= 0");
  if (!(std::isfinite(c.maxPenetration) && c.maxPenetration >= 0))
    fail("maxPenetration", c.maxPenetration, "finite and >= 0 (m)");
  if (!(c.maxHalvings >= 0 && c.maxHalvings <= 30)) fail("maxHalvings", c.maxHalvings, "in [0, 30]");
  if (!(c.featureAngle >= 0 && c.featureAngle <= 180)) fail("featureAngle", c.featureAngle, "in [0, 180] (degrees)");
  for (size_t k = 0; k < c.obstacles.size(); ++k) {
    const Obstacle& o = c.obstacles[k];
    const std::string f = "obstacles[" + std::to_string(k) + "].";
    finite(f + "point", o.point);
    if (!(std::isfinite(o.restitution) && o.restitution >= 0 && o.restitution <= 1))
      fail(f + "restitution", o.restitution, "in [0, 1]");
    if (!(std::isfinite(o.staticFriction) && o.staticFriction >= 0))
      fail(f + "staticFriction", o.staticFriction, "finite and >= 0");
    if (!(std::isfinite(o.kineticFriction) && o.kineticFriction >= 0 && o.kineticFriction <= o.staticFriction))
      fail(f + "kineticFriction", o.kineticFriction, "finite, >= 0 and <= staticFriction");
    switch (o.kind) {
      case ObstacleKind::Plane:
        finite(f + "normal", o.normal);
        if (!(norm(v(o.normal)) > 0)) fail(f + "normal", 0, "a non-zero vector (length)");
        break;
      case ObstacleKind::Capsule:
        finite(f + "end", o.end);
        [[fallthrough]];
      case ObstacleKind::Sphere:
        if (!(std::isfinite(o.radius) && o.radius > 0)) fail(f + "radius", o.radius, "finite and > 0 (m)");
        break;
      case ObstacleKind::Box: {
        finite(f + "halfExtents", o.halfExtents);
        const double smallest = std::min({o.halfExtents.x, o.halfExtents.y, o.halfExtents.z});
        if (!(smallest > 0)) fail(f + "halfExtents", smallest, "> 0 in every axis (smallest)");
        if (!(std::isfinite(o.radius) && o.radius >= 0 && o.radius <= smallest))
          fail(f + "radius", o.radius, "finite, >= 0 and <= the smallest half extent (edge rounding)");
        break;
      }
    }
  }
  for (size_t k = 0; k < c.meshes.size(); ++k) {
    const MeshObstacle& m = c.meshes[k];
    const std::string f = "meshes[" + std::to_string(k) + "]" + (m.name.empty() ? "" : " (" + m.name + ")") + ".";
    if (m.mesh.triangles.empty()) throw std::invalid_argument(w + f + "mesh must have at least one triangle, got none");
    for (size_t i = 0; i < m.mesh.vertices.size(); ++i)
      finite(f + "mesh.vertices[" + std::to_string(i) + "]", m.mesh.vertices[i]);
    const auto count = static_cast<Index>(m.mesh.vertices.size());
    for (size_t t = 0; t < m.mesh.triangles.size(); ++t)
      for (int q = 0; q < 3; ++q)
        if (m.mesh.triangles[t][q] < 0 || m.mesh.triangles[t][q] >= count)
          fail(f + "mesh.triangles[" + std::to_string(t) + "][" + std::to_string(q) + "]", m.mesh.triangles[t][q],
               "a vertex index in [0, vertex count)");
    if (!(std::isfinite(m.restitution) && m.restitution >= 0 && m.restitution <= 1))
      fail(f + "restitution", m.restitution, "in [0, 1]");
    if (!(std::isfinite(m.staticFriction) && m.staticFriction >= 0))
      fail(f + "staticFriction", m.staticFriction, "finite and >= 0");
    if (!(std::isfinite(m.kineticFriction) && m.kineticFriction >= 0 && m.kineticFriction <= m.staticFriction))
      fail(f + "kineticFriction", m.kineticFriction, "finite, >= 0 and <= staticFriction");
    if (m.path) {
      validateKinematicPath(*m.path, w + f + "path.");
      double reach = 0;  // the farthest vertex from the path's centre
      for (const Vec3d& p : m.mesh.vertices)
        reach = std::max(reach, std::hypot(p.x - m.path->center.x, p.y - m.path->center.y, p.z - m.path->center.z));
      validateKinematicSpin(*m.path, reach, w + f + "path.", "the mesh's farthest vertex");
    }
  }
}

}  // namespace weft
