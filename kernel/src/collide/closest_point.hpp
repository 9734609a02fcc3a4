// Internal: inline definitions of the closest-point functions of weft/collide/geometry.hpp,
// shared by geometry.cpp (which instantiates the public templates) and bvh.cpp (whose
// closest-triangle query inlines them).
#pragma once

#include <limits>

#include "weft/collide/geometry.hpp"

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

}  // namespace weft::detail
