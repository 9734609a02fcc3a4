// rigid/quickhull_exact.hpp (internal, a part of quickhull.cpp) — the exact arithmetic
// quickhull's decisions rest on: Shewchuk's expansions and nearly exact triangle normals.
// Included by quickhull.cpp alone, so that the hull is still compiled as one translation
// unit: GCC fuses multiply-adds differently across call boundaries between units
// (-ffp-contract=fast), and a hull's bits decide the rigid scenes' state hashes.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "collide/geometry.hpp"

namespace weft {
namespace {

using Eigen::Vector3d;

// ---------------------------------------------------------------------------------------
// Quickhull (Barber, Dobkin, Huhdanpaa 1996) on triangles, then coplanar triangles merged.
//
// Two kinds of decision, kept apart:
//  * Combinatorics (which triangles the new point sees) is decided exactly, with Shewchuk's
//    orient3d on the input coordinates. So every intermediate mesh is a triangulation of
//    the exact convex hull of the points inserted so far: no concave edge, no folded cone
//    triangle, the visible set always a disk with one horizon loop. (With a tolerance here
//    instead, a point nearly coplanar with a horizon triangle leaves a concave edge, and a
//    point near a horizon edge's line turns the cone triangle into a sliver that breaks
//    everything after it; both happen with rotated boxes and cylinders.)
//  * Which points to insert uses floating-point plane distances and the tolerance: a point
//    joins a conflict list only when more than tol above a triangle, so points within tol
//    of the hull (noise on a face, near-duplicates) never become vertices. Those distances
//    come from triangle normals computed to a few ulps even for slivers
//    (crossOfDifferences), in coordinates centred on the bounding box.
// Setting a point aside because it is within tol of the planes it was tested against does
// not keep it within tol of the final hull (beyond a thin slab's sharp rim it can end up far
// outside), so the set-aside points are checked against the final triangles and the hull
// resumed with any more than tol outside (reassignOutsidePoints). Then triangles are
// merged into faces: see makeConvexHull. If a check that exact arithmetic makes impossible
// ever fails (a horizon that is not one loop, a degenerate cone triangle), the point is
// dropped rather than the mesh corrupted.

// Exact orientation: Shewchuk, "Adaptive precision floating-point arithmetic and fast
// robust geometric predicates" (1997): his static error filter, and for the rare uncertain
// cases an exact evaluation with floating-point expansions (two-sum, fma two-product,
// grow-expansion); not his adaptive stages, which only make the rare case faster.

/// x + y == a + b exactly (Knuth).
inline void twoSum(double a, double b, double& x, double& y) {
  x = a + b;
  const double bv = x - a, av = x - bv;
  y = (a - av) + (b - bv);
}

/// Adds b to the non-overlapping, increasing-magnitude expansion e (Shewchuk's
/// Grow-Expansion, zeros eliminated).
void growExpansion(std::vector<double>& e, double b) {
  double q = b;
  std::size_t out = 0;
  for (std::size_t i = 0; i < e.size(); ++i) {
    double sum, err;
    twoSum(q, e[i], sum, err);
    q = sum;
    if (err != 0) e[out++] = err;
  }
  e.resize(out);
  if (q != 0) e.push_back(q);
}

/// Sign of det[a - d; b - d; c - d] (Shewchuk's convention): negative when d is above the
/// plane of (a, b, c), that is, when (a, b, c) turn counter-clockwise seen from d; zero when
/// coplanar. Exact: collide's orient3d (weft/collide/geometry.hpp), whose sign convention is
/// the opposite one.
int orient3dBelow(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d) {
  return -orient3d(a, b, c, d);
}

/// The value of the expansion e, rounded (its components summed smallest first).
double approximate(const std::vector<double>& e) {
  double sum = 0;
  for (const double x : e) sum += x;
  return sum;
}

/// (b - a) x (c - a). Thin triangles (slivers) are where rounding would turn the direction
/// arbitrarily and with it every plane distance; when Shewchuk's orient2d error bound
/// (ccwerrboundA, per component) exceeds 1e-14 of the length, each component is evaluated
/// exactly and rounded, so the plane is right to a few ulps whatever the shape.
Vector3d crossOfDifferences(const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const Vector3d u = b - a, v = c - a;
  const Vector3d n = u.cross(v);
  constexpr double kEpsilon = std::numeric_limits<double>::epsilon() / 2;
  constexpr double kErrorBound = (3.0 + 16.0 * kEpsilon) * kEpsilon;
  double error = 0;
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3, k = (i + 2) % 3;
    error += kErrorBound * (std::abs(u[j] * v[k]) + std::abs(u[k] * v[j]));
  }
  if (error <= 1e-14 * n.norm()) return n;
  Vector3d exact;
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3, k = (i + 2) % 3;
    // (b_j - a_j)(c_k - a_k) - (b_k - a_k)(c_j - a_j) with exact differences.
    const auto diff = [](double x, double y) {
      const double d = x - y, yv = x - d, xv = d + yv;
      return std::array<double, 2>{d, (x - xv) + (yv - y)};
    };
    const std::array<double, 2> bj = diff(b[j], a[j]), ck = diff(c[k], a[k]), bk = diff(b[k], a[k]),
                                cj = diff(c[j], a[j]);
    std::vector<double> sum;
    for (int s = 0; s < 2; ++s)
      for (int t = 0; t < 2; ++t) {
        const double x0 = bj[static_cast<std::size_t>(s)], y0 = ck[static_cast<std::size_t>(t)];
        const double x1 = -bk[static_cast<std::size_t>(s)], y1 = cj[static_cast<std::size_t>(t)];
        const double p0 = x0 * y0, p1 = x1 * y1;
        for (const double term : {p0, std::fma(x0, y0, -p0), p1, std::fma(x1, y1, -p1)})
          if (term != 0) growExpansion(sum, term);
      }
    exact[i] = approximate(sum);
  }
  return exact;
}

}  // namespace
}  // namespace weft
