// weft/rigid/narrow_phase.cpp — contact manifolds between convex hulls: the exact
// separating-axis test, the Opposing Face Geometry heuristic and the separating-plane
// witness (see the design note in narrow_phase.hpp).
//
// Frames. A query works in A's shape frame: B is placed there by the relative pose
// x_A = R x_B + p (R = RA^T RB, p = RA^T (pB - pA)), so A's faces and edges are used as
// stored and only B's features are rotated. A manifold whose reference face is B's is
// built in B's frame (the inverse relative pose) and its normal flipped at the end.
//
// The separating-axis test (Gregorius, GDC 2013). The candidate axes are the face
// normals of A, those of B, and for each edge pair that builds a face of the Minkowski
// difference M = B - A (their arcs on the Gauss map cross: A's arc between its two face
// normals, B's arc between its two negated face normals) the cross product of the two
// edges, oriented away from A's centroid. Together these are the face normals of M, so
// the largest separation along them is the exact SAT answer: the distance when the
// closest features are face-vertex or edge-edge, a lower bound of it otherwise, minus the
// penetration depth when the hulls overlap. Edge pairs closer to parallel than
// kParallelSine are skipped (their Minkowski face is a sliver of width below
// kParallelSine x the shorter edge, and its normal is ill-conditioned).
//
// No function here allocates or throws: polygons are clipped in fixed stack arrays
// (kMaxPolygon vertices a polygon; larger faces are subsampled, which keeps a convex
// polygon inside the face), the OFG keeps at most kMaxOfgFaces faces a side, and every
// loop runs in index order, so the result is deterministic.
#include "weft/rigid/narrow_phase.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>

