// Analytic obstacles (plane, sphere, capsule, rounded box): their signed distance fields
// and the public constructors and queries of weft/collide/obstacles.hpp.
#include <algorithm>
#include <cmath>
#include <limits>

#include "contact_math.hpp"
#include "weft/collide/obstacles.hpp"

namespace weft {

namespace detail {

// Signed distance and outward normal (unit) of each shape at p.
double distance(const Obstacle& o, V p, V& n) {
  switch (o.kind) {
    case ObstacleKind::Plane: {
      const V nn = v(o.normal);
      const double len = norm(nn);
      n = (1 / len) * nn;
      return dot(p - v(o.point), n);
    }
    case ObstacleKind::Sphere: {
      const V d = p - v(o.point);
      const double len = norm(d);
      n = len > 0 ? (1 / len) * d : V{0, 1, 0};
      return len - o.radius;
    }
    case ObstacleKind::Capsule: {
      const V a = v(o.point), ab = v(o.end) - a;
      const double ll = dot(ab, ab);
      const double t = ll > 0 ? std::clamp(dot(p - a, ab) / ll, 0.0, 1.0) : 0.0;
      const V d = p - (a + t * ab);
      const double len = norm(d);
      n = len > 0 ? (1 / len) * d : V{0, 1, 0};
      return len - o.radius;
    }
    case ObstacleKind::Box: {
      // Rounded box: the box shrunk by the rounding radius, then inflated by it.
      const V c = v(o.point);
      const double r = o.radius;
      const V e{o.halfExtents.x - r, o.halfExtents.y - r, o.halfExtents.z - r};
      const V d = p - c;
      const V q{std::abs(d.x) - e.x, std::abs(d.y) - e.y, std::abs(d.z) - e.z};
      const V outside{std::max(q.x, 0.0), std::max(q.y, 0.0), std::max(q.z, 0.0)};
      const double lo = norm(outside);
      const double inside = std::min(std::max(q.x, std::max(q.y, q.z)), 0.0);
      if (lo > 0) {
        n = (1 / lo) * V{std::copysign(outside.x, d.x), std::copysign(outside.y, d.y), std::copysign(outside.z, d.z)};
      } else {  // inside the core box: the face of least penetration
        if (q.x >= q.y && q.x >= q.z)
          n = {std::copysign(1.0, d.x), 0, 0};
        else if (q.y >= q.z)
          n = {0, std::copysign(1.0, d.y), 0};
        else
          n = {0, 0, std::copysign(1.0, d.z)};
      }
      return lo + inside - r;
    }
  }
  n = {0, 1, 0};
  return std::numeric_limits<double>::infinity();
}

}  // namespace detail

using detail::V;
using detail::v;

const char* obstacleKindName(ObstacleKind kind) {
  switch (kind) {
    case ObstacleKind::Plane:
      return "plane";
    case ObstacleKind::Sphere:
      return "sphere";
    case ObstacleKind::Capsule:
      return "capsule";
    case ObstacleKind::Box:
      return "box";
  }
  return "unknown";
}

Obstacle Obstacle::plane(const Vec3d& p, const Vec3d& n) {
  Obstacle o;
  o.kind = ObstacleKind::Plane;
  o.point = p;
  o.normal = n;
  return o;
}
Obstacle Obstacle::sphere(const Vec3d& c, double r) {
  Obstacle o;
  o.kind = ObstacleKind::Sphere;
  o.point = c;
  o.radius = r;
  return o;
}
Obstacle Obstacle::capsule(const Vec3d& a, const Vec3d& b, double r) {
  Obstacle o;
  o.kind = ObstacleKind::Capsule;
  o.point = a;
  o.end = b;
  o.radius = r;
  return o;
}
Obstacle Obstacle::box(const Vec3d& c, const Vec3d& e) {
  Obstacle o;
  o.kind = ObstacleKind::Box;
  o.point = c;
  o.halfExtents = e;
  o.radius = 0;
  return o;
}

double obstacleDistance(const Obstacle& o, const Vec3d& x, Vec3d* normal) {
  V n;
  const double phi = distance(o, v(x), n);
  if (normal) *normal = {n.x, n.y, n.z};
  return phi;
}

CollisionStats& CollisionStats::operator+=(const CollisionStats& o) {
  contacts += o.contacts;
  continuousHits += o.continuousHits;
  edgeContacts += o.edgeContacts;
  cornerContacts += o.cornerContacts;
  rollbacks += o.rollbacks;
  acceptedDeep += o.acceptedDeep;
  maxPenetration = std::max(maxPenetration, o.maxPenetration);
  return *this;
}

}  // namespace weft
