// weft/collide/obstacles.hpp — analytic obstacles (plane, sphere, capsule, box), contact
// response with restitution and Coulomb friction, continuous detection, and the
// penetration measure that drives rollback in time.
//
// Design note
// -----------
// Every obstacle is a signed distance function phi(x) (negative inside) with its outward
// normal; particles are spheres of radius `thickness`, so a particle is in contact when
// phi(x) < thickness. After the integrator has produced the candidate state (x1, v1) of a
// time chunk from (x0, v0), each free particle is handled on its own (so in parallel and
// bitwise the same for any thread count):
//
//   detection   discrete: phi(x1) < thickness; when x0 was clear, the time of impact s along
//               x0 -> x1 by bisection until the particle is within `epsilon` of the
//               thickened surface (the lecture notes' time of impact). Continuous (the
//               default) also when x1 is clear: conservative advancement along the
//               segment (phi is 1-Lipschitz, so a step of phi - thickness never jumps over
//               the surface) to the first impact within epsilon. A particle fast enough to
//               cross a thin obstacle within one chunk is caught, where discrete detection,
//               which only sees x1 on the far side, misses it.
//   response    position: a penetrating x1 is pushed out along the normal to phi = thickness
//               (continuous hits: put at the impact point, then slid along the surface by
//               the tangential rest of the motion); velocity: the normal part v_n < 0
//               becomes -e v_n (e = restitution, 0 below restingSpeed so resting contact
//               does not bounce), and the tangential part v_t feels Coulomb friction with
//               the normal impulse per unit mass dv_n = (1 + e)|v_n|: static (v_t = 0)
//               when |v_t| <= mu_s dv_n, else kinetic (|v_t| reduced by mu_k dv_n).
//
// Mesh obstacles (MeshObstacle) are shells of the thickness around their triangles, static
// or moving rigidly along a KinematicPath. Their BVH is built once over the vertices at
// time 0, and each particle's chunk x0 -> x1 is mapped into that frame (x0 by the inverse
// motion at t0, x1 at t1), so the mesh never needs a refit. Distances are the BVH's
// closest-triangle query (radius: the thickness plus the rest of the segment, the
// particle's swept bound); the time of impact is found by the same conservative
// advancement, and counts only while the particle approaches the surface. The response is
// the one above, in the mesh's frame and with the velocity relative to the surface point.
//
// With v_t = 0 under static friction and v_n = 0 at rest, a settled cloth neither jitters
// nor creeps. The Simulation measures the deepest penetration of each chunk before the
// response; above CollisionOptions::maxPenetration it rolls the chunk back (the state is
// never overwritten, so the restore is exact) and retries with half the chunk, down to
// maxHalvings halvings, then accepts and counts it.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "weft/core/kinematic_path.hpp"
#include "weft/core/parallel.hpp"
#include "weft/core/types.hpp"
#include "weft/model/topology.hpp"
#include "weft/model/triangle_mesh.hpp"

namespace weft {

enum class ObstacleKind { Plane, Sphere, Capsule, Box };
const char* obstacleKindName(ObstacleKind kind);

/// A static obstacle. Fields by kind:
///   Plane    point (on it), normal (outward, normalised on use)
///   Sphere   point (centre), radius
///   Capsule  point and end (the axis segment), radius
///   Box      point (centre), halfExtents (axis-aligned), radius (rounding of the edges, >= 0)
struct Obstacle {
  ObstacleKind kind = ObstacleKind::Plane;
  Vec3d point{0, 0, 0};
  Vec3d normal{0, 1, 0};
  Vec3d end{0, 0, 0};
  Vec3d halfExtents{0.5, 0.5, 0.5};
  double radius = 0.5;
  double restitution = 0;        // e in [0, 1]
  double staticFriction = 0.5;   // mu_s >= 0
  double kineticFriction = 0.3;  // mu_k in [0, mu_s]

