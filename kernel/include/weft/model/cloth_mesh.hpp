// weft/model/cloth_mesh.hpp — a cloth from any triangle mesh.
//
// Design note
// -----------
// addClothMesh turns a (cleaned, see triangle_mesh.hpp) TriangleMesh into particles,
// springs and surface triangles:
//
//   * one particle per vertex, at scale * v + translate, with the lumped mass
//     density * (one third of the area of every triangle around it); the density is
//     arealDensity (kg/m^2) when it is > 0, otherwise totalMass / (total area), so the
//     masses add up to totalMass;
//   * one Structural spring per unique edge, its rest length the edge's length;
//   * for every interior edge (shared by exactly two triangles) one Bend spring between
//     the two vertices opposite it (the "hinge" spring of the original design), rest
//     length their distance, unless they are the same vertex or already joined by an
//     edge or an earlier bend spring. Boundary edges (one triangle) and non-manifold
//     edges (more than two) get none;
//   * the triangles, with the mesh's winding.
//
// The mesh is at rest as given: every rest length is the current distance, so a cloth
// built from any mesh starts with zero spring forces. Springs are emitted in a
// deterministic order: structural springs by edge (min vertex, max vertex), then bend
// springs in the order of their edges. No GridLayout is recorded (the general force
// strategies apply), so the builder need not be empty: particle indices start at the
// builder's current particle count (ClothMeshStats::firstParticle).
//
// Everything is validated before anything is added, so a rejected mesh leaves the
// builder unchanged: std::invalid_argument names the field or the vertex / triangle and
// the value (including a vertex no triangle uses, which would have no mass: clean the
// mesh with cleanMesh first).
#pragma once

#include "weft/model/model_builder.hpp"
#include "weft/model/triangle_mesh.hpp"

namespace weft {

struct ClothMeshSpec {
  double totalMass = 0.5;   // kg, finite and > 0; used when arealDensity == 0
  double arealDensity = 0;  // kg/m^2, finite and >= 0; when > 0 it wins over totalMass
  SpringMaterial structural{800, 0.05};
  bool bendSprings = true;
  SpringMaterial bend{100, 0.01};
  Vec3d translate{0, 0, 0};  // m, added after scaling
  double scale = 1;          // finite and > 0 (e.g. 0.01 for a mesh modelled in cm)
};

struct ClothMeshStats {
  Index particles = 0;
  Index structuralSprings = 0;  // = unique edges
  Index bendSprings = 0;        // <= interior edges
  Index triangles = 0;
  Index firstParticle = 0;  // mesh vertex i is particle firstParticle + i
  double area = 0;          // total area after scaling, m^2
};

/// Adds the cloth described by `mesh` and `spec` to `builder` (see the design note).
template <class S>
ClothMeshStats addClothMesh(ModelBuilder<S>& builder, const TriangleMesh& mesh, const ClothMeshSpec& spec = {});

}  // namespace weft
