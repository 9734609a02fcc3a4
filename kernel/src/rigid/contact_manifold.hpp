// Part of narrow_phase.cpp (see narrow_phase_internal.hpp): contact manifolds — the
// reference face's polygon clipped by the incident face's side planes (Sutherland-Hodgman
// in fixed stack arrays), reduced to at most four points with stable feature ids — and the
// single point of an edge-edge contact.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "../collide/closest_point.hpp"
#include "narrow_phase_internal.hpp"

namespace weft {
namespace {

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

/// One point midway between the closest points of the two edges; returns the distance
/// between those points (an upper bound of the hulls' distance).
double edgeContact(const ConvexHull& a, const ConvexHull& b, const Relative& rel, int edgeA, int edgeB,
                   const Vector3d& axis, double separation, const Pose& poseA, ContactManifold& out) {
  const EdgeFrame ea = edgeOfA(a, edgeA);
  const EdgeFrame eb = edgeOfB(b, rel, edgeB);
  Vector3d c1, c2;
  const Vector3d qa = ea.p + ea.e, qb = eb.p + eb.e;
  double s, t;
  detail::closestSegmentSegment(ea.p, qa, eb.p, qb, s, t, c1, c2);
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

}  // namespace
}  // namespace weft
