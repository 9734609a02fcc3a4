// weft/rigid/convex_hull.hpp — convex polyhedra: the shape rigid bodies collide with.
//
// Design note
// -----------
// A ConvexHull is a closed convex polyhedron in its own (shape) frame, stored as the
// narrow phase wants it: vertices, polygonal faces (coplanar triangles merged, so a box
// has 6 faces, not 12) with their outward unit normal and plane offset, and the unique
// edges with the two faces that meet there. Faces list their vertices counter-clockwise
// seen from outside (right-hand rule around the normal). Edge directions are what the
// separating-axis test crosses; face normals are the face axes.
//
// makeConvexHull runs quickhull (Barber, Dobkin, Huhdanpaa 1996): an initial simplex from
// the extreme points, then each face's furthest outside point is added, the faces it sees
// removed and the horizon coned to it. Points within `tolerance` of a face are inside.
// Adjacent faces whose normals agree within the tolerance are merged into one polygon.
// Build time only: it allocates and throws std::invalid_argument for fewer than four
// non-coplanar points or non-finite coordinates, naming the point.
#pragma once

#include <Eigen/Core>
#include <span>
#include <string>
#include <vector>

namespace weft {

/// One polygonal face: normal . x == offset for every x on the face, normal . x < offset
/// inside. Its vertices are faceVertices[first, first + count), counter-clockwise about normal.
struct ConvexFace {
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // outward unit normal
  double offset = 0;                                 // m
  int first = 0;
  int count = 0;
};

/// One edge between vertices v0 and v1, shared by faces face0 (whose loop runs v0 -> v1)
/// and face1.
struct ConvexEdge {
  int v0 = 0, v1 = 0;
  int face0 = 0, face1 = 0;
};

struct ConvexHull {
  std::vector<Eigen::Vector3d> vertices;  // shape frame, m
  std::vector<ConvexFace> faces;
  std::vector<int> faceVertices;  // concatenated polygons, see ConvexFace::first
  std::vector<ConvexEdge> edges;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // mean of the vertices, m
  double boundingRadius = 0;                           // max |vertex - centroid|, m

  int vertexCount() const { return static_cast<int>(vertices.size()); }
  int faceCount() const { return static_cast<int>(faces.size()); }
  int edgeCount() const { return static_cast<int>(edges.size()); }
  /// Index of a vertex furthest along `direction` (the first in index order on ties).
  int support(const Eigen::Vector3d& direction) const;
  /// The vertex positions of face f, in order.
  std::span<const int> faceIndices(int f) const {
    return {faceVertices.data() + faces[f].first, static_cast<std::size_t>(faces[f].count)};
  }
};

/// Convex hull of `points` (quickhull; visibility decided exactly with Shewchuk's orient3d,
/// so every intermediate hull is convex). Hull vertices keep the input order; every input
/// point ends within about 1.5 x tolerance of the faces. Throws std::invalid_argument for fewer than four
/// points, non-finite coordinates or coordinates beyond +-1e50 m, an extent below 1e-50 m, or
/// points that span no volume (all within tolerance of a plane). tolerance <= 0: a relative
/// default (1e-9 x the points' extent).
ConvexHull makeConvexHull(std::span<const Eigen::Vector3d> points, double tolerance = 0);

/// A box centred at the origin with the given half extents (each finite and > 0): 8
/// vertices, 6 faces, 12 edges.
ConvexHull makeBoxHull(const Eigen::Vector3d& halfExtents);

/// `tolerance` is relative to the larger of the hull's extent and its largest coordinate.
/// Checks the invariants (closed, Euler characteristic V - E + F = 2, unit normals, every
/// vertex on or below every face plane within tolerance, counter-clockwise faces); returns
/// an empty string when they hold, else what failed. For tests and for hulls built by hand.
std::string checkConvexHull(const ConvexHull& hull, double tolerance = 1e-9);

}  // namespace weft
