// weft/collide/geometry.hpp — exact orientation predicates, triangle-triangle
// intersection and closest points, the geometry under the BVH queries.
//
// Design note
// -----------
// Intersection tests decide from signs of determinants, and a wrong sign near a
// degenerate configuration (coplanar triangles, a vertex on a face, an edge through an
// edge, a sliver) turns into a missed or an invented contact. So the tests here are
// exact: orient2d / orient3d return the sign of the exact determinant of the (double)
// input coordinates. Each is evaluated in double first and accepted when its magnitude
// exceeds a forward error bound (Shewchuk's bounds for this evaluation order, doubled
// as a margin); otherwise it is recomputed exactly with floating-point expansions
// (two_sum / two_product with fma, Shewchuk 1997), which only happens within a few ulps
// of zero. float input is converted to double, which is exact. The one assumption is
// that no intermediate product overflows or underflows (|coordinates| between about
// 1e-70 and 1e70 apart from exact zeros), which any scene in metres satisfies.
//
// trianglesIntersect(T1, T2) is true iff the two CLOSED triangles share a point
// (touching counts). A triangle whose corners are collinear is handled as the segment
// between its extreme corners, one with three equal corners as a point, so every input
// has a defined answer. For two proper triangles: if all corners of one lie strictly on
// one side of the other's plane, false (Möller's early rejection, the common case);
// coplanar triangles are tested in 2D (a projection along an axis the plane's normal
// has a non-zero component on, exact because it only drops a coordinate): a corner of
// one inside the other or two edges crossing; otherwise Devillers and Guigue's test (the
// corners permuted by their sides so that one corner of each triangle is alone on its
// side, then two more orientations decide whether the two triangles' intervals on the
// planes' common line overlap). Segments and points against anything use the edge-wise
// tests: an edge pq meets a proper triangle abc iff p, q are not strictly on one side of
// its plane and either both lie in it (2D test) or the volumes [p, q, a, b],
// [p, q, b, c], [p, q, c, a] agree in sign, zeros allowed. (Devillers-Guigue was checked
// against that edge-wise test on two triangles as well, 8 million random triangle pairs
// on small integer grids, full of coplanar, touching and collinear cases: no difference;
// it is 2.5x faster on intersecting pairs.) A sum of products that are all exactly zero
// is zero without an exact evaluation, so a flat cloth in a coordinate plane costs no
// expansion arithmetic.
//
// closestPointOnTriangle is Ericson's "Real-Time Collision Detection" 5.1.5 (Voronoi
// regions of vertices, then edges, then the face), in S. Divisions are guarded, and a
// sliver whose sin^2 of the angle at a is below eps(S) is handled as its three edges
// (the distance then differs by at most the sliver's height from the face's), so
// degenerate triangles give a point on the triangle, never NaN.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products

#include "weft/core/types.hpp"

namespace weft {

/// A fixed-size 3-vector (no alignment requirement: 12 or 24 bytes).
template <class S>
using Vec3 = Eigen::Matrix<S, 3, 1>;

/// Sign (+1, 0, -1) of the exact (b - a) x (c - a) . (d - a): +1 when d lies on the side the
/// normal of the counter-clockwise triangle abc points to.
int orient3d(const Vec3<double>& a, const Vec3<double>& b, const Vec3<double>& c, const Vec3<double>& d);

/// Sign of the exact (bx - ax)(cy - ay) - (by - ay)(cx - ax): +1 when a, b, c turn left.
int orient2d(double ax, double ay, double bx, double by, double cx, double cy);

/// True iff the closed triangles a1 b1 c1 and a2 b2 c2 share a point; exact for any finite
/// input, degenerate triangles included (see the design note).
bool trianglesIntersect(const Vec3<double>& a1, const Vec3<double>& b1, const Vec3<double>& c1, const Vec3<double>& a2,
                        const Vec3<double>& b2, const Vec3<double>& c2);

/// Closest point to p on the segment ab (a point if a == b).
template <class S>
Vec3<S> closestPointOnSegment(const Vec3<S>& p, const Vec3<S>& a, const Vec3<S>& b);

/// Closest point to p on the closed triangle abc (Ericson 5.1.5; see the design note for
/// degenerate triangles).
template <class S>
Vec3<S> closestPointOnTriangle(const Vec3<S>& p, const Vec3<S>& a, const Vec3<S>& b, const Vec3<S>& c);

extern template Vec3<float> closestPointOnSegment(const Vec3<float>&, const Vec3<float>&, const Vec3<float>&);
extern template Vec3<double> closestPointOnSegment(const Vec3<double>&, const Vec3<double>&, const Vec3<double>&);
extern template Vec3<float> closestPointOnTriangle(const Vec3<float>&, const Vec3<float>&, const Vec3<float>&,
                                                   const Vec3<float>&);
extern template Vec3<double> closestPointOnTriangle(const Vec3<double>&, const Vec3<double>&, const Vec3<double>&,
                                                    const Vec3<double>&);

}  // namespace weft
