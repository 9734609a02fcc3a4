// Queries against mesh obstacles (see mesh_queries.hpp).
#include "mesh_queries.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include "closest_point.hpp"
#include "collide/contact_solver.hpp"

namespace weft::detail {

// Unsigned distance to a mesh within `radius` (infinity beyond), with the closest point.
double meshDistance(const MeshCollider& c, V p, double radius, V* closest, Index* triangle) {
  const auto hit = c.bvh.closestTriangle(c.x, e3(p), radius);
  if (!hit) return std::numeric_limits<double>::infinity();
  if (closest) *closest = v3(hit->point);
  if (triangle) *triangle = hit->triangle;
  return std::sqrt(hit->squaredDistance);
}

// First time of impact along b0 -> b1 (body frame) with the mesh thickened by h, to within
// eps, by conservative advancement (the distance is 1-Lipschitz: advancing by the gap never
// passes the surface); 1 (none) when the segment stays farther than h + eps.
double meshImpact(const MeshCollider& c, V b0, V b1, double h, double eps) {
  const V d = b1 - b0;
  const double length = norm(d);
  double s = 0;
  for (int k = 0; k < 64; ++k) {
    const V p = b0 + s * d;
    V q{0, 0, 0};
    const double dist = meshDistance(c, p, h + eps + (1 - s) * length, &q);
    const double gap = dist - h;
    // An impact only while approaching the surface (a particle leaving a resting contact
    // is not stopped; one inside the thickness at x1 is handled as a discrete contact).
    if (gap <= eps) return h > 0 && dist > 0 && dot(d, p - q) >= 0 ? 1 : s;
    if (length == 0 || !std::isfinite(gap)) return 1;
    s += gap / length;
    if (s >= 1) return 1;
  }
  return 1;  // grazing for 64 advances: the segment stays within a hair of h, not inside
}

// Moves p (body frame) out of the thickened mesh to distance h, on the side of `side`.
V pushOutOfMesh(const MeshCollider& c, V p, V side, double h) {
  V q{0, 0, 0};
  const double dist = meshDistance(c, p, h, &q);
  if (!(dist < h)) return p;
  V dir = dist > 0 ? (1 / dist) * (p - q) : side;
  if (dot(dir, side) < 0) dir = -1.0 * dir;  // p crossed the surface: back to the side it came from
  return q + h * dir;
}

// Generalised winding number of a closed mesh about p (1 inside, 0 outside): the sum of the
// triangles' signed solid angles (Van Oosterom and Strackee) over 4 pi.
double windingNumber(const MeshCollider& c, V p) {
  double total = 0;
  for (Index t = 0; t < c.triangles.count(); ++t) {
    const auto corner = [&](Index i) { return V{c.x(i, 0), c.x(i, 1), c.x(i, 2)} - p; };
    const V a = corner(c.triangles.a[t]), b = corner(c.triangles.b[t]), cc = corner(c.triangles.c[t]);
    const double la = norm(a), lb = norm(b), lc = norm(cc);
    const double det =
        a.x * (b.y * cc.z - b.z * cc.y) - a.y * (b.x * cc.z - b.z * cc.x) + a.z * (b.x * cc.y - b.y * cc.x);
    const double div = la * lb * lc + dot(a, b) * lc + dot(b, cc) * la + dot(cc, a) * lb;
    total += 2 * std::atan2(det, div);
  }
  return total / (4 * 3.14159265358979323846);
}

EdgeProbe closestMeshEdge(const MeshCollider& c, V a, V b, const Aabb<double>& box) {
  EdgeProbe best;
  double best2 = std::numeric_limits<double>::infinity();
  if (c.featureEdges.empty()) return best;
  c.bvh.forEachOverlapping(box, [&](Index t) {
    const std::uint8_t mask = c.featureEdges[static_cast<size_t>(t)];
    if (mask == 0) return;
    const Index corner[3] = {c.triangles.a[t], c.triangles.b[t], c.triangles.c[t]};
    for (int k = 0; k < 3; ++k) {
      if (!(mask & (1u << k))) continue;
      const Index u = corner[k], w = corner[(k + 1) % 3];
      const V pu{c.x(u, 0), c.x(u, 1), c.x(u, 2)}, pw{c.x(w, 0), c.x(w, 1), c.x(w, 2)};
      double s, tt;
      V c1, c2;
      const double d2 = closestSegmentSegment(a, b, pu, pw, s, tt, c1, c2);
      if (d2 < best2) {
        best2 = d2;
        best.alpha = s;
        best.onEdge = c1;
        best.onMesh = c2;
      }
    }
  });
  best.distance = std::sqrt(best2);
  return best;
}

// The feature edges of a mesh (see MeshCollider::featureEdges): edges with one face, with
// more than two, or whose two faces' unit normals make an angle of at least `degrees`
// (a face without a normal, of zero area, makes every edge of it a feature).
std::vector<std::uint8_t> featureEdges(const MeshCollider& c, double degrees) {
  const Index nt = c.triangles.count();
  struct Side {
    Index lo, hi, triangle;
    int k;
  };
  std::vector<Side> sides;
  sides.reserve(static_cast<size_t>(3 * nt));
  std::vector<V> normals(static_cast<size_t>(nt));
  for (Index t = 0; t < nt; ++t) {
    const Index corner[3] = {c.triangles.a[t], c.triangles.b[t], c.triangles.c[t]};
    const auto p = [&](Index i) { return V{c.x(i, 0), c.x(i, 1), c.x(i, 2)}; };
    const V e1 = p(corner[1]) - p(corner[0]), e2 = p(corner[2]) - p(corner[0]);
    const V n{e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x};
    const double len = norm(n);
    normals[static_cast<size_t>(t)] = len > 0 ? (1 / len) * n : V{0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      const Index u = corner[k], w = corner[(k + 1) % 3];
      sides.push_back({std::min(u, w), std::max(u, w), t, k});
    }
  }
  std::sort(sides.begin(), sides.end(), [](const Side& a, const Side& b) {
    return std::tie(a.lo, a.hi, a.triangle, a.k) < std::tie(b.lo, b.hi, b.triangle, b.k);
  });
  const double cosLimit = std::cos(degrees * 3.14159265358979323846 / 180);
  std::vector<std::uint8_t> mask(static_cast<size_t>(nt), 0);
  bool any = false;
  for (size_t g = 0; g < sides.size();) {
    size_t e = g + 1;
    while (e < sides.size() && sides[e].lo == sides[g].lo && sides[e].hi == sides[g].hi) ++e;
    bool feature = e - g != 2 || degrees == 0;
    if (!feature) {
      const V n1 = normals[static_cast<size_t>(sides[g].triangle)],
              n2 = normals[static_cast<size_t>(sides[g + 1].triangle)];
      feature = dot(n1, n1) == 0 || dot(n2, n2) == 0 || dot(n1, n2) <= cosLimit;
    }
    if (feature) {
      mask[static_cast<size_t>(sides[g].triangle)] |= static_cast<std::uint8_t>(1u << sides[g].k);
      any = true;
    }
    g = e;
  }
  if (!any) mask.clear();
  return mask;
}

// The corners of a mesh (see MeshCollider::corners): the ends of its feature edges, each
// given to the first triangle that has it.
std::vector<std::uint8_t> cornerMasks(const MeshCollider& c) {
  std::vector<std::uint8_t> mask;
  if (c.featureEdges.empty()) return mask;
  const Index nt = c.triangles.count();
  std::vector<std::uint8_t> corner(static_cast<size_t>(c.x.rows()), 0);  // 1: a corner, 2: given to a triangle
  for (Index t = 0; t < nt; ++t) {
    const Index v[3] = {c.triangles.a[t], c.triangles.b[t], c.triangles.c[t]};
    for (int k = 0; k < 3; ++k)
      if (c.featureEdges[static_cast<size_t>(t)] & (1u << k)) {
        corner[static_cast<size_t>(v[k])] = 1;
        corner[static_cast<size_t>(v[(k + 1) % 3])] = 1;
      }
  }
  mask.assign(c.featureEdges.size(), 0);  // one per triangle
  for (Index t = 0; t < nt; ++t) {
    const Index v[3] = {c.triangles.a[t], c.triangles.b[t], c.triangles.c[t]};
    for (int k = 0; k < 3; ++k)
      if (corner[static_cast<size_t>(v[k])] == 1) {
        corner[static_cast<size_t>(v[k])] = 2;
        mask[static_cast<size_t>(t)] |= static_cast<std::uint8_t>(1u << k);
      }
  }
  return mask;
}

// Deepest penetration (thickness - distance) of the point p at time t over every obstacle:
// negative when clear (minus the smallest gap; -infinity when no mesh is within the thickness).
double pointPenetration(const CollisionOptions& opt, const std::vector<MeshCollider>& meshes, V p, double t) {
  const double h = opt.thickness;
  double deepest = -std::numeric_limits<double>::infinity();
  for (const Obstacle& o : opt.obstacles) {
    V nn;
    deepest = std::max(deepest, h - distance(o, p, nn));
  }
  for (size_t m = 0; m < meshes.size(); ++m)
    deepest = std::max(deepest, h - meshDistance(meshes[m], toBody(opt.meshes[m], p, t), h + opt.epsilon));
  return deepest;
}

// The first contact of the edge a0 -> a1, b0 -> b1 (its ends over the chunk, in the mesh's
// frame) with an edge of the mesh thickened by h: conservative advancement on the distance
// between the segment and the mesh's edges (no point of the segment moves farther than the
// larger end displacement L over the chunk, so advancing by gap / L never passes a contact),
// an impact counting only while the contact point approaches; else a discrete contact at
// the end. Returns the chunk fraction (> 1: none) and fills the probe.
double edgeImpact(const MeshCollider& c, V a0, V a1, V b0, V b1, double h, double eps, EdgeProbe& hit) {
  const V da = a1 - a0, db = b1 - b0;
  const double length = std::max(norm(da), norm(db));
  double s = 0;
  for (int k = 0; k < 64; ++k) {
    const V a = a0 + s * da, b = b0 + s * db;
    const EdgeProbe p = closestMeshEdge(c, a, b, boxAround({a, b, a1, b1}, h + eps));
    const double gap = p.distance - h;
    if (gap <= eps) {
      const V motion = (1 - p.alpha) * da + p.alpha * db;
      if (p.distance > 0 && dot(motion, p.onEdge - p.onMesh) < 0) {
        hit = p;
        return s;
      }
      break;  // moving away from or along the edge it touches (a resting contact): no impact
    }
    if (length == 0 || !std::isfinite(gap)) break;
    s += gap / length;
    if (s >= 1) break;
  }
  const EdgeProbe end = closestMeshEdge(c, a1, b1, boxAround({a1, b1}, h));
  if (end.distance < h && end.distance > 0) {
    hit = end;
    return 1;
  }
  return 2;
}

}  // namespace weft::detail
