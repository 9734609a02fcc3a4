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
#include "hull_internal.hpp"
#include "rigid_text.hpp"
#include "weft/rigid/convex_hull.hpp"

namespace weft {

using Eigen::Vector3d;
using rigid_detail::formatNumber;

namespace {

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

struct HullTriangle {
  std::array<int, 3> v{};              // point indices, counter-clockwise about normal
  std::array<int, 3> adj{};            // adj[i]: the triangle across the edge v[i] -> v[(i + 1) % 3]
  Vector3d area = Vector3d::Zero();    // (v1 - v0) x (v2 - v0), nearly exact (crossOfDifferences)
  Vector3d normal = Vector3d::Zero();  // area / |area|
  double offset = 0;                   // normal . x on the plane, in the centred coordinates
  std::vector<int> outside;            // conflict list: points more than tol above this plane
  int furthest = -1;
  double furthestDistance = 0;
  bool alive = true;
  int replacement = -1;  // once dead: a triangle that replaced it (a hint where to look)
};

class QuickHull {
 public:
  QuickHull(std::span<const Vector3d> points, std::vector<Vector3d> local, double tol)
      : points_(points), q_(std::move(local)), tol_(tol) {}

  /// Builds the hull from the simplex (a, b, c, d); d must lie below the plane of (a, b, c).
  void run(int a, int b, int c, int d) {
    // Directed edges pair up: (a,b,c) (a,d,b) (b,d,c) (c,d,a).
    const int t0 = addTriangle(a, b, c), t1 = addTriangle(a, d, b), t2 = addTriangle(b, d, c),
              t3 = addTriangle(c, d, a);
    tri_[t0].adj = {t1, t2, t3};
    tri_[t1].adj = {t3, t2, t0};
    tri_[t2].adj = {t1, t3, t0};
    tri_[t3].adj = {t2, t1, t0};
    const std::vector<int> all = {t0, t1, t2, t3};
    status_.assign(q_.size(), kInside);
    hint_.assign(q_.size(), t0);
    for (const int v : {a, b, c, d}) status_[static_cast<std::size_t>(v)] = kVertex;
    for (int p = 0; p < static_cast<int>(q_.size()); ++p)
      if (status_[static_cast<std::size_t>(p)] != kVertex) assign(p, all);
    visited_.assign(tri_.size(), 0);
    // Being within tol of the planes seen when a point was set aside does not keep it within
    // tol of the final planes: near a sharp edge (a thin slab's rim) it can end up far
    // outside a later plane. So every set-aside point is checked against the final hull and
    // the hull resumed with those more than tol outside, until none is.
    do processPending();
    while (reassignOutsidePoints());
  }

  const std::vector<HullTriangle>& triangles() const { return tri_; }

 private:
  enum PointStatus : char { kInside, kVertex, kDropped };

  /// Adds points until no conflict list is left. pending_ lists every triangle whose
  /// conflict list became non-empty, in that order.
  void processPending() {
    for (std::size_t i = 0; i < pending_.size(); ++i) {
      const int t = pending_[i];
      while (tri_[static_cast<std::size_t>(t)].alive && !tri_[static_cast<std::size_t>(t)].outside.empty()) {
        addPoint(t);
      }
    }
    pending_.clear();
  }

