// Internal to weft's collide module (not installed): the double-precision 3-vector the
// contact pass computes in, conversions to and from the state's rows and the public Vec3d,
// a mesh obstacle's frame, and the surface parameters of a contact. Everything here is
// inline: the contact pass calls it per particle.
#pragma once

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>

#include "collide/bvh.hpp"
#include "weft/collide/obstacles.hpp"
#include "weft/core/kinematic_path.hpp"

namespace weft::detail {

// The contact pass keeps its own plain 3-vector instead of Eigen's Vector3d: its
// arithmetic is written out component by component, and rewriting it with Eigen's
// expressions changes which products the compiler fuses into FMAs, and so the results
// (tried: drape, drape-mesh and rope-on-pegs in double gave other state hashes). e3, v3
// and d3 convert at the boundaries (BVH queries, kinematic paths).
struct V {
  double x, y, z;
};
inline V operator+(V a, V b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V operator-(V a, V b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V operator*(double s, V a) { return {s * a.x, s * a.y, s * a.z}; }
inline double dot(V a, V b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline double dot(V a) { return dot(a, a); }
inline double norm(V a) { return std::sqrt(dot(a, a)); }
inline V v(const Vec3d& a) { return {a.x, a.y, a.z}; }

inline Vec3<double> e3(V a) { return {a.x, a.y, a.z}; }
inline V v3(const Vec3<double>& a) { return {a[0], a[1], a[2]}; }
inline Vec3d d3(V a) { return {a.x, a.y, a.z}; }

// A point in a mesh obstacle's frame (where it was at time 0) and back.
inline V toBody(const MeshObstacle& m, V p, double t) { return m.path ? v(kinematicInverse(*m.path, d3(p), t)) : p; }
inline V toWorld(const MeshObstacle& m, V p, double t) { return m.path ? v(kinematicPosition(*m.path, d3(p), t)) : p; }

// The friction and restitution of a contact, and the response to it.
struct Surface {
  double restitution, staticFriction, kineticFriction;
};
inline Surface surface(const Obstacle& o) { return {o.restitution, o.staticFriction, o.kineticFriction}; }
inline Surface surface(const MeshObstacle& m) { return {m.restitution, m.staticFriction, m.kineticFriction}; }

// The box around points p[0..3], grown by r.
inline Aabb<double> boxAround(std::initializer_list<V> points, double r) {
  Aabb<double> box{{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                    std::numeric_limits<double>::infinity()},
                   {-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                    -std::numeric_limits<double>::infinity()}};
  for (const V& p : points) {
    const double c[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k) {
      box.lo[k] = std::min(box.lo[k], c[k] - r);
      box.hi[k] = std::max(box.hi[k], c[k] + r);
    }
  }
  return box;
}

template <class S>
inline V row(const Vec3Array<S>& x, Index i) {
  return {double(x(i, 0)), double(x(i, 1)), double(x(i, 2))};
}
template <class S>
inline void setRow(Vec3Array<S>& x, Index i, V p) {
  x(i, 0) = static_cast<S>(p.x);
  x(i, 1) = static_cast<S>(p.y);
  x(i, 2) = static_cast<S>(p.z);
}

// Signed distance (m) and outward unit normal n of an analytic obstacle at p
// (obstacle_shapes.cpp).
double distance(const Obstacle& o, V p, V& n);

}  // namespace weft::detail