namespace weft {

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kMaxPolygon = 128;           // vertices kept of a reference or incident polygon
constexpr int kMaxClip = 2 * kMaxPolygon;  // clipping a convex n-gon by m planes leaves <= n + m vertices
constexpr int kMaxOfgFaces = 64;           // OFG: k is clamped to this
constexpr double kParallelSine = 1e-5;     // edge pairs with |ea x eb| < this |ea| |eb| are skipped
// Feature preference (Gregorius' and Box2D's tolerances, made symmetric in sign so that
// they also behave for speculative, positive separations): an edge axis replaces the best
// face axis only if it is better by kEdgeRelTolerance |F| + kAbsTolerance, a face of B
// replaces A's only if better by kFaceRelTolerance |fa| + kAbsTolerance. This keeps the
// manifold (and its feature ids) from flickering between near-equal axes.
constexpr double kLinearSlop = 0.001;  // m, RigidOptions::linearSlop's default
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

/// The exact SAT. Stops as soon as an axis separates by more than stopAbove (after the
/// face queries of A, those of B, or at that edge pair).
SatResult satQuery(const ConvexHull& a, const ConvexHull& b, const Relative& rel, double stopAbove) {
  SatResult r;
  for (int i = 0; i < a.faceCount(); ++i) r.faceA.add(faceSeparationA(a, b, rel, i), i);
  if (r.faceA.best > stopAbove) {
    r.complete = false;
    return r;
  }
  for (int j = 0; j < b.faceCount(); ++j) r.faceB.add(faceSeparationB(a, b, rel, j), j);
  if (r.faceB.best > stopAbove) {
    r.complete = false;
    return r;
  }
  // B's edge outside (rotated once), A's edges inside: no buffer of transformed edges.
  for (int j = 0; j < b.edgeCount(); ++j) {
    const EdgeFrame eb = edgeOfB(b, rel, j);
    for (int i = 0; i < a.edgeCount(); ++i) {
      // Most pairs fail the first arc test: make it from the two normals alone.
      const ConvexEdge& edge = a.edges[static_cast<std::size_t>(i)];
      const Vector3d vxu = a.faces[static_cast<std::size_t>(edge.face1)].normal.cross(
          a.faces[static_cast<std::size_t>(edge.face0)].normal);
      if (!(eb.u.dot(vxu) * eb.v.dot(vxu) < 0)) continue;
      const EdgeFrame ea = edgeOfA(a, i);
      double s = 0, width = 0;
      Vector3d axis;
      switch (edgePairSeparation(ea, eb, a.centroid, s, axis, width)) {
        case EdgePairKind::MinkowskiFace:
          if (s > r.edgeBest) {
            r.edgeBest = s;
            r.edgeA = i;
            r.edgeB = j;
            r.edgeAxis = axis;
            if (s > stopAbove) {
              r.complete = false;
              return r;
            }
          }
          break;
        case EdgePairKind::Parallel:
          r.sliverWidth = std::max(r.sliverWidth, width);
          break;
        case EdgePairKind::NotMinkowskiFace:
          break;
      }
    }
  }
  return r;
}

enum class Reference { None, FaceA, FaceB, Edge };

/// The feature that builds the manifold (see the preference tolerances above).
Reference chooseReference(const SatResult& r) {
  const double fa = r.faceA.best, fb = r.faceB.best;
  if (r.faceA.index < 0 && r.faceB.index < 0) return r.edgeA >= 0 ? Reference::Edge : Reference::None;
  const double f = std::max(fa, fb);
  if (r.edgeA >= 0 && r.edgeBest > f + kEdgeRelTolerance * std::abs(f) + kAbsTolerance) return Reference::Edge;
  if (r.faceA.index < 0) return Reference::FaceB;
  if (r.faceB.index >= 0 && fb > fa + kFaceRelTolerance * std::abs(fa) + kAbsTolerance) return Reference::FaceB;
  return Reference::FaceA;
}

// ---------------------------------------------------------------------------------------
// Manifold building

struct ClipVertex {
  Vector3d x;
  std::uint32_t id;
};

/// Polygon of face f (hull frame), at most kMaxPolygon vertices: a larger face is subsampled
/// evenly (the subset is a convex polygon inside the face, in the same order).
int facePolygon(const ConvexHull& hull, int f, int* vertexIndices) {
  const std::span<const int> idx = hull.faceIndices(f);
  const int n = static_cast<int>(idx.size());
  if (n <= kMaxPolygon) {
    for (int k = 0; k < n; ++k) vertexIndices[k] = idx[static_cast<std::size_t>(k)];
    return n;
  }
  for (int k = 0; k < kMaxPolygon; ++k) {
    vertexIndices[k] = idx[static_cast<std::size_t>(static_cast<long long>(k) * n / kMaxPolygon)];
  }
  return kMaxPolygon;
}

/// Keeps the side of the plane s . x <= offset (Sutherland-Hodgman, one plane). A new
/// vertex's id is made of its edge's two ids and the plane: the same while the topology is.
int clipPolygon(const ClipVertex* in, int n, const Vector3d& s, double offset, std::uint32_t planeId, ClipVertex* out) {
  int m = 0;
  for (int k = 0; k < n; ++k) {
    const ClipVertex& p = in[k];
    const ClipVertex& q = in[(k + 1) % n];
    const double dp = s.dot(p.x) - offset, dq = s.dot(q.x) - offset;
    if (dp <= 0 && m < kMaxClip) out[m++] = p;
    if ((dp <= 0) != (dq <= 0) && m < kMaxClip) {
      const double t = dp / (dp - dq);
      out[m++] = {p.x + t * (q.x - p.x), mixId(mixId(mixId(kTagClip, p.id), q.id), planeId)};
    }
  }
  return m;
}

constexpr double kDepthTolerance = 0.1 * kLinearSlop;  // m: depths this close count as equal when reducing

/// Picks at most four of the candidates: the deepest, the farthest from it, the one making
/// the largest triangle with those two, and the one adding the most area to that triangle
/// (normal n fixes the orientation). Writes the chosen indices, returns how many.
int reducePoints(const ClipVertex* c, const double* sep, int n, const Vector3d& normal, int* chosen) {
  if (n <= 4) {
    for (int k = 0; k < n; ++k) chosen[k] = k;
    return n;
  }
  // The deepest, up to kDepthTolerance: the first in clip order among the points that deep,
  // so that a flat contact (equal depths) keeps the same four points under small motions.
  double deepest = sep[0];
  for (int k = 1; k < n; ++k) deepest = std::min(deepest, sep[k]);
  int i0 = 0;
  while (sep[i0] > deepest + kDepthTolerance) ++i0;
  int i1 = -1;
  double far = -1;
  for (int k = 0; k < n; ++k) {
    const double d = (c[k].x - c[i0].x).squaredNorm();
    if (k != i0 && d > far) {
      far = d;
      i1 = k;
    }
  }
  const auto area = [&](int p, int q, int r) { return normal.dot((c[q].x - c[p].x).cross(c[r].x - c[p].x)); };
  int i2 = -1;
  double best = -1;
  for (int k = 0; k < n; ++k) {
    const double aAbs = std::abs(area(i0, i1, k));
    if (k != i0 && k != i1 && aAbs > best) {
      best = aAbs;
      i2 = k;
    }
  }
  const double orientation = area(i0, i1, i2) >= 0 ? 1.0 : -1.0;
  int i3 = -1;
  best = 0;
  for (int k = 0; k < n; ++k) {
    if (k == i0 || k == i1 || k == i2) continue;
    // Area outside the triangle (i0, i1, i2) that k adds: the most negative edge area.
    const double extra =
        -std::min({orientation * area(i0, i1, k), orientation * area(i1, i2, k), orientation * area(i2, i0, k)});
    if (extra > best) {
      best = extra;
      i3 = k;
    }
  }
  chosen[0] = i0;
  chosen[1] = i1;
  chosen[2] = i2;
  if (i3 < 0) return 3;
  chosen[3] = i3;
  return 4;
}

/// Manifold from reference face `refFace` of `ref` against `inc`, placed in ref's frame by
/// relInc. The incident face is the face of inc (among incCandidates if given) most
/// anti-parallel to the reference normal. The normal reported is the reference normal,
/// negated when flip (the reference hull is B). Returns false when no clipped point lay
/// within the margin and the deepest vertex of inc was used instead.
bool faceContact(const ConvexHull& ref, const ConvexHull& inc, const Relative& relInc, int refFace,
                 const int* incCandidates, int incCandidateCount, double margin, const Pose& refPose, bool flip,
                 ContactManifold& out) {
  const ConvexFace& rf = ref.faces[static_cast<std::size_t>(refFace)];
  const Vector3d n = rf.normal;
  const Vector3d nInc = relInc.rotation.transpose() * n;  // the reference normal in inc's frame
  int incFace = -1;
  double most = kInf;
  const int candidates = incCandidates ? incCandidateCount : inc.faceCount();
  for (int k = 0; k < candidates; ++k) {
    const int f = incCandidates ? incCandidates[k] : k;
    const double d = inc.faces[static_cast<std::size_t>(f)].normal.dot(nInc);
    if (d < most) {
      most = d;
      incFace = f;
    }
  }
  const std::uint32_t baseId =
      mixId(mixId(mixId(kTagFace, flip ? kTagFlip : 0u), u32(refFace)), incFace < 0 ? 0u : u32(incFace));
  const Vector3d worldNormal = flip ? Vector3d(-(refPose.rotation * n)) : Vector3d(refPose.rotation * n);
  out.normal = worldNormal;
  out.pointCount = 0;

  std::array<ClipVertex, kMaxClip> bufferA, bufferB;
  std::array<int, kMaxPolygon> indices;
  int count = 0;
  if (incFace >= 0) {
    count = facePolygon(inc, incFace, indices.data());
    for (int k = 0; k < count; ++k) {
      const int v = indices[static_cast<std::size_t>(k)];
      bufferA[static_cast<std::size_t>(k)] = {
          relInc.rotation * inc.vertices[static_cast<std::size_t>(v)] + relInc.position, mixId(kTagVertex, u32(v))};
    }
  }
  std::array<int, kMaxPolygon> refIndices;
  const int refCount = facePolygon(ref, refFace, refIndices.data());
  ClipVertex* cur = bufferA.data();
  ClipVertex* next = bufferB.data();
  for (int k = 0; k < refCount && count > 0; ++k) {
    const Vector3d& v0 = ref.vertices[static_cast<std::size_t>(refIndices[static_cast<std::size_t>(k)])];
    const Vector3d& v1 =
        ref.vertices[static_cast<std::size_t>(refIndices[static_cast<std::size_t>((k + 1) % refCount)])];
    const Vector3d side = (v1 - v0).cross(n);  // outward: the polygon is counter-clockwise about n
    count = clipPolygon(cur, count, side, side.dot(v0), u32(refIndices[static_cast<std::size_t>(k)]), next);
    std::swap(cur, next);
  }
  // Keep the points within the margin (compacted in place, in order).
  std::array<double, kMaxClip> sep;
  int kept = 0;
  for (int k = 0; k < count; ++k) {
    const double s = n.dot(cur[k].x) - rf.offset;
    if (s <= margin) {
      cur[kept] = cur[k];
      sep[static_cast<std::size_t>(kept)] = s;
      ++kept;
    }
  }
  const auto emit = [&](const Vector3d& x, double s, std::uint32_t id) {
    ContactPoint& p = out.points[static_cast<std::size_t>(out.pointCount++)];
    p.position = refPose.rotation * (x - 0.5 * s * n) + refPose.position;  // midway to the reference plane
    p.separation = s;
    p.featureId = mixId(baseId, id);
  };
  if (kept > 0) {
    std::array<int, 4> chosen;
    const int m = reducePoints(cur, sep.data(), kept, n, chosen.data());
    for (int k = 0; k < m; ++k) {
      const int c = chosen[static_cast<std::size_t>(k)];
      emit(cur[c].x, sep[static_cast<std::size_t>(c)], cur[c].id);
    }
    return true;
  }
  // Nothing of the incident face inside the reference face's prism within the margin (a
  // glancing configuration): report the deepest vertex of inc so a contact is not lost.
  int v = 0;
  minDot(inc, nInc, &v);
  if (inc.vertexCount() == 0) return false;
  const Vector3d x = relInc.rotation * inc.vertices[static_cast<std::size_t>(v)] + relInc.position;
  const double s = n.dot(x) - rf.offset;
  if (s <= margin) emit(x, s, mixId(kTagSupport, u32(v)));
  return false;
}

/// Closest points of segments p1 + s d1 and p2 + t d2, s, t in [0, 1] (Ericson 5.1.9).
void closestSegmentPoints(const Vector3d& p1, const Vector3d& q1, const Vector3d& p2, const Vector3d& q2, Vector3d& c1,
                          Vector3d& c2) {
  const Vector3d d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  constexpr double tiny = 1e-300;
  double s = 0, t = 0;
  if (a <= tiny && e <= tiny) {
    s = t = 0;
  } else if (a <= tiny) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= tiny) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2);
      const double denom = a * e - b * b;
      s = denom > 0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  c1 = p1 + s * d1;
  c2 = p2 + t * d2;
}

