// weft/model/triangle_mesh.hpp — an indexed triangle mesh and its cleaning.
//
// Design note
// -----------
// A TriangleMesh is what a mesh file or a program hands to the cloth builder: vertex
// positions (m) and triangles as three vertex indices, counter-clockwise seen from the
// side the normal (b - a) x (c - a) points to. Files rarely come clean: readers duplicate
// vertices (assimp gives every face corner of a 3DS file its own vertex), modellers
// leave zero-area slivers, repeated faces and edges shared by more than two faces.
// cleanMesh turns such input into a mesh the cloth builder can trust and reports what it
// did, count by count, in a MeshReport:
//
//   1. Validation: every coordinate finite and every index in range, or
//      std::invalid_argument naming the vertex / triangle, the field and the value.
//   2. Welding. Two vertices closer than MeshCleanOptions::weldTolerance (Euclidean
//      distance <= tolerance; 0 welds identical positions only) are one vertex, and so,
//      transitively, are chains of them: the groups are the connected components of the
//      "within tolerance" relation, so they do not depend on the order of the input. A
//      group takes the lexicographically smallest (x, y, z) position among its members
//      (an input position, exact, again independent of the input order). Cost O(n log n):
//      identical positions are merged by one sort, then the remaining distinct positions
//      are sorted by a grid cell of size 2 x tolerance and each is compared only with the
//      points of its own and the 26 neighbouring cells. (A cloud of many distinct points
//      all within a few tolerances of each other would make that quadratic; meshes do not
//      have such clouds.)
//   3. Triangles. A triangle is degenerate if two of its corners are one vertex after
//      welding, or if its area is at most kDegenerateRelativeArea x (longest edge)^2 (a
//      height below 2e-12 of its longest edge: collinear corners up to rounding). A
//      triangle with the same three corners as an earlier one, in any order or winding, is
//      a duplicate. Both are dropped; the kept triangles keep their input order and
//      winding.
//   4. Vertices no kept triangle uses are dropped. The output vertices are the remaining
//      groups in the order of their first member in the input (the lowest input index).
//   5. Edges are counted, not repaired: a boundary edge belongs to one kept triangle, a
//      non-manifold edge to more than two (the cloth builder gives such an edge one
//      structural spring and no bend spring).
//
// Counts add up: inputVertices = weldedVertices + unreferencedVertices + outputVertices
// and inputTriangles = degenerateTriangles + duplicateTriangles + outputTriangles.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "weft/core/types.hpp"

namespace weft {

/// Indexed triangle mesh: positions in metres, triangles as three vertex indices.
struct TriangleMesh {
  std::vector<Vec3d> vertices;
  std::vector<std::array<Index, 3>> triangles;
};

struct MeshCleanOptions {
  double weldTolerance = 1e-6;  // m, finite and >= 0; 0 welds identical positions only
};

/// A triangle is degenerate when |(b - a) x (c - a)| <= kDegenerateRelativeArea * L^2,
/// L its longest edge (twice its area against the square of its longest edge).
inline constexpr double kDegenerateRelativeArea = 1e-12;

/// What cleanMesh found and did.
struct MeshReport {
  Index inputVertices = 0;
  Index inputTriangles = 0;
  Index weldedVertices = 0;        // vertices merged into another (within the weld tolerance)
  Index unreferencedVertices = 0;  // welded vertices no kept triangle uses (dropped)
  Index degenerateTriangles = 0;   // dropped: a repeated corner after welding, or area ~ 0
  Index duplicateTriangles = 0;    // dropped: the same three corners as an earlier triangle
  Index nonManifoldEdges = 0;      // edges of more than two kept triangles
  Index boundaryEdges = 0;         // edges of exactly one kept triangle
  Index outputVertices = 0;
  Index outputTriangles = 0;
  // What a mesh file held beside its faces (filled by loadCleanMesh; cleanMesh leaves them 0):
  std::int64_t ignoredPoints = 0;  // point primitives (OBJ p, faces of one corner): not cloth
  std::int64_t ignoredLines = 0;   // line primitives (OBJ l, faces of two corners): not cloth
  std::int64_t emptyFaces = 0;     // faces listed with no corner (PLY)

  /// One line: input and output sizes, then every non-zero count, e.g.
  /// "24 vertices, 8 triangles in; 9 vertices, 8 triangles out; 15 welded vertices; 8 boundary edges".
  std::string summary() const;
};

/// Validates, welds and cleans `raw` as the design note describes; fills *report if it is
/// not null. Throws std::invalid_argument for a bad coordinate, index or option (naming
/// it and its value) and when no triangle is left.
TriangleMesh cleanMesh(const TriangleMesh& raw, const MeshCleanOptions& options = {}, MeshReport* report = nullptr);

}  // namespace weft
