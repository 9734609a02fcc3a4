// Internal: inline definitions of the closest-point functions of weft/collide/geometry.hpp,
// shared by geometry.cpp (which instantiates the public templates) and bvh.cpp (whose
// closest-triangle query inlines them), and the segment-segment closest points shared by
// the contact pass's edge test (mesh_queries.cpp) and the rigid narrow phase's edge
// contacts (contact_manifold.cpp).
#pragma once

#include <algorithm>
#include <limits>

#include "collide/geometry.hpp"

namespace weft::detail {

template <class S>
inline Vec3<S> closestOnSegment(const Vec3<S>& p, const Vec3<S>& a, const Vec3<S>& b) {
  const Vec3<S> ab = b - a;
  const S len2 = ab.squaredNorm();
  if (!(len2 > S(0))) return a;
  S t = (p - a).dot(ab) / len2;
  t = t < S(0) ? S(0) : (t > S(1) ? S(1) : t);
  return a + t * ab;
}

/// Closest of the three edges' closest points (a degenerate triangle is the union of its edges).
template <class S>
inline Vec3<S> closestOnEdges(const Vec3<S>& p, const Vec3<S>& a, const Vec3<S>& b, const Vec3<S>& c) {
  Vec3<S> best = closestOnSegment(p, a, b);
  S bestD = (p - best).squaredNorm();
  const Vec3<S> q1 = closestOnSegment(p, b, c);
  const S d1 = (p - q1).squaredNorm();
  if (d1 < bestD) {
    best = q1;
    bestD = d1;
  }
  const Vec3<S> q2 = closestOnSegment(p, c, a);
  if ((p - q2).squaredNorm() < bestD) best = q2;
  return best;
}

template <class S>
inline Vec3<S> closestOnTriangle(const Vec3<S>& p, const Vec3<S>& a, const Vec3<S>& b, const Vec3<S>& c) {
  const Vec3<S> ab = b - a;
  const Vec3<S> ac = c - a;
  // Slivers (sin^2 of the angle at a below eps, including zero-length edges): their edges.
  const S ab2 = ab.squaredNorm();
  const S ac2 = ac.squaredNorm();
  if (!(ab.cross(ac).squaredNorm() > std::numeric_limits<S>::epsilon() * ab2 * ac2)) return closestOnEdges(p, a, b, c);

  const Vec3<S> ap = p - a;
  const S d1 = ab.dot(ap);
  const S d2 = ac.dot(ap);
  if (d1 <= S(0) && d2 <= S(0)) return a;  // vertex region a

  const Vec3<S> bp = p - b;
  const S d3 = ab.dot(bp);
  const S d4 = ac.dot(bp);
  if (d3 >= S(0) && d4 <= d3) return b;  // vertex region b

  const S vc = d1 * d4 - d3 * d2;
  if (vc <= S(0) && d1 >= S(0) && d3 <= S(0)) {  // edge region ab
    const S den = d1 - d3;
    return a + (den > S(0) ? d1 / den : S(0)) * ab;
  }

  const Vec3<S> cp = p - c;
  const S d5 = ab.dot(cp);
  const S d6 = ac.dot(cp);
  if (d6 >= S(0) && d5 <= d6) return c;  // vertex region c

  const S vb = d5 * d2 - d1 * d6;
  if (vb <= S(0) && d2 >= S(0) && d6 <= S(0)) {  // edge region ac
    const S den = d2 - d6;
    return a + (den > S(0) ? d2 / den : S(0)) * ac;
  }

  const S va = d3 * d6 - d5 * d4;
  const S e43 = d4 - d3;
  const S e56 = d5 - d6;
  if (va <= S(0) && e43 >= S(0) && e56 >= S(0)) {  // edge region bc
    const S den = e43 + e56;
    return b + (den > S(0) ? e43 / den : S(0)) * (c - b);
  }

  const S den = va + vb + vc;  // face region
  if (!(den > S(0))) return closestOnEdges(p, a, b, c);
  const S v = vb / den;
  const S w = vc / den;
  return a + v * ab + w * ac;
}

inline double dot(const Vec3<double>& a, const Vec3<double>& b) { return a.dot(b); }
inline double dot(const Vec3<double>& a) { return a.squaredNorm(); }

/// Closest points of the segments p1 q1 and p2 q2 (Ericson, Real-Time Collision Detection,
/// 5.1.9): parameters s, t in [0, 1] and the points c1, c2; returns the squared distance.
/// A segment shorter than 1e-150 counts as a point; of parallel segments, s = 0 is taken.
/// Vec is Vec3<double> or the contact pass's own 3-vector (with a free dot() found by ADL).
template <class Vec>
inline double closestSegmentSegment(const Vec& p1, const Vec& q1, const Vec& p2, const Vec& q2, double& s, double& t,
                                    Vec& c1, Vec& c2) {
  constexpr double tiny = 1e-300;  // squared length
  const Vec d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = dot(d1), e = dot(d2), f = dot(d2, r);
  s = t = 0;
  if (a <= tiny && e <= tiny) {
    // two points
  } else if (a <= tiny) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = dot(d1, r);
    if (e <= tiny) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = dot(d1, d2), denom = a * e - b * b;
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
  const Vec gap = c1 - c2;
  return dot(gap, gap);
}

}  // namespace weft::detail
