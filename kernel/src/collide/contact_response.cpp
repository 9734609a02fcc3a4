// Contact detection against the obstacles and the response to a contact (see
// contact_response.hpp).
#include "contact_response.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "collide/contact_solver.hpp"
#include "mesh_queries.hpp"

namespace weft::detail {

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
V respondAnalytic(const CollisionOptions& opt, const Contact& c, V p0, V p1, V& vel, V& normal) {
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
  normal = nrm;
  return p;
}

// Response to mesh m hit at s along p0 -> p1 (world, chunk t0 -> t1): the same steps as
// respondAnalytic in the mesh's frame, with the velocity taken relative to the surface.
V respondMesh(const CollisionOptions& opt, const MeshObstacle& m, const MeshCollider& c, double s, V p0, V p1,
              double t0, double t1, V& vel, V& normal) {
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
  normal = nw;
  return toWorld(m, pb, t1);
}

}  // namespace weft::detail