  /// Puts every set-aside point that is more than tol above a live triangle on the conflict
  /// list of the triangle it is furthest above; true when there was one.
  ///
  /// Finding that triangle without scanning them all: from an interior point c, the ray
  /// towards the point x leaves the hull through the triangle F maximising
  /// n_F . (x - c) / (d_F - n_F . c) (d_F the offset). That is a linear function of the
  /// vertices n_F / (d_F - n_F . c) of the polar dual, itself a convex polytope whose edges
  /// are the hull's, so climbing over neighbours reaches the maximum (coplanar neighbours tie;
  /// the climb crosses such plateaus). If x is outside the hull it is above F, and the
  /// triangles it is above form a connected patch, searched from F for the highest. Points in
  /// the inscribed ball about c are skipped outright.
  bool reassignOutsidePoints() {
    Vector3d centre = Vector3d::Zero();
    double vertexCount = 0;
    for (std::size_t p = 0; p < q_.size(); ++p)
      if (status_[p] == kVertex) {
        centre += q_[p];
        vertexCount += 1;
      }
    centre /= vertexCount;
    double inradius = std::numeric_limits<double>::infinity();
    for (const HullTriangle& t : tri_)
      if (t.alive) inradius = std::min(inradius, t.offset - t.normal.dot(centre));
    // The climb's objective for triangle t and direction d.
    const auto exitRate = [&](int t, const Vector3d& d) {
      const HullTriangle& tri = tri_[static_cast<std::size_t>(t)];
      return tri.normal.dot(d) / std::max(tri.offset - tri.normal.dot(centre), std::numeric_limits<double>::min());
    };
    bool any = false;
    std::vector<int> patch;
    for (int p = 0; p < static_cast<int>(q_.size()); ++p) {
      if (status_[static_cast<std::size_t>(p)] != kInside) continue;
      const Vector3d& x = q_[static_cast<std::size_t>(p)];
      if ((x - centre).norm() + tol_ < inradius) continue;
      int t = hint_[static_cast<std::size_t>(p)];
      while (!tri_[static_cast<std::size_t>(t)].alive) t = tri_[static_cast<std::size_t>(t)].replacement;
      const Vector3d d = x - centre;
      // Climb; on a plateau (equal rates) search it breadth-first for a way up.
      for (;;) {
        const double rate = exitRate(t, d);
        int up = -1;
        ++stamp_;
        patch.assign(1, t);
        visited_[static_cast<std::size_t>(t)] = stamp_;
        const double slack = 1e-12 * std::abs(rate);  // rounding between coplanar triangles
        for (std::size_t i = 0; i < patch.size() && up < 0; ++i)
          for (const int n : tri_[static_cast<std::size_t>(patch[i])].adj) {
            if (visited_[static_cast<std::size_t>(n)] == stamp_) continue;
            visited_[static_cast<std::size_t>(n)] = stamp_;
            const double r = exitRate(n, d);
            if (r > rate + slack) {
              up = n;
              break;
            }
            if (r >= rate - slack) patch.push_back(n);
          }
        if (up < 0) break;
        t = up;
      }
      if (!(distance(t, p) > 0)) continue;  // inside: below the plane it exits through
      // Outside: search the patch of triangles it is above for the highest.
      int best = -1;
      double bestDistance = tol_;
      ++stamp_;
      patch.assign(1, t);
      visited_[static_cast<std::size_t>(t)] = stamp_;
      for (std::size_t i = 0; i < patch.size(); ++i) {
        const double h = distance(patch[i], p);
        if (h > bestDistance) {
          bestDistance = h;
          best = patch[i];
        }
        for (const int n : tri_[static_cast<std::size_t>(patch[i])].adj)
          if (visited_[static_cast<std::size_t>(n)] != stamp_) {
            visited_[static_cast<std::size_t>(n)] = stamp_;
            if (distance(n, p) > 0) patch.push_back(n);
          }
      }
      if (best >= 0) {
        assign(p, {best});
        any = true;
      }
    }
    return any;
  }

 private:
  int addTriangle(int a, int b, int c) {
    HullTriangle t;
    t.v = {a, b, c};
    t.area = crossOfDifferences(points_[static_cast<std::size_t>(a)], points_[static_cast<std::size_t>(b)],
                                points_[static_cast<std::size_t>(c)]);
    const double length = t.area.norm();
    t.normal = length > 0 && std::isfinite(length) ? Vector3d(t.area / length) : Vector3d::Zero();
    t.offset = t.normal.dot(q_[static_cast<std::size_t>(a)] + q_[static_cast<std::size_t>(b)] +
                            q_[static_cast<std::size_t>(c)]) /
               3;
    tri_.push_back(std::move(t));
    visited_.push_back(0);
    return static_cast<int>(tri_.size()) - 1;
  }

  double distance(int t, int p) const {
    const HullTriangle& tri = tri_[static_cast<std::size_t>(t)];
    return tri.normal.dot(q_[static_cast<std::size_t>(p)]) - tri.offset;
  }