/// One point midway between the closest points of the two edges; returns the distance
/// between those points (an upper bound of the hulls' distance).
double edgeContact(const ConvexHull& a, const ConvexHull& b, const Relative& rel, int edgeA, int edgeB,
                   const Vector3d& axis, double separation, const Pose& poseA, ContactManifold& out) {
  const EdgeFrame ea = edgeOfA(a, edgeA);
  const EdgeFrame eb = edgeOfB(b, rel, edgeB);
  Vector3d c1, c2;
  closestSegmentPoints(ea.p, ea.p + ea.e, eb.p, eb.p + eb.e, c1, c2);
  out.normal = poseA.rotation * axis;
  out.pointCount = 1;
  ContactPoint& p = out.points[0];
  p.position = poseA.rotation * (0.5 * (c1 + c2)) + poseA.position;
  p.separation = separation;
  p.featureId = mixId(mixId(kTagEdge, u32(edgeA)), u32(edgeB));
  return (c2 - c1).norm();
}

/// Builds the manifold of a chosen face axis (or the edge pair) of a SAT result.
bool buildManifold(Reference reference, const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB,
                   const Relative& rel, int faceA, int faceB, double margin, ContactManifold& out) {
  if (reference == Reference::FaceA) return faceContact(a, b, rel, faceA, nullptr, 0, margin, poseA, false, out);
  return faceContact(b, a, inversePose(rel), faceB, nullptr, 0, margin, poseB, true, out);
}

