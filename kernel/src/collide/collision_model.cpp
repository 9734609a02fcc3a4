// CollisionModel: mesh obstacles prepared once (see weft/collide/collision_model.hpp).
#include "weft/collide/collision_model.hpp"

#include "collide/contact_solver.hpp"
#include "mesh_queries.hpp"
#include "weft/collide/shapes.hpp"

namespace weft {

CollisionModel::CollisionModel(const CollisionOptions& options)
    : featureAngle_(options.featureAngle), featureEdges_(options.continuous && (options.edges || options.corners)) {
  validateCollision(options);
  const Executor serial(1);
  meshes_.resize(options.meshes.size());
  for (size_t k = 0; k < options.meshes.size(); ++k) {
    MeshCollider& c = meshes_[k];
    c.x = meshPositions<double>(options.meshes[k].mesh);
    c.triangles = meshTriangles(options.meshes[k].mesh);
    c.bvh.build(c.x, c.triangles, serial);
    MeshReport report;
    cleanMesh(options.meshes[k].mesh, MeshCleanOptions{0}, &report);
    c.closed = report.boundaryEdges == 0 && report.nonManifoldEdges == 0;
    if (featureEdges_) {
      c.featureEdges = detail::featureEdges(c, featureAngle_);
      c.corners = detail::cornerMasks(c);
    }
  }
}

CollisionModel::~CollisionModel() = default;

std::size_t CollisionModel::meshCount() const { return meshes_.size(); }

bool CollisionModel::matches(const CollisionOptions& options) const {
  if (options.meshes.size() != meshes_.size()) return false;
  if (options.continuous && (options.edges || options.corners) &&
      !(featureEdges_ && options.featureAngle == featureAngle_))
    return false;
  for (size_t k = 0; k < meshes_.size(); ++k) {
    const TriangleMesh& mesh = options.meshes[k].mesh;
    const MeshCollider& c = meshes_[k];
    if (static_cast<Index>(mesh.vertices.size()) != c.x.rows() ||
        static_cast<Index>(mesh.triangles.size()) != c.triangles.count())
      return false;
    for (size_t i = 0; i < mesh.vertices.size(); ++i) {
      const Index r = static_cast<Index>(i);
      if (mesh.vertices[i].x != c.x(r, 0) || mesh.vertices[i].y != c.x(r, 1) || mesh.vertices[i].z != c.x(r, 2))
        return false;
    }
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
      const Index r = static_cast<Index>(t);
      if (mesh.triangles[t][0] != c.triangles.a[r] || mesh.triangles[t][1] != c.triangles.b[r] ||
          mesh.triangles[t][2] != c.triangles.c[r])
        return false;
    }
  }
  return true;
}

}  // namespace weft
