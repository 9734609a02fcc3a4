// weft/rigid/convex_hull.cpp — what every hull shares (edges, centroid, bounding radius),
// the support query, box hulls and the hull invariant check (quickhull: quickhull.cpp).
//
// Conventions of every hull built here (checkConvexHull verifies the first ones):
//  * faces are convex polygons, vertices counter-clockwise about the outward normal;
//  * each edge is listed once; face0 is the face whose counter-clockwise loop runs
//    v0 -> v1, face1 the face whose loop runs v1 -> v0;
//  * edges are listed in order of first appearance when walking the faces in order.
#include "weft/rigid/convex_hull.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/text.hpp"
#include "hull_internal.hpp"

namespace weft {

using Eigen::Vector3d;

using detail::number;

/// Fills edges (see the conventions above), centroid and boundingRadius from vertices,
/// faces and faceVertices. Throws std::logic_error when a directed edge appears twice or an
/// edge has only one face (the callers build closed manifolds, so that is a bug here).
void rigid_detail::finishHull(ConvexHull& hull) {
  hull.edges.clear();
  std::map<std::pair<int, int>, int> edgeOf;  // (min, max) vertex -> edge index
  for (int f = 0; f < hull.faceCount(); ++f) {
    const std::span<const int> idx = hull.faceIndices(f);
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const int a = idx[k], b = idx[(k + 1) % idx.size()];
      const auto key = std::minmax(a, b);
      const auto it = edgeOf.find(key);
      if (it == edgeOf.end()) {
        edgeOf.emplace(key, hull.edgeCount());
        ConvexEdge e;
        e.v0 = a;
        e.v1 = b;
        e.face0 = f;
        e.face1 = -1;
        hull.edges.push_back(e);
      } else {
        ConvexEdge& e = hull.edges[static_cast<std::size_t>(it->second)];
        if (e.face1 != -1 || e.v0 != b) throw std::logic_error("convex hull: non-manifold edge");
        e.face1 = f;
      }
    }
  }
  for (const ConvexEdge& e : hull.edges)
    if (e.face1 < 0) throw std::logic_error("convex hull: open edge");

  hull.centroid.setZero();
  for (const Vector3d& v : hull.vertices) hull.centroid += v;
  if (!hull.vertices.empty()) hull.centroid /= static_cast<double>(hull.vertices.size());
  hull.boundingRadius = 0;
  for (const Vector3d& v : hull.vertices)
    hull.boundingRadius = std::max(hull.boundingRadius, (v - hull.centroid).norm());
}

int ConvexHull::support(const Vector3d& direction) const {
  int best = 0;
  double bestDot = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < vertexCount(); ++i) {
    const double d = vertices[static_cast<std::size_t>(i)].dot(direction);
    if (d > bestDot) {  // strict: the first index wins ties
      bestDot = d;
      best = i;
    }
  }
  return best;
}

ConvexHull makeBoxHull(const Vector3d& halfExtents) {
  static const char* const kAxis[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    const double h = halfExtents[k];
    if (!std::isfinite(h) || !(h > 0))
      throw std::invalid_argument(std::string("makeBoxHull: halfExtents.") + kAxis[k] +
                                  " must be finite and > 0, got " + number(h));
  }
  ConvexHull hull;
  // Vertex i has x = +hx when bit 0 is set, y = +hy for bit 1, z = +hz for bit 2.
  for (int i = 0; i < 8; ++i)
    hull.vertices.emplace_back((i & 1) ? halfExtents.x() : -halfExtents.x(),
                               (i & 2) ? halfExtents.y() : -halfExtents.y(),
                               (i & 4) ? halfExtents.z() : -halfExtents.z());
  struct Quad {
    int axis;
    double sign;
    int v[4];
  };
  static const Quad kQuads[6] = {
      {0, +1, {1, 3, 7, 5}}, {0, -1, {0, 4, 6, 2}}, {1, +1, {2, 6, 7, 3}},
      {1, -1, {0, 1, 5, 4}}, {2, +1, {4, 5, 7, 6}}, {2, -1, {0, 2, 3, 1}},
  };
  for (const Quad& q : kQuads) {
    ConvexFace f;
    f.normal = Vector3d::Zero();
    f.normal[q.axis] = q.sign;
    f.offset = halfExtents[q.axis];
    f.first = static_cast<int>(hull.faceVertices.size());
    f.count = 4;
    hull.faceVertices.insert(hull.faceVertices.end(), q.v, q.v + 4);
    hull.faces.push_back(f);
  }
  rigid_detail::finishHull(hull);
  return hull;
}