// ---------------------------------------------------------------------------------------
// The three methods

void clearManifold(ContactManifold& out) { out.pointCount = 0; }

/// The exact method. Fills `result` (for the witness cache) and the manifold.
void exactQuery(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB, const Relative& rel,
                double margin, SatResult& sat, Reference& reference, bool& regular, ContactManifold& out) {
  clearManifold(out);
  sat = satQuery(a, b, rel, margin);
  reference = Reference::None;
  regular = false;
  if (!sat.complete || !(sat.best() <= margin)) return;
  reference = chooseReference(sat);
  switch (reference) {
    case Reference::FaceA:
    case Reference::FaceB:
      regular = buildManifold(reference, a, poseA, b, poseB, rel, sat.faceA.index, sat.faceB.index, margin, out);
      break;
    case Reference::Edge:
      edgeContact(a, b, rel, sat.edgeA, sat.edgeB, sat.edgeAxis, sat.edgeBest, poseA, out);
      regular = true;
      break;
    case Reference::None:
      break;
  }
}

/// Opposing Face Geometry (the original design's 8 steps), in A's frame.
void ofgQuery(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB, const Relative& rel,
              double margin, int k, ContactManifold& out) {
  clearManifold(out);
  const Relative inv = inversePose(rel);
  // 1. Bounding spheres of the whole hulls.
  const Vector3d centreB = rel.rotation * b.centroid + rel.position;
  if ((centreB - a.centroid).norm() > a.boundingRadius + b.boundingRadius + margin) return;

  const auto faceCentre = [](const ConvexHull& h, int f) {
    Vector3d c = Vector3d::Zero();
    const std::span<const int> idx = h.faceIndices(f);
    for (const int v : idx) c += h.vertices[static_cast<std::size_t>(v)];
    return idx.empty() ? c : Vector3d(c / static_cast<double>(idx.size()));
  };
  // The k faces of h whose centres are closest to `target` (h's frame), sorted by distance
  // (insertion into a sorted array; ties keep index order).
  const auto closestFaces = [&](const ConvexHull& h, const Vector3d& target, int kk, int* faces, double* dist) {
    int m = 0;
    for (int f = 0; f < h.faceCount(); ++f) {
      const double d = (faceCentre(h, f) - target).squaredNorm();
      if (m == kk && !(d < dist[m - 1])) continue;
      int pos = m < kk ? m++ : kk - 1;
      while (pos > 0 && d < dist[pos - 1]) {
        dist[pos] = dist[pos - 1];
        faces[pos] = faces[pos - 1];
        --pos;
      }
      dist[pos] = d;
      faces[pos] = f;
    }
    return m;
  };
  // Centre of a face selection (mean of the face centres) and its bounding radius.
  const auto selectionSphere = [&](const ConvexHull& h, const int* faces, int m, Vector3d& centre) {
    centre = Vector3d::Zero();
    for (int s = 0; s < m; ++s) centre += faceCentre(h, faces[s]);
    centre /= static_cast<double>(std::max(m, 1));
    double r2 = 0;
    for (int s = 0; s < m; ++s)
      for (const int v : h.faceIndices(faces[s]))
        r2 = std::max(r2, (h.vertices[static_cast<std::size_t>(v)] - centre).squaredNorm());
    return std::sqrt(r2);
  };

  std::array<int, kMaxOfgFaces> facesA, facesB;
  std::array<double, kMaxOfgFaces> distA, distB;
  // 2. The k faces of A closest to B's centre; 3. their centre and sphere.
  const int ka = closestFaces(a, centreB, std::min(k, a.faceCount()), facesA.data(), distA.data());
  Vector3d selA;
  const double radiusA = selectionSphere(a, facesA.data(), ka, selA);
  // 4. The k faces of B closest to that centre; 5. their centre and sphere.
  const Vector3d selAinB = inv.rotation * selA + inv.position;
  const int kb = closestFaces(b, selAinB, std::min(k, b.faceCount()), facesB.data(), distB.data());
  Vector3d selBlocal;
  const double radiusB = selectionSphere(b, facesB.data(), kb, selBlocal);
  const Vector3d selB = rel.rotation * selBlocal + rel.position;
  // 6. The two selections' spheres.
  if (ka == 0 || kb == 0 || (selB - selA).norm() > radiusA + radiusB + margin) return;
  // 7. Sort each set by the distance of its faces to the other selection's centre.
  const auto resort = [&](const ConvexHull& h, const Vector3d& target, int* faces, double* dist, int m) {
    for (int s = 0; s < m; ++s) dist[s] = (faceCentre(h, faces[s]) - target).squaredNorm();
    for (int s = 1; s < m; ++s) {
      const int f = faces[s];
      const double d = dist[s];
      int pos = s;
      while (pos > 0 && d < dist[pos - 1]) {
        dist[pos] = dist[pos - 1];
        faces[pos] = faces[pos - 1];
        --pos;
      }
      dist[pos] = d;
      faces[pos] = f;
    }
  };
  resort(a, selB, facesA.data(), distA.data(), ka);
  resort(b, inv.rotation * selA + inv.position, facesB.data(), distB.data(), kb);
  // 8. The selected face axes, closest first; any that separates by more than the margin
  // ends the query. The best of each side then decides as in the exact method (no edges).
  SatResult sat;
  for (int s = 0; s < std::max(ka, kb); ++s) {
    if (s < ka) {
      const double sep = faceSeparationA(a, b, rel, facesA[static_cast<std::size_t>(s)]);
      if (sep > margin) return;
      sat.faceA.add(sep, facesA[static_cast<std::size_t>(s)]);
    }
    if (s < kb) {
      const double sep = faceSeparationB(a, b, rel, facesB[static_cast<std::size_t>(s)]);
      if (sep > margin) return;
      sat.faceB.add(sep, facesB[static_cast<std::size_t>(s)]);
    }
  }
  // The incident face is sought among the other side's selection (O(k), the OFG's point).
  if (chooseReference(sat) == Reference::FaceB)
    faceContact(b, a, inv, sat.faceB.index, facesA.data(), ka, margin, poseB, true, out);
  else
    faceContact(a, b, rel, sat.faceA.index, facesB.data(), kb, margin, poseA, false, out);
}

