#include "weft/collide/obstacles.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "weft/collide/shapes.hpp"

namespace weft {

namespace {

struct V {
  double x, y, z;
};
inline V operator+(V a, V b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V operator-(V a, V b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V operator*(double s, V a) { return {s * a.x, s * a.y, s * a.z}; }
inline double dot(V a, V b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline double norm(V a) { return std::sqrt(dot(a, a)); }
inline V v(const Vec3d& a) { return {a.x, a.y, a.z}; }

// Signed distance and outward normal (unit) of each shape at p.
double distance(const Obstacle& o, V p, V& n) {
  switch (o.kind) {
    case ObstacleKind::Plane: {
      const V nn = v(o.normal);
      const double len = norm(nn);
      n = (1 / len) * nn;
      return dot(p - v(o.point), n);
    }
    case ObstacleKind::Sphere: {
      const V d = p - v(o.point);
      const double len = norm(d);
      n = len > 0 ? (1 / len) * d : V{0, 1, 0};
      return len - o.radius;
    }
    case ObstacleKind::Capsule: {
      const V a = v(o.point), ab = v(o.end) - a;
      const double ll = dot(ab, ab);
      const double t = ll > 0 ? std::clamp(dot(p - a, ab) / ll, 0.0, 1.0) : 0.0;
      const V d = p - (a + t * ab);
      const double len = norm(d);
      n = len > 0 ? (1 / len) * d : V{0, 1, 0};
      return len - o.radius;
    }
    case ObstacleKind::Box: {
      // Rounded box: the box shrunk by the rounding radius, then inflated by it.
      const V c = v(o.point);
      const double r = o.radius;
      const V e{o.halfExtents.x - r, o.halfExtents.y - r, o.halfExtents.z - r};
      const V d = p - c;
      const V q{std::abs(d.x) - e.x, std::abs(d.y) - e.y, std::abs(d.z) - e.z};
      const V outside{std::max(q.x, 0.0), std::max(q.y, 0.0), std::max(q.z, 0.0)};
      const double lo = norm(outside);
      const double inside = std::min(std::max(q.x, std::max(q.y, q.z)), 0.0);
      if (lo > 0) {
        n = (1 / lo) * V{std::copysign(outside.x, d.x), std::copysign(outside.y, d.y), std::copysign(outside.z, d.z)};
      } else {  // inside the core box: the face of least penetration
        if (q.x >= q.y && q.x >= q.z)
          n = {std::copysign(1.0, d.x), 0, 0};
        else if (q.y >= q.z)
          n = {0, std::copysign(1.0, d.y), 0};
        else
          n = {0, 0, std::copysign(1.0, d.z)};
      }
      return lo + inside - r;
    }
  }
  n = {0, 1, 0};
  return std::numeric_limits<double>::infinity();
}

// What the per-particle pass found for one particle.
struct Contact {
  bool found = false;
  bool continuous = false;  // found by continuous detection only (x1 itself was clear)
  double depth = 0;         // thickness - distance at x1 for discrete contacts
  double s = 1;             // time of impact along x0 -> x1
  const Obstacle* obstacle = nullptr;
  Index mesh = -1;  // or the mesh obstacle hit
};

// Discrete contacts of x1, and with `continuous` the first time of impact along x0 -> x1.
Contact detect(const CollisionOptions& opt, V p0, V p1) {
  Contact best;
  const double h = opt.thickness, eps = opt.epsilon;
  const V d = p1 - p0;
  const double length = norm(d);
  for (const Obstacle& o : opt.obstacles) {
    V n;
    const double phi1 = distance(o, p1, n);
    if (phi1 < h) {  // discrete contact at the end of the chunk
      const double phi0 = distance(o, p0, n);
      double s = 0;
      if (phi0 >= h && length > 0) {
        // Time of impact by bisection: phi(x(lo)) >= h > phi(x(hi)), until the bracket
        // is within epsilon of the thickened surface.
        double lo = 0, hi = 1;
        for (int k = 0; k < 60 && (hi - lo) * length > eps; ++k) {
          const double mid = 0.5 * (lo + hi);
          (distance(o, p0 + mid * d, n) >= h ? lo : hi) = mid;
        }
        s = lo;
      }
      if (!best.found || s < best.s || (s == best.s && h - phi1 > best.depth)) {
        best.found = true;
        best.continuous = false;
        best.s = s;
        best.depth = std::max(best.depth, h - phi1);
        best.obstacle = &o;
      }
      continue;
    }
    if (!opt.continuous || length == 0) continue;
    // x1 is clear; did the segment pass through? Conservative advancement: phi is
    // 1-Lipschitz, so moving (phi - h) along the segment never crosses the surface.
    double s = 0;
    for (int k = 0; k < 64 && s < 1; ++k) {
      const double gap = distance(o, p0 + s * d, n) - h;
      if (gap <= eps) {
        // Started inside (pushed out when x1 is), or moving away from the surface here (a
        // particle leaving a resting contact): not an impact.
        if ((gap < 0 && s == 0) || dot(d, n) >= 0) s = 1;
        break;
      }
      s += gap / length;
    }
    if (s < 1 && (!best.found || s < best.s)) {
      best.found = true;
      best.continuous = true;
      best.s = s;
      best.obstacle = &o;
    }
  }
  return best;
}

inline Vec3<double> e3(V a) { return {a.x, a.y, a.z}; }
inline V v3(const Vec3<double>& a) { return {a[0], a[1], a[2]}; }
inline Vec3d d3(V a) { return {a.x, a.y, a.z}; }

// A point in a mesh obstacle's frame (where it was at time 0) and back.
V toBody(const MeshObstacle& m, V p, double t) { return m.path ? v(kinematicInverse(*m.path, d3(p), t)) : p; }
V toWorld(const MeshObstacle& m, V p, double t) { return m.path ? v(kinematicPosition(*m.path, d3(p), t)) : p; }

// Unsigned distance to a mesh within `radius` (infinity beyond), with the closest point.
double meshDistance(const MeshCollider& c, V p, double radius, V* closest = nullptr, Index* triangle = nullptr) {
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

// The friction and restitution of a contact, and the response to it.
struct Surface {
  double restitution, staticFriction, kineticFriction;
};
Surface surface(const Obstacle& o) { return {o.restitution, o.staticFriction, o.kineticFriction}; }
Surface surface(const MeshObstacle& m) { return {m.restitution, m.staticFriction, m.kineticFriction}; }

// Velocity response at a contact with normal n (see the header): restitution above the
// resting speed, Coulomb friction with the normal impulse. Returns the factor applied to the
// tangential velocity (0: static friction), which the position response reuses.
double respondVelocity(const Surface& o, double restingSpeed, V n, V& vel) {
  const double vn = dot(vel, n);
  if (vn >= 0) return 1;  // separating
  const double e = -vn > restingSpeed ? o.restitution : 0.0;
  const double dvn = -(1 + e) * vn;
  const V vt = vel - vn * n;
  const double st = norm(vt);
  double factor = 0;
  if (st > o.staticFriction * dvn) factor = std::max(0.0, 1 - o.kineticFriction * dvn / st);
  vel = factor * vt + (-e * vn) * n;
  return factor;
}

// Response to an analytic obstacle's contact c of the chunk p0 -> p1: returns the new
// position, updates vel.
V respondAnalytic(const CollisionOptions& opt, const Contact& c, V p0, V p1, V& vel) {
  const double h = opt.thickness;
  const Obstacle& o = *c.obstacle;
  V p = p1, nrm;
  if (c.continuous || c.s > 0) {
    // Put at the impact point, then slide by the tangential rest of the motion.
    const V hit = p0 + c.s * (p1 - p0);
    distance(o, hit, nrm);
    const V rest = (1 - c.s) * (p1 - p0);
    p = hit + (rest - dot(rest, nrm) * nrm);
  }
  // Out of this obstacle along its normal (the slide may end inside a curved surface).
  double phi = distance(o, p, nrm);
  if (phi < h) p = p + (h - phi) * nrm;
  distance(o, p, nrm);
  const double factor = respondVelocity(surface(o), opt.restingSpeed, nrm, vel);
  // Friction acts on this chunk's tangential motion too: static friction keeps the
  // particle where it was along the surface (no creep), kinetic friction shortens the slide.
  if (factor < 1) {
    const V moved = p - p0;
    const V tangential = moved - dot(moved, nrm) * nrm;
    p = p - (1 - factor) * tangential;
    phi = distance(o, p, nrm);
    if (phi < h) p = p + (h - phi) * nrm;
  }
  return p;
}

// Response to mesh m hit at s along p0 -> p1 (world, chunk t0 -> t1): the same steps as
// respondAnalytic in the mesh's frame, with the velocity taken relative to the surface.
V respondMesh(const CollisionOptions& opt, const MeshObstacle& m, const MeshCollider& c, double s, V p0, V p1,
              double t0, double t1, V& vel) {
  const double h = opt.thickness;
  const V b0 = toBody(m, p0, t0), b1 = toBody(m, p1, t1), d = b1 - b0;
  const V hit = b0 + s * d;
  V q{0, 0, 0};
  Index tri = -1;
  // The hit point is within h + eps of the mesh (continuous), or b0, within h + |d| (x1 is
  // within h): look no farther, unless rounding says otherwise.
  double dist = meshDistance(c, hit, h + opt.epsilon + norm(d) + 1e-9, &q, &tri);
  if (tri < 0) dist = meshDistance(c, hit, std::numeric_limits<double>::infinity(), &q, &tri);
  V n;
  if (dist > 1e-9 * h) {
    n = (1 / dist) * (hit - q);
  } else {  // on the surface: the face normal, towards where the particle came from
    const Index ia = c.triangles.a[tri], ib = c.triangles.b[tri], ic = c.triangles.c[tri];
    const V a{c.x(ia, 0), c.x(ia, 1), c.x(ia, 2)}, bb{c.x(ib, 0), c.x(ib, 1), c.x(ib, 2)},
        cc{c.x(ic, 0), c.x(ic, 1), c.x(ic, 2)};
    const V e1 = bb - a, e2 = cc - a;
    V fn{e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x};
    const double len = norm(fn);
    fn = len > 0 ? (1 / len) * fn : V{0, 1, 0};
    n = dot(b0 - q, fn) >= 0 ? fn : -1.0 * fn;
  }
  const V rest = (1 - s) * d;
  V pb = pushOutOfMesh(c, hit + (rest - dot(rest, n) * n), n, h);
  // Velocity relative to the surface point under the contact.
  const V qEnd = toWorld(m, q, t1);
  const V surfaceVelocity = m.path && t1 > t0 ? (1 / (t1 - t0)) * (qEnd - toWorld(m, q, t0)) : V{0, 0, 0};
  const V nw = m.path ? v(kinematicRotate(*m.path, d3(n), t1)) : n;
  V relative = vel - surfaceVelocity;
  const double factor = respondVelocity(surface(m), opt.restingSpeed, nw, relative);
  vel = relative + surfaceVelocity;
  if (factor < 1) {
    const V moved = pb - b0;
    const V tangential = moved - dot(moved, n) * n;
    pb = pushOutOfMesh(c, pb - (1 - factor) * tangential, n, h);
  }
  return toWorld(m, pb, t1);
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

// Closest points of the segments p1 q1 and p2 q2 (Ericson, Real-Time Collision Detection,
// 5.1.9): parameters s, t in [0, 1] and the points c1, c2; returns the squared distance.
double closestSegmentSegment(V p1, V q1, V p2, V q2, double& s, double& t, V& c1, V& c2) {
  const V d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = dot(d1, d1), e = dot(d2, d2), f = dot(d2, r);
  if (a == 0 && e == 0) {
    s = t = 0;
  } else if (a == 0) {
    s = 0;
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = dot(d1, r);
    if (e == 0) {
      t = 0;
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = dot(d1, d2), denom = a * e - b * b;
      s = denom > 0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;  // parallel: any s, take 0
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
  return dot(c1 - c2, c1 - c2);
}

// The mesh edge closest to the segment A B, among the triangles whose boxes overlap `box`.
struct EdgeProbe {
  double distance = std::numeric_limits<double>::infinity();
  double alpha = 0;   // along A B
  V onEdge{0, 0, 0};  // on A B
  V onMesh{0, 0, 0};  // on the mesh edge
};
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

// The box around points p[0..3], grown by r.
Aabb<double> boxAround(std::initializer_list<V> points, double r) {
  Aabb<double> box{{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                    std::numeric_limits<double>::infinity()},
                   {-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                    -std::numeric_limits<double>::infinity()}};
  for (const V& p : points) {
    const double c[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k) {
      box.lo[k] = std::min(box.lo[k], c[k] - r);
      box.hi[k] = std::max(box.hi[k], c[k] + r);
    }
  }
  return box;
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

}  // namespace

const char* obstacleKindName(ObstacleKind kind) {
  switch (kind) {
    case ObstacleKind::Plane:
      return "plane";
    case ObstacleKind::Sphere:
      return "sphere";
    case ObstacleKind::Capsule:
      return "capsule";
    case ObstacleKind::Box:
      return "box";
  }
  return "unknown";
}

Obstacle Obstacle::plane(const Vec3d& p, const Vec3d& n) {
  Obstacle o;
  o.kind = ObstacleKind::Plane;
  o.point = p;
  o.normal = n;
  return o;
}
Obstacle Obstacle::sphere(const Vec3d& c, double r) {
  Obstacle o;
  o.kind = ObstacleKind::Sphere;
  o.point = c;
  o.radius = r;
  return o;
}
Obstacle Obstacle::capsule(const Vec3d& a, const Vec3d& b, double r) {
  Obstacle o;
  o.kind = ObstacleKind::Capsule;
  o.point = a;
  o.end = b;
  o.radius = r;
  return o;
}
Obstacle Obstacle::box(const Vec3d& c, const Vec3d& e) {
  Obstacle o;
  o.kind = ObstacleKind::Box;
  o.point = c;
  o.halfExtents = e;
  o.radius = 0;
  return o;
}

double obstacleDistance(const Obstacle& o, const Vec3d& x, Vec3d* normal) {
  V n;
  const double phi = distance(o, v(x), n);
  if (normal) *normal = {n.x, n.y, n.z};
  return phi;
}

CollisionStats& CollisionStats::operator+=(const CollisionStats& o) {
  contacts += o.contacts;
  continuousHits += o.continuousHits;
  edgeContacts += o.edgeContacts;
  rollbacks += o.rollbacks;
  acceptedDeep += o.acceptedDeep;
  maxPenetration = std::max(maxPenetration, o.maxPenetration);
  return *this;
}

void validateCollision(const CollisionOptions& c, const char* where) {
  const std::string w = std::string(where) + ".";
  const auto fail = [&](const std::string& field, double value, const char* rule) {
    std::ostringstream msg;
    msg.precision(17);
    msg << w << field << " must be " << rule << ", got " << value;
    throw std::invalid_argument(msg.str());
  };
  const auto finite = [&](const std::string& field, const Vec3d& p) {
    if (!std::isfinite(p.x)) fail(field + ".x", p.x, "finite");
    if (!std::isfinite(p.y)) fail(field + ".y", p.y, "finite");
    if (!std::isfinite(p.z)) fail(field + ".z", p.z, "finite");
  };
  if (!(std::isfinite(c.thickness) && c.thickness > 0)) fail("thickness", c.thickness, "finite and > 0 (m)");
  if (!(std::isfinite(c.epsilon) && c.epsilon > 0 && c.epsilon < c.thickness))
    fail("epsilon", c.epsilon, "finite, > 0 and < thickness (m)");
  if (!(std::isfinite(c.restingSpeed) && c.restingSpeed >= 0)) fail("restingSpeed", c.restingSpeed, "finite and >= 0");
  if (!(std::isfinite(c.maxPenetration) && c.maxPenetration >= 0))
    fail("maxPenetration", c.maxPenetration, "finite and >= 0 (m)");
  if (!(c.maxHalvings >= 0 && c.maxHalvings <= 30)) fail("maxHalvings", c.maxHalvings, "in [0, 30]");
  if (!(c.featureAngle >= 0 && c.featureAngle <= 180)) fail("featureAngle", c.featureAngle, "in [0, 180] (degrees)");
  for (size_t k = 0; k < c.obstacles.size(); ++k) {
    const Obstacle& o = c.obstacles[k];
    const std::string f = "obstacles[" + std::to_string(k) + "].";
    finite(f + "point", o.point);
    if (!(std::isfinite(o.restitution) && o.restitution >= 0 && o.restitution <= 1))
      fail(f + "restitution", o.restitution, "in [0, 1]");
    if (!(std::isfinite(o.staticFriction) && o.staticFriction >= 0))
      fail(f + "staticFriction", o.staticFriction, "finite and >= 0");
    if (!(std::isfinite(o.kineticFriction) && o.kineticFriction >= 0 && o.kineticFriction <= o.staticFriction))
      fail(f + "kineticFriction", o.kineticFriction, "finite, >= 0 and <= staticFriction");
    switch (o.kind) {
      case ObstacleKind::Plane:
        finite(f + "normal", o.normal);
        if (!(norm(v(o.normal)) > 0)) fail(f + "normal", 0, "a non-zero vector (length)");
        break;
      case ObstacleKind::Capsule:
        finite(f + "end", o.end);
        [[fallthrough]];
      case ObstacleKind::Sphere:
        if (!(std::isfinite(o.radius) && o.radius > 0)) fail(f + "radius", o.radius, "finite and > 0 (m)");
        break;
      case ObstacleKind::Box: {
        finite(f + "halfExtents", o.halfExtents);
        const double smallest = std::min({o.halfExtents.x, o.halfExtents.y, o.halfExtents.z});
        if (!(smallest > 0)) fail(f + "halfExtents", smallest, "> 0 in every axis (smallest)");
        if (!(std::isfinite(o.radius) && o.radius >= 0 && o.radius <= smallest))
          fail(f + "radius", o.radius, "finite, >= 0 and <= the smallest half extent (edge rounding)");
        break;
      }
    }
  }
  for (size_t k = 0; k < c.meshes.size(); ++k) {
    const MeshObstacle& m = c.meshes[k];
    const std::string f = "meshes[" + std::to_string(k) + "]" + (m.name.empty() ? "" : " (" + m.name + ")") + ".";
    if (m.mesh.triangles.empty()) throw std::invalid_argument(w + f + "mesh must have at least one triangle, got none");
    for (size_t i = 0; i < m.mesh.vertices.size(); ++i)
      finite(f + "mesh.vertices[" + std::to_string(i) + "]", m.mesh.vertices[i]);
    const auto count = static_cast<Index>(m.mesh.vertices.size());
    for (size_t t = 0; t < m.mesh.triangles.size(); ++t)
      for (int q = 0; q < 3; ++q)
        if (m.mesh.triangles[t][q] < 0 || m.mesh.triangles[t][q] >= count)
          fail(f + "mesh.triangles[" + std::to_string(t) + "][" + std::to_string(q) + "]", m.mesh.triangles[t][q],
               "a vertex index in [0, vertex count)");
    if (!(std::isfinite(m.restitution) && m.restitution >= 0 && m.restitution <= 1))
      fail(f + "restitution", m.restitution, "in [0, 1]");
    if (!(std::isfinite(m.staticFriction) && m.staticFriction >= 0))
      fail(f + "staticFriction", m.staticFriction, "finite and >= 0");
    if (!(std::isfinite(m.kineticFriction) && m.kineticFriction >= 0 && m.kineticFriction <= m.staticFriction))
      fail(f + "kineticFriction", m.kineticFriction, "finite, >= 0 and <= staticFriction");
    if (m.path) validateKinematicPath(*m.path, w + f + "path.");
  }
}

template <class S>
ContactSolver<S>::ContactSolver(const CollisionOptions& options, Index particleCount, std::vector<Edge> edges)
    : options_(options) {
  validateCollision(options_);
  for (size_t k = 0; k < edges.size(); ++k)
    for (const Index i : edges[k])
      if (i < 0 || i >= particleCount)
        throw std::invalid_argument("ContactSolver: edges[" + std::to_string(k) + "] has particle " +
                                    std::to_string(i) + ", not in [0, " + std::to_string(particleCount) + ")");
  if (options_.continuous && options_.edges && !options_.meshes.empty()) {
    edges_ = std::move(edges);
    edgeHits_.resize(edges_.size());
  }
  if (options_.maxPenetration == 0) options_.maxPenetration = 0.5 * options_.thickness;
  const Index blocks = Executor::blockCount(particleCount, kGrain);
  blockDepth_.assign(static_cast<size_t>(blocks), 0.0);
  blockHits_.assign(static_cast<size_t>(blocks), 0);
  blockCcd_.assign(static_cast<size_t>(blocks), 0);
  if (options_.meshes.empty()) return;
  // No clearance known yet: -infinity, so that every particle is tested first.
  clearance_.assign(options_.meshes.size() * static_cast<size_t>(particleCount) * 4,
                    -std::numeric_limits<double>::infinity());
  const Executor serial(1);
  meshes_.resize(options_.meshes.size());
  for (size_t k = 0; k < options_.meshes.size(); ++k) {
    MeshCollider& c = meshes_[k];
    c.x = meshPositions<double>(options_.meshes[k].mesh);
    c.triangles = meshTriangles(options_.meshes[k].mesh);
    c.bvh.build(c.x, c.triangles, serial);
    MeshReport report;
    cleanMesh(options_.meshes[k].mesh, MeshCleanOptions{0}, &report);
    c.closed = report.boundaryEdges == 0 && report.nonManifoldEdges == 0;
    if (!edges_.empty()) c.featureEdges = featureEdges(c, options_.featureAngle);
  }
  // The edge pass needs a mesh with feature edges.
  if (std::none_of(meshes_.begin(), meshes_.end(), [](const MeshCollider& c) { return !c.featureEdges.empty(); })) {
    edges_.clear();
    edgeHits_.clear();
  }
}

namespace {

template <class S>
V row(const Vec3Array<S>& x, Index i) {
  return {double(x(i, 0)), double(x(i, 1)), double(x(i, 2))};
}
template <class S>
void setRow(Vec3Array<S>& x, Index i, V p) {
  x(i, 0) = static_cast<S>(p.x);
  x(i, 1) = static_cast<S>(p.y);
  x(i, 2) = static_cast<S>(p.z);
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

}  // namespace

namespace {

// The clearance record of particle i against mesh m (see ContactSolver::clearance_).
inline double* clearanceOf(std::vector<double>& clearance, size_t m, Index i, Index n) {
  return clearance.data() + 4 * (m * static_cast<size_t>(n) + static_cast<size_t>(i));
}
// The lower bound on the distance to the mesh of every point within `reach` of p.
inline double clearanceBound(const double* c, V p, double reach) {
  return c[3] - norm(p - V{c[0], c[1], c[2]}) - reach;
}

}  // namespace

template <class S>
double ContactSolver<S>::deepestPenetration(const Vec3Array<S>& x1, const ScalarArray<S>& w, double t1,
                                            const Executor& exec) {
  const Index n = static_cast<Index>(x1.rows());
  const double h = options_.thickness, eps = options_.epsilon;
  exec.parallelForBlocks(n, kGrain, [&](Index block, Index b, Index e) {
    double deepest = 0;
    for (Index i = b; i < e; ++i) {
      if (w[i] == S(0)) continue;
      const V p = row(x1, i);
      for (const Obstacle& o : options_.obstacles) {
        V nn;
        deepest = std::max(deepest, h - distance(o, p, nn));
      }
      for (size_t m = 0; m < meshes_.size(); ++m) {
        const V bp = toBody(options_.meshes[m], p, t1);
        if (clearanceBound(clearanceOf(clearance_, m, i, n), bp, 0) > h + 2 * eps) continue;  // farther than h
        deepest = std::max(deepest, h - meshDistance(meshes_[m], bp, h + eps));
      }
    }
    blockDepth_[block] = deepest;
  });
  double deepest = 0;
  for (Index k = 0; k < Executor::blockCount(n, kGrain); ++k) deepest = std::max(deepest, blockDepth_[k]);
  return deepest;
}

template <class S>
CollisionStats ContactSolver<S>::resolve(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1,
                                         const ScalarArray<S>& w, double t0, double t1, const Executor& exec) {
  const Index n = static_cast<Index>(x1.rows());
  const double h = options_.thickness, eps = options_.epsilon;
  exec.parallelForBlocks(n, kGrain, [&](Index block, Index b, Index e) {
    std::int64_t hits = 0, ccd = 0;
    double deepest = 0;
    for (Index i = b; i < e; ++i) {
      if (w[i] == S(0)) continue;
      const V p0 = row(x0, i), p1 = row(x1, i);
      Contact c = detect(options_, p0, p1);
      // Mesh obstacles: the first impact along the segment in each mesh's frame; without
      // continuous detection only when x1 itself is within the thickness.
      for (size_t m = 0; m < meshes_.size(); ++m) {
        const MeshObstacle& mo = options_.meshes[m];
        const V b0 = toBody(mo, p0, t0), b1 = toBody(mo, p1, t1);
        double* clear = clearanceOf(clearance_, m, i, n);
        const double length = norm(b1 - b0);
        // The whole chunk farther than the thickness from the mesh (every point of it is
        // within `length` of b1): nothing to find, as the queries below would confirm.
        if (clearanceBound(clear, b1, length) > h + 2 * eps) continue;
        // The distance at b1, looked up a little farther than needed (8 thicknesses) so
        // that it tells the next chunks to skip too.
        const double reach = 9 * h + eps + length;
        const double d1 = meshDistance(meshes_[m], b1, reach);
        clear[0] = b1.x;
        clear[1] = b1.y;
        clear[2] = b1.z;
        clear[3] = std::min(d1, reach);
        const double depth = h - d1;
        if (depth <= 0 && !options_.continuous) continue;
        if (depth <= 0 && d1 - length > h + 2 * eps) continue;  // the segment stays clear
        const double s = meshImpact(meshes_[m], b0, b1, h, eps);
        if (s >= 1 && depth <= 0) continue;
        const double at = std::min(s, 1.0);
        if (!c.found || at < c.s || (at == c.s && depth > c.depth)) {
          c.found = true;
          c.continuous = depth <= 0;
          c.s = at < 1 ? at : 0;  // within the thickness at x1 only (a slow approach inside): push out from x1
          c.depth = std::max(depth, 0.0);
          c.obstacle = nullptr;
          c.mesh = static_cast<Index>(m);
        }
      }
      if (!c.found) continue;
      ++hits;
      ccd += c.continuous ? 1 : 0;
      deepest = std::max(deepest, c.depth);
      V vel = row(v1, i);
      const V p = c.obstacle ? respondAnalytic(options_, c, p0, p1, vel)
                             : respondMesh(options_, options_.meshes[static_cast<size_t>(c.mesh)],
                                           meshes_[static_cast<size_t>(c.mesh)], c.s, p0, p1, t0, t1, vel);
      setRow(x1, i, p);
      setRow(v1, i, vel);
    }
    blockHits_[block] = hits;
    blockCcd_[block] = ccd;
    blockDepth_[block] = deepest;
  });
  CollisionStats stats;
  for (Index k = 0; k < Executor::blockCount(n, kGrain); ++k) {
    stats.contacts += blockHits_[k];
    stats.continuousHits += blockCcd_[k];
    stats.maxPenetration = std::max(stats.maxPenetration, blockDepth_[k]);
  }
  if (!edges_.empty()) stats.edgeContacts = resolveEdges(x0, x1, v1, w, t0, t1, exec);
  return stats;
}

template <class S>
std::int64_t ContactSolver<S>::resolveEdges(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1,
                                            const ScalarArray<S>& w, double t0, double t1, const Executor& exec) {
  // Detection, per edge and in parallel, on the particles' resolved motion x0 -> x1: the
  // earliest contact over the mesh obstacles.
  const double h = options_.thickness, eps = options_.epsilon;
  const auto edgeCount = static_cast<Index>(edges_.size());
  exec.parallelForBlocks(edgeCount, kGrain, [&](Index, Index b, Index e) {
    for (Index k = b; k < e; ++k) {
      EdgeHit& record = edgeHits_[static_cast<size_t>(k)];
      record.mesh = -1;
      const auto [i, j] = edges_[static_cast<size_t>(k)];
      if (w[i] == S(0) && w[j] == S(0)) continue;
      const V pi0 = row(x0, i), pi1 = row(x1, i), pj0 = row(x0, j), pj1 = row(x1, j);
      double first = 2;
      for (size_t m = 0; m < meshes_.size(); ++m) {
        const MeshObstacle& mo = options_.meshes[m];
        EdgeProbe probe;
        const double s = edgeImpact(meshes_[m], toBody(mo, pi0, t0), toBody(mo, pi1, t1), toBody(mo, pj0, t0),
                                    toBody(mo, pj1, t1), h, eps, probe);
        if (!(s < first)) continue;
        first = s;
        const V n = (1 / probe.distance) * (probe.onEdge - probe.onMesh);
        record.mesh = static_cast<int>(m);
        record.alpha = probe.alpha;
        record.point[0] = probe.onMesh.x;
        record.point[1] = probe.onMesh.y;
        record.point[2] = probe.onMesh.z;
        record.normal[0] = n.x;
        record.normal[1] = n.y;
        record.normal[2] = n.z;
      }
    }
  });
  // Response, serially in edge order (edges share particles): the contact point of the
  // edge, at alpha between its ends, goes back to the thickness along the normal, and its
  // velocity relative to the mesh gets the contact's restitution and friction; both
  // changes are shared by the two ends in proportion to their inverse masses (the
  // point's change is exactly the one asked for).
  std::int64_t hits = 0;
  for (Index k = 0; k < edgeCount; ++k) {
    const EdgeHit& r = edgeHits_[static_cast<size_t>(k)];
    if (r.mesh < 0) continue;
    const auto [i, j] = edges_[static_cast<size_t>(k)];
    const MeshObstacle& mo = options_.meshes[static_cast<size_t>(r.mesh)];
    const double wi = static_cast<double>(w[i]), wj = static_cast<double>(w[j]), al = r.alpha;
    const double weight = (1 - al) * (1 - al) * wi + al * al * wj;
    if (!(weight > 0)) continue;  // the contact point sits on a pinned end
    ++hits;
    const V n{r.normal[0], r.normal[1], r.normal[2]}, q{r.point[0], r.point[1], r.point[2]};
    V a = toBody(mo, row(x1, i), t1), b = toBody(mo, row(x1, j), t1);
    const double separation = dot((1 - al) * a + al * b - q, n);
    if (separation < h) {
      const double lambda = (h - separation) / weight;
      a = a + (lambda * (1 - al) * wi) * n;
      b = b + (lambda * al * wj) * n;
    }
    const V qEnd = toWorld(mo, q, t1);
    const V surfaceVelocity = mo.path && t1 > t0 ? (1 / (t1 - t0)) * (qEnd - toWorld(mo, q, t0)) : V{0, 0, 0};
    const V nw = mo.path ? v(kinematicRotate(*mo.path, d3(n), t1)) : n;
    const V vi = row(v1, i), vj = row(v1, j);
    const V relative = (1 - al) * vi + al * vj - surfaceVelocity;
    V after = relative;
    const double factor = respondVelocity(surface(mo), options_.restingSpeed, nw, after);
    const V change = after - relative;
    const V vi1 = vi + ((1 - al) * wi / weight) * change, vj1 = vj + (al * wj / weight) * change;
    if (factor < 1) {
      // Friction on the contact point's tangential motion over the chunk, as for a particle.
      const V start = (1 - al) * toBody(mo, row(x0, i), t0) + al * toBody(mo, row(x0, j), t0);
      const V moved = (1 - al) * a + al * b - start;
      const V slide = (-(1 - factor)) * (moved - dot(moved, n) * n);
      a = a + ((1 - al) * wi / weight) * slide;
      b = b + (al * wj / weight) * slide;
    }
    const V ai = toWorld(mo, a, t1), bj = toWorld(mo, b, t1);
    if (wi > 0) {
      setRow(x1, i, ai);
      setRow(v1, i, vi1);
    }
    if (wj > 0) {
      setRow(x1, j, bj);
      setRow(v1, j, vj1);
    }
  }
  return hits;
}

template <class S>
std::int64_t ContactSolver<S>::countContacts(const Vec3Array<S>& x, const ScalarArray<S>& w, double t) const {
  std::int64_t count = 0;
  for (Index i = 0; i < static_cast<Index>(x.rows()); ++i)
    if (w[i] != S(0) && pointPenetration(options_, meshes_, row(x, i), t) > -options_.epsilon) ++count;
  return count;
}

template <class S>
double ContactSolver<S>::penetration(const Vec3Array<S>& x, const ScalarArray<S>& w, double t) const {
  double deepest = 0;
  for (Index i = 0; i < static_cast<Index>(x.rows()); ++i)
    if (w[i] != S(0)) deepest = std::max(deepest, pointPenetration(options_, meshes_, row(x, i), t));
  return deepest;
}

template <class S>
std::int64_t ContactSolver<S>::countTunnelled(const Vec3Array<S>& start, const Vec3Array<S>& end,
                                              const ScalarArray<S>& w, double t0, double t1) const {
  std::int64_t count = 0;
  for (Index i = 0; i < static_cast<Index>(end.rows()); ++i) {
    if (w[i] == S(0)) continue;
    const V a = row(start, i), b = row(end, i);
    bool tunnelled = false;
    for (const Obstacle& o : options_.obstacles) {
      V nn;
      if (distance(o, b, nn) < 0) tunnelled = true;  // ended inside
      if (o.kind != ObstacleKind::Box) continue;
      // Thinnest axis of the box: opposite sides along it, within the other two extents.
      const double ex[3] = {o.halfExtents.x, o.halfExtents.y, o.halfExtents.z};
      const int axis = ex[0] <= ex[1] && ex[0] <= ex[2] ? 0 : (ex[1] <= ex[2] ? 1 : 2);
      const double ca[3] = {a.x - o.point.x, a.y - o.point.y, a.z - o.point.z};
      const double cb[3] = {b.x - o.point.x, b.y - o.point.y, b.z - o.point.z};
      bool within = true;
      for (int k = 0; k < 3; ++k)
        if (k != axis) within = within && std::abs(cb[k]) <= ex[k] && std::abs(ca[k]) <= ex[k];
      if (within && ((ca[axis] < -ex[axis] && cb[axis] > ex[axis]) || (ca[axis] > ex[axis] && cb[axis] < -ex[axis])))
        tunnelled = true;
    }
    for (size_t m = 0; m < meshes_.size() && !tunnelled; ++m) {
      const MeshObstacle& mo = options_.meshes[m];
      const V bb = toBody(mo, b, t1);
      if (meshes_[m].closed)
        tunnelled = windingNumber(meshes_[m], bb) > 0.5;  // ended inside
      else                                                // the straight path from start to end goes through the sheet
        tunnelled = meshImpact(meshes_[m], toBody(mo, a, t0), bb, 0.0, 1e-9 * options_.thickness) < 1 &&
                    meshDistance(meshes_[m], bb, options_.thickness) > 0.5 * options_.thickness &&
                    meshDistance(meshes_[m], toBody(mo, a, t0), options_.thickness) > 0.5 * options_.thickness;
    }
    count += tunnelled ? 1 : 0;
  }
  return count;
}

template class ContactSolver<float>;
template class ContactSolver<double>;

}  // namespace weft
