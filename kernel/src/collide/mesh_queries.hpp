// Internal to weft's collide module (not installed): queries against a mesh obstacle's
// triangles through its BVH (distance, time of impact, push-out, winding number, the
// closest feature edge, a cloth edge's first contact) and its feature edges. All work in
// the mesh's own frame; none allocates except featureEdges (at construction).
#pragma once

#include <cstdint>
#include <vector>

#include "collide/contact_solver.hpp"
#include "contact_math.hpp"
#include "weft/collide/obstacles.hpp"

namespace weft::detail {

/// Unsigned distance to a mesh within `radius` (infinity beyond), with the closest point.
double meshDistance(const MeshCollider& c, V p, double radius, V* closest = nullptr, Index* triangle = nullptr);

/// First time of impact along b0 -> b1 with the mesh thickened by h, to within eps; 1: none.
double meshImpact(const MeshCollider& c, V b0, V b1, double h, double eps);

/// Moves p out of the thickened mesh to distance h, on the side of `side`.
V pushOutOfMesh(const MeshCollider& c, V p, V side, double h);

/// Generalised winding number of a closed mesh about p (1 inside, 0 outside).
double windingNumber(const MeshCollider& c, V p);

// The mesh edge closest to the segment A B, among the triangles whose boxes overlap `box`.
struct EdgeProbe {
  double distance = std::numeric_limits<double>::infinity();
  double alpha = 0;   // along A B
  V onEdge{0, 0, 0};  // on A B
  V onMesh{0, 0, 0};  // on the mesh edge
};

EdgeProbe closestMeshEdge(const MeshCollider& c, V a, V b, const Aabb<double>& box);

/// Per triangle, a bit mask of its feature edges (see MeshCollider::featureEdges); empty
/// when the mesh has none.
std::vector<std::uint8_t> featureEdges(const MeshCollider& c, double degrees);

/// Per triangle, a bit mask of the corners it tests (see MeshCollider::corners), from the
/// feature edges; empty when the mesh has none.
std::vector<std::uint8_t> cornerMasks(const MeshCollider& c);

/// Deepest penetration (thickness - distance) of p at time t over every obstacle.
double pointPenetration(const CollisionOptions& opt, const std::vector<MeshCollider>& meshes, V p, double t);

/// The first contact of a moving edge with an edge of the thickened mesh (chunk fraction,
/// > 1: none), filling `hit`.
double edgeImpact(const MeshCollider& c, V a0, V a1, V b0, V b1, double h, double eps, EdgeProbe& hit);

}  // namespace weft::detail