// Witness motion bound. Let the relative pose change from (R, p) at the last full query to
// (R', p') now, and write B's vertices about its centroid cB: x_A = R (b - cB) + q with
// q = R cB + p. For an axis n fixed in A's frame (a face of A, or any fixed direction) the
// separation min_b n . x_A - max_a n . a changes by at most
//     max_b |n . ((R' - R)(b - cB) + (q' - q))| <= |q' - q| + ||R' - R||_2 rB = deltaA,
// because a minimum of functions that each move by at most e moves by at most e. Likewise
// for an axis fixed in B's frame (a face of B), with A's centroid in B's frame w = R^T (cA - p):
//     deltaB = |w' - w| + ||R' - R||_2 rA.
// ||R' - R||_2 = 2 sin(theta / 2) <= theta for the rotation angle theta of R' R^T; we use the
// Frobenius norm, which is sqrt(2) times as large for rotations (and still an upper bound for
// slightly non-orthonormal input). Edge axes turn with the rotation, at a rate up to
// 1 / sin(angle between the edges), so no such per-axis bound holds for them; instead every
// edge axis's separation is a value of g(u) = min_{x in M} u . x, and the largest value of g
// over all unit u, G, is a maximum over directions fixed in A's frame (or in B's): G moves by
// at most min(deltaA, deltaB). G is an upper bound of every edge axis's separation, and G is
// known at the last full query: when the hulls overlapped (S <= 0) the maximum of g over all
// directions is attained at a face normal of M, i.e. G = S (plus the width of any skipped
// near-parallel sliver face); when they were apart, G is their distance, at most the length
// of any segment joining them, e.g. a manifold point's |separation| (its incident point lies
// on B's face and its projection on A's reference face). With delta = max(deltaA, deltaB):
//   - the reference face stays the best face of its hull while delta < (lead over the
//     runner-up of the same hull) / 2;
//   - the face-A/face-B preference test keeps its outcome while delta < slack / (2 + c),
//     c = kFaceRelTolerance, since x + c|x| + t moves by at most (1 + c) delta;
//   - no edge axis gets preferred while delta < (F + cE |F| + t - G) / (2 + cE).
// PairCache::axisGap stores the smallest of these, scaled to the common form "reuse while
// delta < axisGap / 2". Then the exact method would choose the same reference face, and the
// manifold, built by the same code from the current pose, is the same.
double motionBound(const ConvexHull& a, const ConvexHull& b, const PairCache& cache, const Relative& rel) {
  const Matrix3d& r0 = cache.relativeRotation;
  const Vector3d& p0 = cache.relativePosition;
  const double dr = (rel.rotation - r0).norm();  // Frobenius
  const Vector3d dq = (rel.rotation * b.centroid + rel.position) - (r0 * b.centroid + p0);
  const Vector3d dw = rel.rotation.transpose() * (a.centroid - rel.position) - r0.transpose() * (a.centroid - p0);
  const double deltaA = dq.norm() + dr * b.boundingRadius;
  const double deltaB = dw.norm() + dr * a.boundingRadius;
  // Rounding of the separations themselves (a few ulps of the coordinates).
  const double scale = 1 + a.boundingRadius + b.boundingRadius + rel.position.norm();
  return std::max(deltaA, deltaB) + 1e-13 * scale;
}

