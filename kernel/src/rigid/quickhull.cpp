// weft/rigid/quickhull.cpp — the convex hull of a point set: quickhull (Barber, Dobkin,
// Huhdanpaa 1996) on triangles with exact orientation decisions, then coplanar triangles
// merged into convex polygons (the conventions of every hull: convex_hull.cpp).
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "collide/geometry.hpp"
#include "core/text.hpp"
#include "hull_internal.hpp"
#include "quickhull_mesh.hpp"
#include "weft/rigid/convex_hull.hpp"

namespace weft {

using detail::number;
using Eigen::Vector3d;

namespace {
// The sizes a hull can have: a face normal's squared length is the fourth power of the
// hull's size, finite and normal between these (1e200^4 overflows, 1e-80^4 underflows).
constexpr double kHullFarthest = 1e50, kHullShortest = 1e-50;
}  // namespace

ConvexHull makeConvexHull(std::span<const Vector3d> points, double tolerance) {
  const int pointCount = static_cast<int>(points.size());
  if (pointCount < 4)
    throw std::invalid_argument("makeConvexHull: needs at least 4 points, got " + std::to_string(pointCount));
  for (int i = 0; i < pointCount; ++i) {
    const Vector3d& p = points[static_cast<std::size_t>(i)];
    if (!p.allFinite())
      throw std::invalid_argument("makeConvexHull: point " + std::to_string(i) + " has a non-finite coordinate (" +
                                  number(p.x()) + ", " + number(p.y()) + ", " + number(p.z()) + ")");
    if (!(p.cwiseAbs().maxCoeff() <= kHullFarthest))
      throw std::invalid_argument("makeConvexHull: point " + std::to_string(i) + " = (" + number(p.x()) + ", " +
                                  number(p.y()) + ", " + number(p.z()) + ") must be within +-" + number(kHullFarthest) +
                                  " m in each coordinate");
  }
  if (std::isnan(tolerance) || std::isinf(tolerance))
    throw std::invalid_argument("makeConvexHull: tolerance must be finite, got " + number(tolerance));

  Vector3d lo = points[0], hi = points[0];
  for (const Vector3d& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Vector3d centre = 0.5 * (lo + hi);
  const double extent = (hi - lo).maxCoeff();
  // Below ~1e3 ulps of the extent, rounding rather than geometry would decide which nearly
  // coplanar points become vertices, so a smaller tolerance is raised to that.
  const double tol =
      std::max(tolerance > 0 ? tolerance : 1e-9 * extent, 1e3 * std::numeric_limits<double>::epsilon() * extent);
  const auto noVolume = [&](const char* what) {
    return std::invalid_argument(std::string("makeConvexHull: points span no volume (all within ") + number(tol) +
                                 " of " + what + ")");
  };
  if (!(extent > 0)) throw std::invalid_argument("makeConvexHull: points span no volume (all coincident)");
  if (extent < kHullShortest)  // (its normals' squared lengths, extent^4, would underflow)
    throw std::invalid_argument("makeConvexHull: the points' extent " + number(extent) + " m must be at least " +
                                number(kHullShortest) + " m");
  std::vector<Vector3d> local(points.begin(), points.end());
  for (Vector3d& p : local) p -= centre;

  // Initial simplex: the two furthest apart of the six axis extremes, the point furthest
  // from their line, the point furthest from the plane of the three.
  std::array<int, 6> extreme{};
  for (int axis = 0; axis < 3; ++axis)
    for (int i = 0; i < pointCount; ++i) {
      const double x = local[static_cast<std::size_t>(i)][axis];
      if (x < local[static_cast<std::size_t>(extreme[2 * axis])][axis]) extreme[2 * axis] = i;
      if (x > local[static_cast<std::size_t>(extreme[2 * axis + 1])][axis]) extreme[2 * axis + 1] = i;
    }
  int a = extreme[0], b = extreme[1];
  double best = -1;
  for (int i = 0; i < 6; ++i)
    for (int j = i + 1; j < 6; ++j) {
      const double d =
          (local[static_cast<std::size_t>(extreme[i])] - local[static_cast<std::size_t>(extreme[j])]).norm();
      if (d > best) {
        best = d;
        a = extreme[i];
        b = extreme[j];
      }
    }
  if (!(best > tol)) throw noVolume("one point");
  const Vector3d pa = local[static_cast<std::size_t>(a)];
  const Vector3d dir = (local[static_cast<std::size_t>(b)] - pa).normalized();
  int c = -1;
  best = -1;
  for (int i = 0; i < pointCount; ++i) {
    const double d = (local[static_cast<std::size_t>(i)] - pa).cross(dir).norm();
    if (d > best) {
      best = d;
      c = i;
    }
  }
  if (!(best > tol)) throw noVolume("a line");
  const Vector3d normal =
      (local[static_cast<std::size_t>(b)] - pa).cross(local[static_cast<std::size_t>(c)] - pa).normalized();
  int d = -1;
  best = -1;
  double signedBest = 0;
  for (int i = 0; i < pointCount; ++i) {
    const double h = normal.dot(local[static_cast<std::size_t>(i)] - pa);
    if (std::abs(h) > best) {
      best = std::abs(h);
      signedBest = h;
      d = i;
    }
  }
  if (!(best > tol)) throw noVolume("a plane");
  if (signedBest > 0) std::swap(b, c);  // d below the plane of (a, b, c)

  QuickHull quickHull(points, local, tol);
  quickHull.run(a, b, c, d);
  const std::vector<HullTriangle>& tris = quickHull.triangles();

  // Merge coplanar triangles into faces. Seeds are taken largest first (the
  // best-conditioned planes); a cluster grows across edges to triangles whose three
  // vertices are all within mergeTol = tol / 2 of the seed's plane (so a gently curved
  // strip cannot creep into one face), and is kept as one face only when its outline is one
  // simple loop, every member vertex is within mergeTol of the face's own plane and no
  // corner is reflex by more than mergeTol; otherwise it stays triangles, which are exactly
  // convex. Half the tolerance leaves the merged faces flat and convex to within tol. Only
  // input noise near the tolerance makes merging fail (then faces may be slivers).
  std::vector<int> order;
  std::vector<double> area(tris.size(), 0);
  for (std::size_t t = 0; t < tris.size(); ++t) {
    if (!tris[t].alive) continue;
    order.push_back(static_cast<int>(t));
    const auto& v = tris[t].v;
    area[t] = (local[static_cast<std::size_t>(v[1])] - local[static_cast<std::size_t>(v[0])])
                  .cross(local[static_cast<std::size_t>(v[2])] - local[static_cast<std::size_t>(v[0])])
                  .norm();
  }
  std::stable_sort(order.begin(), order.end(),
                   [&](int x, int y) { return area[static_cast<std::size_t>(x)] > area[static_cast<std::size_t>(y)]; });
  const double mergeTol = 0.5 * tol;
  std::vector<int> cluster(tris.size(), -1);
  std::vector<std::vector<int>> polygons;  // point indices, counter-clockwise
  std::vector<Vector3d> polygonArea;       // sum of the members' area vectors: the outline's
  int clusterCount = 0;
  for (const int seed : order) {
    if (cluster[static_cast<std::size_t>(seed)] >= 0) continue;
    const int id = clusterCount++;
    const HullTriangle& s = tris[static_cast<std::size_t>(seed)];
    std::vector<int> members = {seed};
    cluster[static_cast<std::size_t>(seed)] = id;
    for (std::size_t i = 0; i < members.size(); ++i)
      for (const int n : tris[static_cast<std::size_t>(members[i])].adj) {
        const HullTriangle& nt = tris[static_cast<std::size_t>(n)];
        if (cluster[static_cast<std::size_t>(n)] >= 0 || !(nt.normal.dot(s.normal) > 0)) continue;
        bool coplanar = true;
        for (const int v : nt.v)
          coplanar = coplanar && std::abs(s.normal.dot(local[static_cast<std::size_t>(v)]) - s.offset) <= mergeTol;
        if (!coplanar) continue;
        cluster[static_cast<std::size_t>(n)] = id;
        members.push_back(n);
      }
    if (members.size() == 1) {
      polygons.emplace_back(s.v.begin(), s.v.end());
      polygonArea.push_back(s.area);
      continue;
    }
    // The outline: member edges whose neighbour is not a member, chained into a loop.
    std::vector<std::pair<int, int>> outline;  // (from, to)
    for (const int m : members)
      for (int k = 0; k < 3; ++k)
        if (cluster[static_cast<std::size_t>(tris[static_cast<std::size_t>(m)].adj[static_cast<std::size_t>(k)])] != id)
          outline.emplace_back(tris[static_cast<std::size_t>(m)].v[static_cast<std::size_t>(k)],
                               tris[static_cast<std::size_t>(m)].v[static_cast<std::size_t>((k + 1) % 3)]);
    std::sort(outline.begin(), outline.end());
    bool simple = outline.size() >= 3;
    for (std::size_t i = 1; simple && i < outline.size(); ++i) simple = outline[i].first != outline[i - 1].first;
    std::vector<int> polygon;
    if (simple) {
      int v = outline[0].first;
      do {
        polygon.push_back(v);
        const auto it = std::lower_bound(outline.begin(), outline.end(), std::make_pair(v, -1));
        if (it == outline.end() || it->first != v) break;
        v = it->second;
      } while (v != outline[0].first && polygon.size() <= outline.size());
      simple = v == outline[0].first && polygon.size() == outline.size();
    }
    Vector3d sum = Vector3d::Zero();
    for (const int m : members) sum += tris[static_cast<std::size_t>(m)].area;
    // The merged face must be flat and convex within mergeTol about its own plane (noise
    // near the tolerance can put a steep sliver within the slab); else it stays triangles,
    // which are exactly convex.
    if (simple) {
      const Vector3d n = sum.normalized();
      double offset = 0;
      for (const int v : polygon) offset += n.dot(local[static_cast<std::size_t>(v)]);
      offset /= static_cast<double>(polygon.size());
      for (const int m : members)
        for (const int v : tris[static_cast<std::size_t>(m)].v)
          simple = simple && std::abs(n.dot(local[static_cast<std::size_t>(v)]) - offset) <= mergeTol;
      for (std::size_t k = 0; simple && k < polygon.size(); ++k) {
        const Vector3d& x0 = local[static_cast<std::size_t>(polygon[k])];
        const Vector3d& x1 = local[static_cast<std::size_t>(polygon[(k + 1) % polygon.size()])];
        const Vector3d& x2 = local[static_cast<std::size_t>(polygon[(k + 2) % polygon.size()])];
        simple = n.dot((x1 - x0).cross(x2 - x0)) >= -mergeTol * (x2 - x0).norm();  // x1's height over x0 x2
      }
    }
    if (simple) {
      polygons.push_back(std::move(polygon));
      polygonArea.push_back(sum);
    } else {
      for (std::size_t i = 0; i < members.size(); ++i) {
        if (i > 0) cluster[static_cast<std::size_t>(members[i])] = clusterCount++;
        const auto& v = tris[static_cast<std::size_t>(members[i])].v;
        polygons.emplace_back(v.begin(), v.end());
        polygonArea.push_back(tris[static_cast<std::size_t>(members[i])].area);
      }
    }
  }

  // A vertex shared by exactly two faces lies on the edge between them: when it is within
  // tol of the line through its two neighbours (a point on a box edge), it is dropped from
  // both, so a box's corners plus edge points give 8 vertices and 12 edges.
  std::vector<std::vector<int>> facesOf(static_cast<std::size_t>(pointCount));
  for (std::size_t f = 0; f < polygons.size(); ++f)
    for (const int v : polygons[f]) facesOf[static_cast<std::size_t>(v)].push_back(static_cast<int>(f));
  for (int v = 0; v < pointCount; ++v) {
    const std::vector<int>& fs = facesOf[static_cast<std::size_t>(v)];
    if (fs.size() != 2) continue;
    std::vector<int>& pa0 = polygons[static_cast<std::size_t>(fs[0])];
    std::vector<int>& pb0 = polygons[static_cast<std::size_t>(fs[1])];
    if (pa0.size() < 4 || pb0.size() < 4) continue;
    const auto ia = std::find(pa0.begin(), pa0.end(), v) - pa0.begin();
    const auto ib = std::find(pb0.begin(), pb0.end(), v) - pb0.begin();
    const auto na = static_cast<std::ptrdiff_t>(pa0.size()), nb = static_cast<std::ptrdiff_t>(pb0.size());
    const int prev = pa0[static_cast<std::size_t>((ia + na - 1) % na)],
              next = pa0[static_cast<std::size_t>((ia + 1) % na)];
    if (pb0[static_cast<std::size_t>((ib + nb - 1) % nb)] != next ||
        pb0[static_cast<std::size_t>((ib + 1) % nb)] != prev)
      continue;
    const Vector3d& x0 = local[static_cast<std::size_t>(std::min(prev, next))];
    const Vector3d& x1 = local[static_cast<std::size_t>(std::max(prev, next))];
    const Vector3d e = x1 - x0;
    const double lineDistance = (local[static_cast<std::size_t>(v)] - x0).cross(e).norm() / e.norm();
    if (!(lineDistance <= tol)) continue;
    pa0.erase(pa0.begin() + ia);
    pb0.erase(pb0.begin() + ib);
  }

  // Output: used points in input order; faces in cluster order, each starting at its
  // lowest vertex; offset the mean of normal . vertex.
  std::vector<int> newIndex(static_cast<std::size_t>(pointCount), -1);
  for (const auto& polygon : polygons)
    for (const int v : polygon) newIndex[static_cast<std::size_t>(v)] = 0;
  ConvexHull hull;
  for (int v = 0; v < pointCount; ++v)
    if (newIndex[static_cast<std::size_t>(v)] == 0) {
      newIndex[static_cast<std::size_t>(v)] = hull.vertexCount();
      hull.vertices.push_back(points[static_cast<std::size_t>(v)]);
    }
  for (std::size_t f = 0; f < polygons.size(); ++f) {
    const std::vector<int>& polygon = polygons[f];
    const std::size_t count = polygon.size();
    ConvexFace face;
    // The summed triangle area vectors are the outline's Newell vector (area vectors add),
    // but each was computed to a few ulps (crossOfDifferences), so thin faces keep
    // accurate normals. Dropping collinear outline vertices changes it by O(tol).
    face.normal = polygonArea[f].normalized();
    face.first = static_cast<int>(hull.faceVertices.size());
    face.count = static_cast<int>(count);
    std::size_t start = 0;
    for (std::size_t k = 1; k < count; ++k)
      if (polygon[k] < polygon[start]) start = k;
    double offset = 0;
    for (std::size_t k = 0; k < count; ++k) {
      const int v = polygon[(start + k) % count];
      hull.faceVertices.push_back(newIndex[static_cast<std::size_t>(v)]);
      offset += face.normal.dot(points[static_cast<std::size_t>(v)]);
    }
    face.offset = offset / static_cast<double>(count);
    hull.faces.push_back(face);
  }
  rigid_detail::finishHull(hull);
  return hull;
}

}  // namespace weft
