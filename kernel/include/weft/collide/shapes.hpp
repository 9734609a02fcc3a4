// weft/collide/shapes.hpp — triangle meshes of simple solids (obstacles, tests, benchmarks)
// and the conversion of a TriangleMesh into the arrays a TriangleBvh is built over.
//
// Design note
// -----------
// makeIcosphere splits each face of an icosahedron into divisions^2 triangles and pushes
// the points onto the sphere: triangles of nearly equal size and shape (unlike a UV
// sphere's polar slivers), 20 d^2 triangles and 10 d^2 + 2 vertices, counter-clockwise
// seen from outside. A point on an edge shared by two faces is computed as the same
// two-term sum from both, so shared vertices coincide exactly and an exact weld
// (cleanMesh with tolerance 0) joins them.
#pragma once

#include "weft/model/model.hpp"
#include "weft/model/triangle_mesh.hpp"

namespace weft {

/// Sphere of `radius` (m, finite, > 0) around `center`; divisions >= 1 (20 divisions^2 triangles).
TriangleMesh makeIcosphere(const Vec3d& center, double radius, Index divisions);

/// The vertices of `mesh` as an (n x 3) array.
template <class S>
Vec3Array<S> meshPositions(const TriangleMesh& mesh);

/// The triangles of `mesh` as index arrays.
Triangles meshTriangles(const TriangleMesh& mesh);

extern template Vec3Array<float> meshPositions(const TriangleMesh&);
extern template Vec3Array<double> meshPositions(const TriangleMesh&);

}  // namespace weft
