// weft/collide/collision_model.hpp — what the contact pass only reads, built once: each
// mesh obstacle prepared for queries (its vertices in double, its triangles, a BVH over
// them, whether it is closed, its feature edges and corners).
//
// Design note
// -----------
// Preparing a mesh obstacle costs a BVH build, a closedness check and, for the edge and
// corner passes, a sort of its edges: work that depends on the obstacle alone, not on the cloth or the
// state. A CollisionModel holds it, immutable after construction, so several Simulations
// (a batch of runs, the accuracy study, a program restarting a scene) share one by
// SimulationOptions::collisionModel, as they share one particle Model; without one, each
// Simulation builds its own. A Simulation checks that the model it is given was built from
// the same meshes (vertices and triangles) and feature angle as its CollisionOptions, and
// refuses it otherwise.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "weft/collide/obstacles.hpp"

namespace weft {

class CollisionModel {
 public:
  /// Validates `options` (validateCollision) and prepares each of options.meshes. Throws
  /// std::invalid_argument naming the field.
  explicit CollisionModel(const CollisionOptions& options);
  ~CollisionModel();
  CollisionModel(const CollisionModel&) = delete;
  CollisionModel& operator=(const CollisionModel&) = delete;

  /// One per CollisionOptions::meshes, in order (MeshCollider is internal:
  /// kernel/src/collide/contact_solver.hpp).
  const std::vector<MeshCollider>& meshes() const { return meshes_; }
  /// Mesh obstacles prepared.
  std::size_t meshCount() const;
  /// True when `options` has the meshes (vertices and triangles, bit for bit) and the
  /// feature angle this model was built from.
  bool matches(const CollisionOptions& options) const;

 private:
  std::vector<MeshCollider> meshes_;
  double featureAngle_ = 0;
  bool featureEdges_ = false;  // feature edges and corners computed (continuous detection with edges or corners)
};

}  // namespace weft
