// Internal to weft's collide module (not installed): what the per-particle pass finds
// against the obstacles (discrete contacts and the first time of impact) and the response
// to it: restitution above the resting speed, Coulomb friction on the velocity and on the
// chunk's slide, for analytic obstacles and for (moving) meshes.
#pragma once

#include "collide/contact_solver.hpp"
#include "contact_math.hpp"
#include "weft/collide/obstacles.hpp"

namespace weft::detail {

// What the per-particle pass found for one particle.
struct Contact {
  bool found = false;
  bool continuous = false;  // found by continuous detection only (x1 itself was clear)
  double depth = 0;         // thickness - distance at x1 for discrete contacts
  double s = 1;             // time of impact along x0 -> x1
  const Obstacle* obstacle = nullptr;
  Index mesh = -1;  // or the mesh obstacle hit
};

// Discrete contacts of x1, and with `continuous` the first time of impact along x0 -> x1.
Contact detect(const CollisionOptions& opt, V p0, V p1);

/// Velocity response at a contact with normal n; returns the factor applied to the
/// tangential velocity (0: static friction).
double respondVelocity(const Surface& o, double restingSpeed, V n, V& vel);

/// Response to an analytic obstacle's contact c of the chunk p0 -> p1: the new position;
/// updates vel and sets `normal` to the obstacle's unit normal there (out of the obstacle).
V respondAnalytic(const CollisionOptions& opt, const Contact& c, V p0, V p1, V& vel, V& normal);

/// Response to mesh m hit at s along p0 -> p1 (world, chunk t0 -> t1); `normal` as for
/// respondAnalytic, in the world frame at t1.
V respondMesh(const CollisionOptions& opt, const MeshObstacle& m, const MeshCollider& c, double s, V p0, V p1,
              double t0, double t1, V& vel, V& normal);

}  // namespace weft::detail
