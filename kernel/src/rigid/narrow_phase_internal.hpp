// Part of narrow_phase.cpp (included by it alone, not installed): what the three narrow
// phases share — constants, the relative pose, feature ids, the separating-axis test's
// per-axis queries and its result. narrow_phase.cpp is one translation unit made of
// narrow_phase_internal.hpp, sat_query.hpp (the exact test), contact_manifold.hpp
// (clipping and point reduction) and the methods themselves: split into files by
// responsibility, compiled as one so that the compiler inlines and fuses multiply-adds
// exactly as it did when they were one file (compiled as separate units, the pile's
// results changed in the last bits). Frames and the algorithm: the design note at the top
// of narrow_phase.cpp.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "weft/rigid/narrow_phase.hpp"

namespace weft {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kMaxPolygon = 128;           // vertices kept of a reference or incident polygon
constexpr int kMaxClip = 2 * kMaxPolygon;  // clipping a convex n-gon by m planes leaves <= n + m vertices
constexpr double kParallelSine = 1e-5;     // edge pairs with |ea x eb| < this |ea| |eb| are skipped
// Feature preference (Gregorius' and Box2D's tolerances, made symmetric in sign so that
// they also behave for speculative, positive separations): an edge axis replaces the best
// face axis only if it is better by kEdgeRelTolerance |F| + kAbsTolerance, a face of B
// replaces A's only if better by kFaceRelTolerance |fa| + kAbsTolerance. This keeps the
// manifold (and its feature ids) from flickering between near-equal axes.
// (A fixed 1 mm: RigidOptions::linearSlop, 5 mm by default, is the solver's and does not
// reach the narrow phase.)
constexpr double kLinearSlop = 0.001;  // m
constexpr double kAbsTolerance = 0.5 * kLinearSlop;
constexpr double kEdgeRelTolerance = 0.05;
constexpr double kFaceRelTolerance = 0.02;

// ---------------------------------------------------------------------------------------
// Small helpers

/// B's placement in A's frame: x_A = rotation x_B + position.
struct Relative {
  Matrix3d rotation;
  Vector3d position;
};

Relative relativePose(const Pose& a, const Pose& b) {
  return {a.rotation.transpose() * b.rotation, a.rotation.transpose() * (b.position - a.position)};
}

Relative inversePose(const Relative& r) { return {r.rotation.transpose(), -(r.rotation.transpose() * r.position)}; }

std::uint32_t mixId(std::uint32_t h, std::uint32_t v) {
  // boost::hash_combine followed by murmur3's finaliser: cheap, deterministic, well spread.
  h ^= v + 0x9e3779b9u + (h << 6) + (h >> 2);
  h ^= h >> 16;
  h *= 0x85ebca6bu;
  h ^= h >> 13;
  h *= 0xc2b2ae35u;
  h ^= h >> 16;
  return h;
}

constexpr std::uint32_t kTagFace = 0x46u, kTagFlip = 0x2fu, kTagEdge = 0x45u, kTagVertex = 0x56u, kTagClip = 0x43u,
                        kTagSupport = 0x53u, kTagSphere = 0x50u;

std::uint32_t u32(int i) { return static_cast<std::uint32_t>(i); }

/// Smallest d . v over the vertices of `hull` (its support in -d), and which vertex.
double minDot(const ConvexHull& hull, const Vector3d& d, int* index = nullptr) {
  double best = kInf;
  int bestIndex = 0;
  const int n = hull.vertexCount();
  for (int v = 0; v < n; ++v) {
    const double x = d.dot(hull.vertices[static_cast<std::size_t>(v)]);
    if (x < best) {
      best = x;
      bestIndex = v;
    }
  }
  if (index) *index = bestIndex;
  return best;
}

/// Separation along face i of A: B's deepest vertex below the face plane (A's frame).
double faceSeparationA(const ConvexHull& a, const ConvexHull& b, const Relative& rel, int i) {
  const ConvexFace& f = a.faces[static_cast<std::size_t>(i)];
  return minDot(b, rel.rotation.transpose() * f.normal) + f.normal.dot(rel.position) - f.offset;
}

/// Separation along face j of B: A's deepest vertex below that face's plane (B's frame):
/// min_a n . R^T (a - p) - offset = min_a (R n) . a - (R n) . p - offset.
double faceSeparationB(const ConvexHull& a, const ConvexHull& b, const Relative& rel, int j) {
  const ConvexFace& f = b.faces[static_cast<std::size_t>(j)];
  const Vector3d m = rel.rotation * f.normal;
  return minDot(a, m) - m.dot(rel.position) - f.offset;
}

/// An edge in A's frame with its arc on the Gauss map: u and v are the two face normals
/// the arc joins (for B: negated, the Gauss map of -B), vxu = v x u the arc's plane normal.
struct EdgeFrame {
  Vector3d p, e, u, v, vxu;
};

EdgeFrame edgeOfA(const ConvexHull& a, int i) {
  const ConvexEdge& edge = a.edges[static_cast<std::size_t>(i)];
  EdgeFrame f;
  f.p = a.vertices[static_cast<std::size_t>(edge.v0)];
  f.e = a.vertices[static_cast<std::size_t>(edge.v1)] - f.p;
  f.u = a.faces[static_cast<std::size_t>(edge.face0)].normal;
  f.v = a.faces[static_cast<std::size_t>(edge.face1)].normal;
  f.vxu = f.v.cross(f.u);
  return f;
}

EdgeFrame edgeOfB(const ConvexHull& b, const Relative& rel, int j) {
  const ConvexEdge& edge = b.edges[static_cast<std::size_t>(j)];
  EdgeFrame f;
  f.p = rel.rotation * b.vertices[static_cast<std::size_t>(edge.v0)] + rel.position;
  f.e = rel.rotation * b.vertices[static_cast<std::size_t>(edge.v1)] + rel.position - f.p;
  f.u = -(rel.rotation * b.faces[static_cast<std::size_t>(edge.face0)].normal);
  f.v = -(rel.rotation * b.faces[static_cast<std::size_t>(edge.face1)].normal);
  f.vxu = f.v.cross(f.u);
  return f;
}

enum class EdgePairKind { NotMinkowskiFace, Parallel, MinkowskiFace };

/// Gregorius' edge query for one pair. The arcs AB (of A's edge) and CD (of B's, negated)
/// cross iff C and D lie on opposite sides of AB's plane, A and B on opposite sides of
/// CD's plane, and the two arcs lie in the same hemisphere (C . (B x A) and B . (D x C)
/// of one sign). Then the edges are the supports of A and B along their cross product, and
/// the separation is the distance between the two edge lines along it.
EdgePairKind edgePairSeparation(const EdgeFrame& ea, const EdgeFrame& eb, const Vector3d& centroidA, double& separation,
                                Vector3d& axis, double& sliverWidth) {
  const double cba = eb.u.dot(ea.vxu);
  const double dba = eb.v.dot(ea.vxu);
  if (!(cba * dba < 0)) return EdgePairKind::NotMinkowskiFace;
  const double adc = ea.u.dot(eb.vxu);
  const double bdc = ea.v.dot(eb.vxu);
  if (!(adc * bdc < 0 && cba * bdc > 0)) return EdgePairKind::NotMinkowskiFace;
  const Vector3d c = ea.e.cross(eb.e);
  const double length2 = c.squaredNorm(), la2 = ea.e.squaredNorm(), lb2 = eb.e.squaredNorm();
  if (!(length2 > kParallelSine * kParallelSine * la2 * lb2)) {
    sliverWidth = std::sqrt(length2 / std::max({la2, lb2, 1e-300}));  // |ea x eb| / longer edge
    return EdgePairKind::Parallel;
  }
  axis = c / std::sqrt(length2);
  if (axis.dot(ea.p - centroidA) < 0) axis = -axis;
  separation = axis.dot(eb.p - ea.p);
  return EdgePairKind::MinkowskiFace;
}

struct FaceQuery {
  double best = -kInf;
  double second = -kInf;  // runner-up among the same hull's faces
  int index = -1;
  void add(double s, int i) {
    if (s > best) {
      second = best;
      best = s;
      index = i;
    } else if (s > second) {
      second = s;
    }
  }
};

struct SatResult {
  FaceQuery faceA, faceB;
  double edgeBest = -kInf;
  int edgeA = -1, edgeB = -1;
  Vector3d edgeAxis = Vector3d::UnitY();  // A's frame, from A to B
  double sliverWidth = 0;                 // widest skipped near-parallel Minkowski face, m
  bool complete = true;                   // false: stopped early (an axis separates by > stopAbove)
  double best() const { return std::max({faceA.best, faceB.best, edgeBest}); }
};

enum class Reference { None, FaceA, FaceB, Edge };

void clearManifold(ContactManifold& out) { out.pointCount = 0; }

}  // namespace
}  // namespace weft