/// Fills the cache after a full exact query.
void refillCache(const SatResult& sat, Reference reference, bool regular, const ContactManifold& out,
                 const Relative& rel, double margin, PairCache& cache) {
  cache.relativeRotation = rel.rotation;
  cache.relativePosition = rel.position;
  cache.axisGap = 0;
  const double best = sat.best();
  const auto setAxis = [&](PairCache::Axis axis) {
    cache.axis = axis;
    cache.indexA = axis == PairCache::Axis::FaceA      ? sat.faceA.index
                   : axis == PairCache::Axis::EdgePair ? sat.edgeA
                                                       : -1;
    cache.indexB = axis == PairCache::Axis::FaceB      ? sat.faceB.index
                   : axis == PairCache::Axis::EdgePair ? sat.edgeB
                                                       : -1;
  };
  if (!(best <= margin) || reference == Reference::None) {
    cache.touching = false;
    if (!(best > margin)) {  // non-finite input: forget everything
      cache.axis = PairCache::Axis::None;
      cache.indexA = cache.indexB = -1;
      return;
    }
    // The axis that separates (the best one found; with an early stop, the query that stopped).
    if (sat.faceA.best >= sat.faceB.best && sat.faceA.best >= sat.edgeBest)
      setAxis(PairCache::Axis::FaceA);
    else if (sat.faceB.best >= sat.edgeBest)
      setAxis(PairCache::Axis::FaceB);
    else
      setAxis(PairCache::Axis::EdgePair);
    return;
  }
  cache.touching = true;
  if (reference == Reference::Edge) {
    setAxis(PairCache::Axis::EdgePair);
    return;  // axisGap 0: an edge manifold is never reused (its axis turns with the motion)
  }
  setAxis(reference == Reference::FaceA ? PairCache::Axis::FaceA : PairCache::Axis::FaceB);
  if (!regular) return;  // fallback point: its pair of points does not bound the distance
  // G, the upper bound of every axis's separation (see motionBound).
  double g = best + 2 * sat.sliverWidth;
  if (best > 0) {
    double closest = kInf;
    for (int k = 0; k < out.pointCount; ++k)
      closest = std::min(closest, std::abs(out.points[static_cast<std::size_t>(k)].separation));
    g = closest;
  }
  const double fa = sat.faceA.best, fb = sat.faceB.best, f = std::max(fa, fb);
  const double edgeSlack = f + kEdgeRelTolerance * std::abs(f) + kAbsTolerance - g;
  double lead, faceSlack;
  if (reference == Reference::FaceA) {
    lead = fa - sat.faceA.second;
    faceSlack = fa + kFaceRelTolerance * std::abs(fa) + kAbsTolerance - fb;
  } else {
    lead = fb - sat.faceB.second;
    faceSlack = fb - fa - kFaceRelTolerance * std::abs(fa) - kAbsTolerance;
  }
  const double gap = std::min({lead, 2 * faceSlack / (2 + kFaceRelTolerance), 2 * edgeSlack / (2 + kEdgeRelTolerance)});
  cache.axisGap = gap > 0 && std::isfinite(gap) ? gap : (gap > 0 ? 1e300 : 0.0);
}

