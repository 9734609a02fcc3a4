// rigid/quickhull_mesh.hpp (internal, a part of quickhull.cpp) — the triangle mesh
// quickhull grows: conflict lists, the horizon, the cone of new triangles, and the points set
// aside and resumed. Included by quickhull.cpp alone (one translation unit: see
// quickhull_exact.hpp).
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

#include "quickhull_exact.hpp"

namespace weft {
namespace {

using Eigen::Vector3d;

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
}  // namespace weft