  /// Puts p on the conflict list of the first candidate it is more than tol above.
  bool assign(int p, const std::vector<int>& candidates) {
    for (const int t : candidates) {
      const double d = distance(t, p);
      if (d > tol_) {
        HullTriangle& tri = tri_[static_cast<std::size_t>(t)];
        if (tri.outside.empty()) pending_.push_back(t);
        tri.outside.push_back(p);
        if (d > tri.furthestDistance) {
          tri.furthestDistance = d;
          tri.furthest = p;
        }
        return true;
      }
    }
    return false;
  }

  struct HorizonEdge {
    int a, b;      // directed as in the visible triangle
    int neighbor;  // the triangle beyond, which stays
  };

  void addPoint(int t0) {
    const int p = tri_[static_cast<std::size_t>(t0)].furthest;
    if (!strictlyAbove(t0, p)) {  // only rounding put it there
      dropPoint(t0, p);
      return;
    }
    ++stamp_;
    // Visible set by breadth-first search from t0; visited_ holds +stamp (visible) or
    // -stamp (tested, stays).
    std::vector<int> visible = {t0};
    std::vector<HorizonEdge> horizon;
    visited_[static_cast<std::size_t>(t0)] = stamp_;
    for (std::size_t i = 0; i < visible.size(); ++i) {
      const int t = visible[i];
      for (int s = 0; s < 3; ++s) {
        const int n = tri_[static_cast<std::size_t>(t)].adj[static_cast<std::size_t>(s)];
        std::int64_t& mark = visited_[static_cast<std::size_t>(n)];
        if (mark != stamp_ && mark != -stamp_) {
          mark = strictlyAbove(n, p) ? stamp_ : -stamp_;
          if (mark == stamp_) visible.push_back(n);
        }
        if (mark == -stamp_) {
          const HullTriangle& tri = tri_[static_cast<std::size_t>(t)];
          horizon.push_back({tri.v[static_cast<std::size_t>(s)], tri.v[static_cast<std::size_t>((s + 1) % 3)], n});
        }
      }
    }
    std::vector<HorizonEdge> loop;
    if (!orderHorizon(horizon, loop) || !coneIsSound(loop, p)) {
      dropPoint(t0, p);
      return;
    }

    // Cone: triangle k is (a_k, b_k, p); its edge 1 (b_k -> p) meets triangle k + 1's edge 2.
    status_[static_cast<std::size_t>(p)] = kVertex;
    const int first = static_cast<int>(tri_.size());
    const int count = static_cast<int>(loop.size());
    for (int k = 0; k < count; ++k) {
      const HorizonEdge& e = loop[static_cast<std::size_t>(k)];
      const int t = addTriangle(e.a, e.b, p);
      HullTriangle& tri = tri_[static_cast<std::size_t>(t)];
      tri.adj = {e.neighbor, first + (k + 1) % count, first + (k + count - 1) % count};
      HullTriangle& nb = tri_[static_cast<std::size_t>(e.neighbor)];
      for (int s = 0; s < 3; ++s)
        if (nb.v[static_cast<std::size_t>(s)] == e.b && nb.v[static_cast<std::size_t>((s + 1) % 3)] == e.a)
          nb.adj[static_cast<std::size_t>(s)] = t;
    }
    // Orphans go to the first new triangle they are more than tol above, else to a
    // triangle beyond the horizon they are more than tol above (with the tolerance, a point
    // can be within tol of every new plane yet further outside beyond the horizon).
    std::vector<int> cone(static_cast<std::size_t>(2 * count));
    for (int k = 0; k < count; ++k) {
      cone[static_cast<std::size_t>(k)] = first + k;
      cone[static_cast<std::size_t>(count + k)] = loop[static_cast<std::size_t>(k)].neighbor;
    }
    for (const int t : visible) {
      HullTriangle& tri = tri_[static_cast<std::size_t>(t)];
      tri.alive = false;
      std::vector<int> orphans;
      orphans.swap(tri.outside);
      // An orphan above none of them is set aside as inside (see reassignOutsidePoints).
      for (const int o : orphans)
        if (o != p && !assign(o, cone)) hint_[static_cast<std::size_t>(o)] = first;
      tri.replacement = first;
    }
  }