// Lengths are compared with tolerance x scale, scale the larger of the hull's bounding-box
// extent and its largest coordinate magnitude: the same basis as makeConvexHull's default
// tolerance (1e-9 x extent), so its hulls pass the default check (their merged faces are
// flat and convex to within that tolerance, exact triangles otherwise). Quadratic in size
// (every vertex against every plane): for tests and build time.
std::string checkConvexHull(const ConvexHull& hull, double tolerance) {
  std::ostringstream msg;
  const int vCount = hull.vertexCount(), fCount = hull.faceCount(), eCount = hull.edgeCount();
  if (vCount < 4 || fCount < 4 || eCount < 6) {
    msg << "too few elements: V=" << vCount << " E=" << eCount << " F=" << fCount;
    return msg.str();
  }
  if (vCount - eCount + fCount != 2) {
    msg << "Euler characteristic V - E + F = " << vCount << " - " << eCount << " + " << fCount << " != 2";
    return msg.str();
  }
  // Lengths are relative to the hull's size (its bounding-box extent), or to its distance
  // from the origin when that is larger (rounding grows with the coordinates).
  Vector3d lo = hull.vertices[0], hi = hull.vertices[0];
  double scale = 0;
  for (const Vector3d& v : hull.vertices) {
    if (!v.allFinite()) return "a vertex has a non-finite coordinate";
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
    scale = std::max(scale, v.cwiseAbs().maxCoeff());
  }
  scale = std::max(scale, (hi - lo).maxCoeff());
  const double tol = tolerance * scale;

  // Faces: index ranges, vertex indices, unit normals, planarity, orientation, convexity.
  for (int f = 0; f < fCount; ++f) {
    const ConvexFace& face = hull.faces[static_cast<std::size_t>(f)];
    if (face.count < 3 || face.first < 0 ||
        static_cast<std::size_t>(face.first) + static_cast<std::size_t>(face.count) > hull.faceVertices.size()) {
      msg << "face " << f << " has a bad vertex range [" << face.first << ", " << face.first + face.count << ")";
      return msg.str();
    }
    if (std::abs(face.normal.norm() - 1) > 1e-9 || !face.normal.allFinite()) {
      msg << "face " << f << " normal is not unit (|n| = " << face.normal.norm() << ")";
      return msg.str();
    }
    const std::span<const int> idx = hull.faceIndices(f);
    for (const int v : idx)
      if (v < 0 || v >= vCount) {
        msg << "face " << f << " has vertex index " << v << " out of range";
        return msg.str();
      }
    Vector3d area = Vector3d::Zero();  // twice the area vector, about the first vertex
    const Vector3d& origin = hull.vertices[static_cast<std::size_t>(idx[0])];
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const Vector3d& p = hull.vertices[static_cast<std::size_t>(idx[k])];
      const double d = face.normal.dot(p) - face.offset;
      if (std::abs(d) > tol) {
        msg << "vertex " << idx[k] << " of face " << f << " is off its plane by " << d;
        return msg.str();
      }
      area += (p - origin).cross(hull.vertices[static_cast<std::size_t>(idx[(k + 1) % idx.size()])] - origin);
    }
    // A sliver (a triangle thinner than the tolerance, possible when the input is noisy at
    // the tolerance) can have a rounded area of zero: only a clear clockwise turn fails.
    double perimeter = 0;
    for (std::size_t k = 0; k < idx.size(); ++k)
      perimeter += (hull.vertices[static_cast<std::size_t>(idx[(k + 1) % idx.size()])] -
                    hull.vertices[static_cast<std::size_t>(idx[k])])
                       .norm();
    if (!(face.normal.dot(area) > -tol * perimeter)) {
      msg << "face " << f << " is not counter-clockwise about its normal (n . area = " << face.normal.dot(area) << ")";
      return msg.str();
    }
    // Convex polygon: no corner is reflex by more than tol (its height over the chord
    // between its neighbours, which stays meaningful when one side is very short).
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const Vector3d& a = hull.vertices[static_cast<std::size_t>(idx[k])];
      const Vector3d& b = hull.vertices[static_cast<std::size_t>(idx[(k + 1) % idx.size()])];
      const Vector3d& c = hull.vertices[static_cast<std::size_t>(idx[(k + 2) % idx.size()])];
      const double height = face.normal.dot((b - a).cross(c - a)) / (c - a).norm();  // of b over the chord a c
      if (height < -tol) {
        msg << "face " << f << " is not convex at vertex " << idx[(k + 1) % idx.size()] << " (reflex by " << -height
            << ")";
        return msg.str();
      }
    }
  }

  // Edges: indices in range, each shared by exactly its two faces, each face loop made of
  // listed edges only (so every edge of every face is listed exactly once).
  std::map<std::pair<int, int>, int> edgeOf;
  for (int e = 0; e < eCount; ++e) {
    const ConvexEdge& edge = hull.edges[static_cast<std::size_t>(e)];
    if (edge.v0 < 0 || edge.v0 >= vCount || edge.v1 < 0 || edge.v1 >= vCount || edge.v0 == edge.v1 || edge.face0 < 0 ||
        edge.face0 >= fCount || edge.face1 < 0 || edge.face1 >= fCount || edge.face0 == edge.face1) {
      msg << "edge " << e << " has a bad vertex or face index";
      return msg.str();
    }
    if (!edgeOf.emplace(std::minmax(edge.v0, edge.v1), e).second) {
      msg << "edge " << e << " (" << edge.v0 << ", " << edge.v1 << ") is listed twice";
      return msg.str();
    }
  }
  std::vector<int> seen(static_cast<std::size_t>(eCount), 0);
  for (int f = 0; f < fCount; ++f) {
    const std::span<const int> idx = hull.faceIndices(f);
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const int a = idx[k], b = idx[(k + 1) % idx.size()];
      const auto it = edgeOf.find(std::minmax(a, b));
      if (it == edgeOf.end()) {
        msg << "face " << f << " side (" << a << ", " << b << ") is not a listed edge";
        return msg.str();
      }
      const ConvexEdge& edge = hull.edges[static_cast<std::size_t>(it->second)];
      if (edge.face0 != f && edge.face1 != f) {
        msg << "edge " << it->second << " does not name face " << f << " that uses it";
        return msg.str();
      }
      ++seen[static_cast<std::size_t>(it->second)];
    }
  }
  for (int e = 0; e < eCount; ++e)
    if (seen[static_cast<std::size_t>(e)] != 2) {
      msg << "edge " << e << " is used by " << seen[static_cast<std::size_t>(e)] << " face sides, not 2";
      return msg.str();
    }

  // Every vertex on or below every face plane.
  for (int f = 0; f < fCount; ++f) {
    const ConvexFace& face = hull.faces[static_cast<std::size_t>(f)];
    for (int v = 0; v < vCount; ++v) {
      const double d = face.normal.dot(hull.vertices[static_cast<std::size_t>(v)]) - face.offset;
      if (d > tol) {
        msg << "vertex " << v << " is above face " << f << " by " << d;
        return msg.str();
      }
    }
  }
  return "";
}

}  // namespace weft