bool validIndex(int i, int count) { return i >= 0 && i < count; }

/// The separation along the cached axis in the current pose, if that axis is one the exact
/// method would test (a face, or an edge pair that still builds a Minkowski face).
bool cachedAxisSeparation(const ConvexHull& a, const ConvexHull& b, const Relative& rel, const PairCache& cache,
                          double& separation) {
  switch (cache.axis) {
    case PairCache::Axis::FaceA:
      if (!validIndex(cache.indexA, a.faceCount())) return false;
      separation = faceSeparationA(a, b, rel, cache.indexA);
      return true;
    case PairCache::Axis::FaceB:
      if (!validIndex(cache.indexB, b.faceCount())) return false;
      separation = faceSeparationB(a, b, rel, cache.indexB);
      return true;
    case PairCache::Axis::EdgePair: {
      if (!validIndex(cache.indexA, a.edgeCount()) || !validIndex(cache.indexB, b.edgeCount())) return false;
      Vector3d axis;
      double width = 0;
      return edgePairSeparation(edgeOfA(a, cache.indexA), edgeOfB(b, rel, cache.indexB), a.centroid, separation, axis,
                                width) == EdgePairKind::MinkowskiFace;
    }
    case PairCache::Axis::None:
      break;
  }
  return false;
}

NarrowPhaseOutcome witnessQuery(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB,
                                const Relative& rel, double margin, PairCache& cache, ContactManifold& out) {
  clearManifold(out);
  double s = 0;
  if (cachedAxisSeparation(a, b, rel, cache, s)) {
    // An axis of the exact method's set separating by more than the margin: the exact
    // method's best is at least s, so it too reports no contact.
    if (s > margin) {
      cache.touching = false;
      return NarrowPhaseOutcome::WitnessSeparated;
    }
    const bool face = cache.axis == PairCache::Axis::FaceA || cache.axis == PairCache::Axis::FaceB;
    if (cache.touching && face && motionBound(a, b, cache, rel) < 0.5 * cache.axisGap) {
      // The reference face is unchanged (see motionBound). The exact method reports contact
      // iff its best S' <= margin; with the preference tests unchanged,
      // S' <= F + cE |F| + t where F bounds both face maxima:
      //   face A chosen: fb' <= fa' + cF |fa'| + t, so F = fa' + cF |fa'| + t;
      //   face B chosen: fa' < fb', so F = fb'.
      const double f = cache.axis == PairCache::Axis::FaceA ? s + kFaceRelTolerance * std::abs(s) + kAbsTolerance : s;
      if (f + kEdgeRelTolerance * std::abs(f) + kAbsTolerance <= margin) {
        buildManifold(cache.axis == PairCache::Axis::FaceA ? Reference::FaceA : Reference::FaceB, a, poseA, b, poseB,
                      rel, cache.indexA, cache.indexB, margin, out);
        return NarrowPhaseOutcome::WitnessTouching;
      }
    }
  }
  SatResult sat;
  Reference reference;
  bool regular;
  exactQuery(a, poseA, b, poseB, rel, margin, sat, reference, regular, out);
  refillCache(sat, reference, regular, out, rel, margin, cache);
  return NarrowPhaseOutcome::FullQuery;
}

}  // namespace

const char* narrowPhaseMethodName(NarrowPhaseMethod method) {
  switch (method) {
    case NarrowPhaseMethod::Exact:
      return "exact";
    case NarrowPhaseMethod::Ofg:
      return "ofg";
    case NarrowPhaseMethod::Witness:
      return "witness";
  }
  return "unknown";
}

NarrowPhaseOutcome collideHulls(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB,
                                double margin, const NarrowPhaseOptions& options, PairCache& cache,
                                ContactManifold& out) {
  clearManifold(out);
  if (a.faceCount() == 0 || b.faceCount() == 0 || a.vertexCount() == 0 || b.vertexCount() == 0)
    return NarrowPhaseOutcome::FullQuery;
  const Relative rel = relativePose(poseA, poseB);
  switch (options.method) {
    case NarrowPhaseMethod::Exact: {
      SatResult sat;
      Reference reference;
      bool regular;
      exactQuery(a, poseA, b, poseB, rel, margin, sat, reference, regular, out);
      return NarrowPhaseOutcome::FullQuery;
    }
    case NarrowPhaseMethod::Ofg:
      ofgQuery(a, poseA, b, poseB, rel, margin, std::clamp(options.ofgFaces, 1, kMaxOfgFaces), out);
      return NarrowPhaseOutcome::FullQuery;
    case NarrowPhaseMethod::Witness:
      return witnessQuery(a, poseA, b, poseB, rel, margin, cache, out);
  }
  return NarrowPhaseOutcome::FullQuery;
}