  /// Chains the horizon edges into one loop; false when they form several loops or a vertex
  /// repeats (the visible set is not a disk).
  static bool orderHorizon(std::vector<HorizonEdge>& horizon, std::vector<HorizonEdge>& loop) {
    if (horizon.size() < 3) return false;
    std::vector<std::pair<int, int>> byStart;  // (a, position in horizon)
    byStart.reserve(horizon.size());
    for (std::size_t i = 0; i < horizon.size(); ++i) byStart.emplace_back(horizon[i].a, static_cast<int>(i));
    std::sort(byStart.begin(), byStart.end());
    for (std::size_t i = 1; i < byStart.size(); ++i)
      if (byStart[i].first == byStart[i - 1].first) return false;
    loop.clear();
    loop.push_back(horizon[0]);
    while (loop.size() < horizon.size()) {
      const auto it = std::lower_bound(byStart.begin(), byStart.end(), std::make_pair(loop.back().b, -1));
      if (it == byStart.end() || it->first != loop.back().b) return false;
      if (it->second == 0) return false;  // closed early: more than one loop
      loop.push_back(horizon[static_cast<std::size_t>(it->second)]);
    }
    return loop.back().b == loop.front().a;
  }

  /// Every cone triangle has a well-defined normal.
  bool coneIsSound(const std::vector<HorizonEdge>& loop, int p) const {
    for (const HorizonEdge& e : loop)
      if (crossOfDifferences(points_[static_cast<std::size_t>(e.a)], points_[static_cast<std::size_t>(e.b)],
                             points_[static_cast<std::size_t>(p)])
              .isZero(0))
        return false;
    return true;
  }

  void dropPoint(int t, int p) {
    HullTriangle& tri = tri_[static_cast<std::size_t>(t)];
    tri.outside.erase(std::find(tri.outside.begin(), tri.outside.end(), p));
    status_[static_cast<std::size_t>(p)] = kDropped;
    tri.furthest = -1;
    tri.furthestDistance = 0;
    for (const int o : tri.outside) {
      const double d = distance(t, o);
      if (tri.furthest < 0 || d > tri.furthestDistance) {
        tri.furthestDistance = d;
        tri.furthest = o;
      }
    }
  }

  /// Exactly: p is above the plane of triangle t (orient3d on the input coordinates).
  bool strictlyAbove(int t, int p) const {
    const auto& v = tri_[static_cast<std::size_t>(t)].v;
    return orient3dBelow(points_[static_cast<std::size_t>(v[0])], points_[static_cast<std::size_t>(v[1])],
                         points_[static_cast<std::size_t>(v[2])], points_[static_cast<std::size_t>(p)]) < 0;
  }

  std::span<const Vector3d> points_;  // as given: the exact predicate uses these
  std::vector<Vector3d> q_;           // points relative to the bounding-box centre
  double tol_;
  std::vector<HullTriangle> tri_;
  std::vector<std::int64_t> visited_;  // per triangle: the search stamp that last reached it
  std::vector<int> pending_;
  std::vector<PointStatus> status_;  // per point
  std::vector<int> hint_;            // per set-aside point: a triangle near it when set aside
  std::int64_t stamp_ = 0;
};

}  // namespace

ConvexHull makeConvexHull(std::span<const Vector3d> points, double tolerance) {
  const int pointCount = static_cast<int>(points.size());
  if (pointCount < 4)
    throw std::invalid_argument("makeConvexHull: needs at least 4 points, got " + std::to_string(pointCount));
  for (int i = 0; i < pointCount; ++i) {
    const Vector3d& p = points[static_cast<std::size_t>(i)];
    if (!p.allFinite())
      throw std::invalid_argument("makeConvexHull: point " + std::to_string(i) + " has a non-finite coordinate (" +
                                  formatNumber(p.x()) + ", " + formatNumber(p.y()) + ", " + formatNumber(p.z()) + ")");
  }
  if (std::isnan(tolerance) || std::isinf(tolerance))
    throw std::invalid_argument("makeConvexHull: tolerance must be finite, got " + formatNumber(tolerance));

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
    return std::invalid_argument(std::string("makeConvexHull: points span no volume (all within ") + formatNumber(tol) +
                                 " of " + what + ")");
  };
  if (!(extent > 0)) throw std::invalid_argument("makeConvexHull: points span no volume (all coincident)");
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