  static Obstacle plane(const Vec3d& point, const Vec3d& normal);
  static Obstacle sphere(const Vec3d& centre, double radius);
  static Obstacle capsule(const Vec3d& a, const Vec3d& b, double radius);
  static Obstacle box(const Vec3d& centre, const Vec3d& halfExtents);
};

/// A triangle mesh obstacle (a thin shell of the collision thickness around its
/// triangles, so it may be open: a wall of one triangle), static or moved rigidly along a
/// KinematicPath. `mesh` gives the vertices at time 0 (m); the ContactSolver builds a
/// TriangleBvh over them once and queries it in the mesh's own frame, so a moving mesh
/// needs no refit.
struct MeshObstacle {
  std::string name;                   // for messages and reports (a file name, "wall")
  TriangleMesh mesh;                  // at least one triangle
  std::optional<KinematicPath> path;  // absent: static
  double restitution = 0;             // e in [0, 1]
  double staticFriction = 0.5;        // mu_s >= 0
  double kineticFriction = 0.3;       // mu_k in [0, mu_s]
};

struct CollisionOptions {
  std::vector<Obstacle> obstacles;   // analytic obstacles
  std::vector<MeshObstacle> meshes;  // triangle mesh obstacles; with no obstacle of either kind collision costs nothing
  double thickness = 0.005;          // particle radius / cloth thickness, m (> 0)
  bool continuous = true;            // continuous detection (no tunnelling)
  bool edges = true;                 // with continuous: cloth and rope edges against the meshes' feature edges too
  bool corners = true;               // with continuous: the meshes' corners (ends of feature edges) against cloth
                                     // triangles too, so that a sharp corner cannot poke through a cloth face
  double featureAngle = 30;          // degrees in [0, 180]: a mesh edge whose faces' normals differ by at least
                                     // this much (or with one face, or more than two) is a feature edge; 0: every edge
  double epsilon = 1e-5;             // time-of-impact tolerance, m (> 0, < thickness)
  double restingSpeed = 0.05;        // m/s: slower normal approach does not bounce
  double maxPenetration = 0;         // rollback above this depth (m); 0 = half the thickness
  int maxHalvings = 6;               // rollback halvings of a chunk before it is accepted anyway
  bool any() const { return !obstacles.empty() || !meshes.empty(); }
};

/// Throws std::invalid_argument naming the field (prefixed by `where`) and the value.
void validateCollision(const CollisionOptions& options, const char* where = "collision");
/// Throws std::invalid_argument naming the obstacle and its extent when an obstacle's
/// surface (or a mesh vertex, at time 0) lies farther from the origin than thickness /
/// (4 epsilon): there, rounding in a precision of machine epsilon `epsilon` (named
/// `precision` in the message) moves a contact by more than a quarter of the thickness.
/// In double with the default 5 mm, 5.6e12 m; in float, about 10 km. Simulation<S> applies
/// it with S's epsilon.
void validateCollisionReach(const CollisionOptions& options, double epsilon, const char* precision,
                            const char* where = "collision");

/// Signed distance (m, negative inside) and outward unit normal of an obstacle at x.
double obstacleDistance(const Obstacle& o, const Vec3d& x, Vec3d* normal = nullptr);

/// Collision work and findings, per step and summed.
struct CollisionStats {
  std::int64_t contacts = 0;        // particles whose candidate state touched an obstacle
  std::int64_t continuousHits = 0;  // of which found only by continuous detection
  std::int64_t edgeContacts = 0;    // cloth / rope edges that hit a mesh edge (CollisionOptions::edges)
  std::int64_t cornerContacts = 0;  // cloth triangles that hit a mesh corner (CollisionOptions::corners)
  std::int64_t rollbacks = 0;       // chunks rolled back and retried with half the time
  std::int64_t acceptedDeep = 0;    // chunks accepted at the halving limit above maxPenetration
  double maxPenetration = 0;        // deepest penetration seen before the response, m
  CollisionStats& operator+=(const CollisionStats& o);
};

/// The contact pass itself (ContactSolver, and MeshCollider, a mesh obstacle prepared for
/// queries) is internal to weft: kernel/src/collide/contact_solver.hpp. A Simulation reports
/// what it finds (Simulation::contactReport, lastCollision, totalCollision).
template <class S>
class ContactSolver;
struct MeshCollider;
class CollisionModel;  // weft/collide/collision_model.hpp

}  // namespace weft