void collideSphereHull(const Eigen::Vector3d& centre, double radius, const ConvexHull& b, const Pose& poseB,
                       double margin, ContactManifold& out) {
  clearManifold(out);
  if (b.faceCount() == 0) return;
  const Vector3d c = poseB.rotation.transpose() * (centre - poseB.position);  // B's frame
  int deepest = 0;
  double deepestDistance = -kInf;
  for (int f = 0; f < b.faceCount(); ++f) {
    const ConvexFace& face = b.faces[static_cast<std::size_t>(f)];
    const double d = face.normal.dot(c) - face.offset;
    if (d > deepestDistance) {
      deepestDistance = d;
      deepest = f;
    }
  }
  if (!(deepestDistance > -kInf)) return;  // non-finite input
  Vector3d closest = c;                    // on the hull, B's frame
  Vector3d normal = Vector3d::UnitY();     // from the sphere to the hull, B's frame
  double distance = 0;                     // signed: < 0 inside
  std::uint32_t feature = 0;
  if (deepestDistance <= 0) {
    // Inside: out through the face of least penetration.
    const ConvexFace& face = b.faces[static_cast<std::size_t>(deepest)];
    closest = c - deepestDistance * face.normal;
    normal = -face.normal;
    distance = deepestDistance;
    feature = mixId(kTagFace, u32(deepest));
  } else {
    // Outside: the closest point lies on a face that faces the centre (d > 0).
    double best2 = kInf;
    for (int f = 0; f < b.faceCount(); ++f) {
      const ConvexFace& face = b.faces[static_cast<std::size_t>(f)];
      const double d = face.normal.dot(c) - face.offset;
      if (!(d > 0) || d * d >= best2) continue;
      const std::span<const int> idx = b.faceIndices(f);
      const int n = static_cast<int>(idx.size());
      const Vector3d x = c - d * face.normal;  // projection on the plane
      bool inside = n >= 3;
      for (int k = 0; k < n && inside; ++k) {
        const Vector3d& v0 = b.vertices[static_cast<std::size_t>(idx[static_cast<std::size_t>(k)])];
        const Vector3d& v1 = b.vertices[static_cast<std::size_t>(idx[static_cast<std::size_t>((k + 1) % n)])];
        if ((v1 - v0).cross(x - v0).dot(face.normal) < 0) inside = false;
      }
      if (inside) {
        best2 = d * d;
        closest = x;
        feature = mixId(kTagFace, u32(f));
        continue;
      }
      for (int k = 0; k < n; ++k) {
        const int i0 = idx[static_cast<std::size_t>(k)], i1 = idx[static_cast<std::size_t>((k + 1) % n)];
        const Vector3d& v0 = b.vertices[static_cast<std::size_t>(i0)];
        const Vector3d e = b.vertices[static_cast<std::size_t>(i1)] - v0;
        const double l2 = e.squaredNorm();
        const double t = l2 > 0 ? std::clamp((c - v0).dot(e) / l2, 0.0, 1.0) : 0.0;
        const Vector3d y = v0 + t * e;
        const double dist2 = (c - y).squaredNorm();
        if (dist2 < best2) {
          best2 = dist2;
          closest = y;
          // The feature: a vertex at the ends, else the edge (its vertex pair, order-free).
          feature = t <= 0   ? mixId(kTagVertex, u32(i0))
                    : t >= 1 ? mixId(kTagVertex, u32(i1))
                             : mixId(mixId(kTagEdge, u32(std::min(i0, i1))), u32(std::max(i0, i1)));
        }
      }
    }
    distance = std::sqrt(best2);
    const double tiny = 1e-12 * (1 + b.boundingRadius);
    normal = distance > tiny ? Vector3d((closest - c) / distance)
                             : Vector3d(-b.faces[static_cast<std::size_t>(deepest)].normal);
  }
  const double separation = distance - radius;
  if (!(separation <= margin)) return;
  const Vector3d onSphere = c + radius * normal;
  out.normal = poseB.rotation * normal;
  out.pointCount = 1;
  out.points[0].position = poseB.rotation * (0.5 * (onSphere + closest)) + poseB.position;
  out.points[0].separation = separation;
  out.points[0].featureId = mixId(kTagSphere, feature);
}

double hullSeparation(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB) {
  if (a.faceCount() == 0 || b.faceCount() == 0) return kInf;
  return satQuery(a, b, relativePose(poseA, poseB), kInf).best();
}

}  // namespace weft
