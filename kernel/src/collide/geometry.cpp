#include "collide/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "closest_point.hpp"

namespace weft {

namespace {

using V = Vec3<double>;

// ---- forward error bounds (Shewchuk 1997, for this evaluation order; doubled) ---------

constexpr double kUnit = std::numeric_limits<double>::epsilon() / 2;  // 2^-53
constexpr double kOrient2dBound = 2 * (3.0 + 16.0 * kUnit) * kUnit;
constexpr double kOrient3dBound = 2 * (7.0 + 56.0 * kUnit) * kUnit;
// kZeroPermanent: when every computed product of differences is zero, so is every exact
// one (a computed difference is zero only for equal operands, and a product of non-zero
// doubles is non-zero without underflow), hence the determinant: no exact evaluation is
// needed. This makes triangles in a coordinate plane (a flat cloth) as cheap as any.

// ---- floating-point expansions --------------------------------------------------------
// An expansion is a sum of doubles, non-overlapping and in increasing magnitude, with
// zeros eliminated; its sign is the sign of its last (largest) component.

constexpr int kCapacity = 256;  // > 192, the largest expansion below (the orient3d determinant)

struct Expansion {
  int size = 0;
  double term[kCapacity];

  Expansion() = default;
  Expansion(const Expansion& o) : size(o.size) { std::copy(o.term, o.term + o.size, term); }
  Expansion& operator=(const Expansion& o) {  // copies the used terms only
    size = o.size;
    std::copy(o.term, o.term + o.size, term);
    return *this;
  }
  void push(double x) { term[size++] = x; }
  int sign() const { return size == 0 ? 0 : (term[size - 1] > 0) - (term[size - 1] < 0); }
};

inline void twoSum(double a, double b, double& sum, double& err) {
  sum = a + b;
  const double bv = sum - a;
  const double av = sum - bv;
  err = (a - av) + (b - bv);
}

inline void twoProduct(double a, double b, double& product, double& err) {
  product = a * b;
  err = std::fma(a, b, -product);  // exact: the rounding error of a * b
}

/// a - b exactly.
void difference(double a, double b, Expansion& h) {
  const double x = a - b;
  const double bv = a - x;
  const double av = x + bv;
  const double err = (a - av) + (bv - b);
  h.size = 0;
  if (err != 0) h.push(err);
  if (x != 0 || h.size == 0) h.push(x);
}

/// h = e + b (grow_expansion_zeroelim). h must not alias e.
void grow(const Expansion& e, double b, Expansion& h) {
  double q = b;
  h.size = 0;
  for (int i = 0; i < e.size; ++i) {
    double sum, err;
    twoSum(q, e.term[i], sum, err);
    if (err != 0) h.push(err);
    q = sum;
  }
  if (q != 0 || h.size == 0) h.push(q);
}

/// h = e + f (repeated growth; O(|e| |f|), fine for these sizes).
void add(const Expansion& e, const Expansion& f, Expansion& h) {
  Expansion tmp;
  h = e;
  for (int j = 0; j < f.size; ++j) {
    grow(h, f.term[j], tmp);
    h = tmp;
  }
}

/// h = e * b (scale_expansion_zeroelim, with two_sum in place of fast_two_sum).
void scale(const Expansion& e, double b, Expansion& h) {
  h.size = 0;
  if (e.size == 0 || b == 0) {
    h.push(0);
    return;
  }
  double q, err;
  twoProduct(e.term[0], b, q, err);
  if (err != 0) h.push(err);
  for (int i = 1; i < e.size; ++i) {
    double p1, p0, sum;
    twoProduct(e.term[i], b, p1, p0);
    twoSum(q, p0, sum, err);
    if (err != 0) h.push(err);
    twoSum(p1, sum, q, err);
    if (err != 0) h.push(err);
  }
  if (q != 0 || h.size == 0) h.push(q);
}

/// h = e * f.
void multiply(const Expansion& e, const Expansion& f, Expansion& h) {
  Expansion part, sum;
  h.size = 0;
  h.push(0);
  for (int j = 0; j < f.size; ++j) {
    scale(e, f.term[j], part);
    add(h, part, sum);
    h = sum;
  }
}

/// h = a*b - c*d for expansions.
void crossTerm(const Expansion& a, const Expansion& b, const Expansion& c, const Expansion& d, Expansion& h) {
  Expansion ab, cd;
  multiply(a, b, ab);
  multiply(c, d, cd);
  for (int i = 0; i < cd.size; ++i) cd.term[i] = -cd.term[i];
  add(ab, cd, h);
}

int orient2dExact(double ax, double ay, double bx, double by, double cx, double cy) {
  Expansion e1x, e1y, e2x, e2y, det;
  difference(bx, ax, e1x);
  difference(by, ay, e1y);
  difference(cx, ax, e2x);
  difference(cy, ay, e2y);
  crossTerm(e1x, e2y, e1y, e2x, det);
  return det.sign();
}

/// Sign of det[b - a; c - a; d - a].
int orient3dExact(const V& a, const V& b, const V& c, const V& d) {
  Expansion e1[3], e2[3], w[3];
  for (int k = 0; k < 3; ++k) {
    difference(b[k], a[k], e1[k]);
    difference(c[k], a[k], e2[k]);
    difference(d[k], a[k], w[k]);
  }
  // det = w . (e1 x e2)
  Expansion det, minor, term, sum;
  det.push(0);
  for (int k = 0; k < 3; ++k) {
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    crossTerm(e1[i], e2[j], e1[j], e2[i], minor);
    multiply(minor, w[k], term);
    add(det, term, sum);
    det = sum;
  }
  return det.sign();
}

inline int signOf(double x) { return (x > 0) - (x < 0); }

// ---- a triangle's plane, with the error-bound data of the side test ---------------------

/// A proper or degenerate triangle with the minors of (b - a) x (c - a) precomputed, so
/// that the side of many points is one dot product each (the same determinant as
/// orient3d(a, b, c, d), hence the same error bound).
struct Plane {
  V a, b, c;
  double m[3];     // (b - a) x (c - a), computed
  double perm[3];  // |e1_i e2_j| + |e1_j e2_i| per component (the permanent's factors)

  Plane(const V& a_, const V& b_, const V& c_) : a(a_), b(b_), c(c_) {
    const V e1 = b - a, e2 = c - a;
    for (int k = 0; k < 3; ++k) {
      const int i = (k + 1) % 3, j = (k + 2) % 3;
      const double p = e1[i] * e2[j], q = e1[j] * e2[i];
      m[k] = p - q;
      perm[k] = std::abs(p) + std::abs(q);
    }
  }

  /// orient3d(a, b, c, d).
  int side(const V& d) const {
    const double wx = d[0] - a[0], wy = d[1] - a[1], wz = d[2] - a[2];
    const double det = wx * m[0] + wy * m[1] + wz * m[2];
    const double permanent = std::abs(wx) * perm[0] + std::abs(wy) * perm[1] + std::abs(wz) * perm[2];
    const double bound = kOrient3dBound * permanent;
    if (det > bound) return 1;
    if (-det > bound) return -1;
    if (permanent == 0) return 0;  // every product is exactly zero (see kZeroPermanent)
    return orient3dExact(a, b, c, d);
  }

  /// Sign of the normal's component k = orient2d of the projection along k.
  int normalSign(int k) const {
    if (m[k] > kOrient2dBound * perm[k]) return 1;
    if (-m[k] > kOrient2dBound * perm[k]) return -1;
    if (perm[k] == 0) return 0;
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    return orient2dExact(a[i], a[j], b[i], b[j], c[i], c[j]);
  }

  /// Axis along which the projection of the plane is one-to-one (the normal's largest
  /// component that is exactly non-zero), or -1 if the corners are collinear.
  int projectionAxis() const {
    int order[3] = {0, 1, 2};
    // Largest |m| first (only a preference for conditioning; exactness comes from normalSign).
    for (int s = 0; s < 2; ++s)
      for (int t = 0; t < 2 - s; ++t)
        if (std::abs(m[order[t]]) < std::abs(m[order[t + 1]])) std::swap(order[t], order[t + 1]);
    for (int k : order)
      if (normalSign(k) != 0) return k;
    return -1;
  }
};

// ---- 2D tests in the projection that drops axis k ------------------------------------

struct Projection {
  int i, j;  // the two kept coordinates
  explicit Projection(int k) : i((k + 1) % 3), j((k + 2) % 3) {}
  int orient(const V& a, const V& b, const V& c) const {
    const double e1x = b[i] - a[i], e1y = b[j] - a[j], e2x = c[i] - a[i], e2y = c[j] - a[j];
    const double p = e1x * e2y, q = e1y * e2x;
    const double det = p - q;
    const double bound = kOrient2dBound * (std::abs(p) + std::abs(q));
    if (det > bound) return 1;
    if (-det > bound) return -1;
    if (p == 0 && q == 0) return 0;
    return orient2dExact(a[i], a[j], b[i], b[j], c[i], c[j]);
  }
  /// p on the closed segment ab, given that a, b, p are collinear (in the projection).
  bool between(const V& a, const V& b, const V& p) const {
    return std::min(a[i], b[i]) <= p[i] && p[i] <= std::max(a[i], b[i]) && std::min(a[j], b[j]) <= p[j] &&
           p[j] <= std::max(a[j], b[j]);
  }
  bool segmentsIntersect(const V& p, const V& q, const V& r, const V& s) const {
    const int d1 = orient(r, s, p), d2 = orient(r, s, q);
    const int d3 = orient(p, q, r), d4 = orient(p, q, s);
    if (d1 * d2 < 0 && d3 * d4 < 0) return true;
    return (d1 == 0 && between(r, s, p)) || (d2 == 0 && between(r, s, q)) || (d3 == 0 && between(p, q, r)) ||
           (d4 == 0 && between(p, q, s));
  }
  /// p in the closed triangle abc (proper in this projection).
  bool inTriangle(const V& p, const V& a, const V& b, const V& c) const {
    const int s1 = orient(a, b, p), s2 = orient(b, c, p), s3 = orient(c, a, p);
    return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
  }
  bool segmentTriangle(const V& p, const V& q, const V& a, const V& b, const V& c) const {
    return inTriangle(p, a, b, c) || inTriangle(q, a, b, c) || segmentsIntersect(p, q, a, b) ||
           segmentsIntersect(p, q, b, c) || segmentsIntersect(p, q, c, a);
  }
  bool triangles(const V* t1, const V* t2) const {
    for (int e = 0; e < 3; ++e)
      if (segmentTriangle(t1[e], t1[(e + 1) % 3], t2[0], t2[1], t2[2])) return true;
    return inTriangle(t2[0], t1[0], t1[1], t1[2]);  // t2 inside t1 (no edge of t1 touches it)
  }
};

// ---- 3D tests -------------------------------------------------------------------------

/// Do the line through p, q (not parallel to the plane) and the closed triangle meet?
bool lineThroughTriangle(const V& p, const V& q, const V& a, const V& b, const V& c) {
  const int s1 = orient3d(p, q, a, b);
  const int s2 = orient3d(p, q, b, c);
  if (s1 * s2 < 0) return false;
  const int s3 = orient3d(p, q, c, a);
  return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
}

/// Closed segment pq against a proper triangle, the sides of p and q given.
bool segmentTriangle(const V& p, const V& q, int sp, int sq, const Plane& t, int axis) {
  if (sp * sq > 0) return false;
  if (sp == 0 && sq == 0) return Projection(axis).segmentTriangle(p, q, t.a, t.b, t.c);
  return lineThroughTriangle(p, q, t.a, t.b, t.c);
}

bool collinear(const V& a, const V& b, const V& c) {
  for (int k = 0; k < 3; ++k)
    if (Projection(k).orient(a, b, c) != 0) return false;
  return true;
}

bool pointOnSegment(const V& p, const V& a, const V& b) {
  if (!collinear(a, b, p)) return false;
  for (int k = 0; k < 3; ++k)
    if (p[k] < std::min(a[k], b[k]) || p[k] > std::max(a[k], b[k])) return false;
  return true;
}

/// Closed segments pq and rs (p != q, r != s).
bool segmentsIntersect(const V& p, const V& q, const V& r, const V& s) {
  if (orient3d(p, q, r, s) != 0) return false;
  const bool cr = collinear(p, q, r), cs = collinear(p, q, s);
  if (cr && cs) {  // one line: intervals along an axis the line is not normal to
    int k = 0;
    while (p[k] == q[k]) ++k;
    return std::max(std::min(p[k], q[k]), std::min(r[k], s[k])) <= std::min(std::max(p[k], q[k]), std::max(r[k], s[k]));
  }
  const V& third = cr ? s : r;  // p, q, third span the common plane
  for (int k = 0; k < 3; ++k) {
    const Projection proj(k);
    if (proj.orient(p, q, third) != 0) return proj.segmentsIntersect(p, q, r, s);
  }
  return false;  // unreachable: p, q, third are not collinear
}

/// A triangle reduced to what its corners span: a proper triangle, a segment or a point.
struct Simplex {
  int dimension;
  V p[3];
};

Simplex reduce(const V& a, const V& b, const V& c, int axis) {
  if (axis >= 0) return {2, {a, b, c}};
  if (a == b && b == c) return {0, {a, a, a}};
  // Collinear: the extreme corners along an axis on which the corners are not all equal.
  int k = 0;
  while (a[k] == b[k] && b[k] == c[k]) ++k;
  const V* lo = &a;
  const V* hi = &a;
  for (const V* v : {&b, &c}) {
    if ((*v)[k] < (*lo)[k]) lo = v;
    if ((*v)[k] > (*hi)[k]) hi = v;
  }
  return {1, {*lo, *hi, *hi}};
}

/// Two proper triangles, s1 the sides of t1's corners against t2's plane and s2 vice versa.
bool properTriangles(const Plane& t1, int axis1, const int* s1, const Plane& t2, int axis2, const int* s2) {
  const V v1[3] = {t1.a, t1.b, t1.c};
  const V v2[3] = {t2.a, t2.b, t2.c};
  if (s1[0] == 0 && s1[1] == 0 && s1[2] == 0) return Projection(axis2).triangles(v1, v2);
  for (int e = 0; e < 3; ++e) {
    const int f = (e + 1) % 3;
    if (segmentTriangle(v1[e], v1[f], s1[e], s1[f], t2, axis2)) return true;
  }
  for (int e = 0; e < 3; ++e) {
    const int f = (e + 1) % 3;
    if (segmentTriangle(v2[e], v2[f], s2[e], s2[f], t1, axis1)) return true;
  }
  return false;
}

// ---- Devillers-Guigue for two proper, non-coplanar triangles ---------------------------
// (O. Devillers, P. Guigue, "Faster triangle-triangle intersection tests", INRIA RR-4488,
// 2002.) The corners are permuted so that p1 is alone on its side of plane 2 and p2 alone on
// its side of plane 1, both on the positive side (swapping q, r of the other triangle flips
// the sign); then the two intervals on the planes' common line overlap iff two orientations
// agree. Zeros (corners on the other plane) fall into the permutation cases.

/// The intervals' check, corners already permuted.
bool dgMinMax(const V& p1, const V& q1, const V& r1, const V& p2, const V& q2, const V& r2) {
  if (orient3d(q1, p2, p1, q2) > 0) return false;
  return orient3d(p1, p2, r1, r2) <= 0;
}

/// T2's corners permuted for a T1 whose p1 is alone on the positive side of plane 2.
bool dgSecond(const V& p1, const V& q1, const V& r1, const V& p2, const V& q2, const V& r2, int dp2, int dq2, int dr2) {
  if (dp2 > 0) {
    if (dq2 > 0) return dgMinMax(p1, r1, q1, r2, p2, q2);
    if (dr2 > 0) return dgMinMax(p1, r1, q1, q2, r2, p2);
    return dgMinMax(p1, q1, r1, p2, q2, r2);
  }
  if (dp2 < 0) {
    if (dq2 < 0) return dgMinMax(p1, q1, r1, r2, p2, q2);
    if (dr2 < 0) return dgMinMax(p1, q1, r1, q2, r2, p2);
    return dgMinMax(p1, r1, q1, p2, q2, r2);
  }
  if (dq2 < 0) {
    if (dr2 >= 0) return dgMinMax(p1, r1, q1, q2, r2, p2);
    return dgMinMax(p1, q1, r1, p2, q2, r2);
  }
  if (dq2 > 0) {
    if (dr2 > 0) return dgMinMax(p1, r1, q1, p2, q2, r2);
    return dgMinMax(p1, q1, r1, q2, r2, p2);
  }
  if (dr2 > 0) return dgMinMax(p1, q1, r1, r2, p2, q2);
  return dgMinMax(p1, r1, q1, r2, p2, q2);  // dr2 < 0 (all zero is excluded by the caller)
}

/// d1 = sides of T1's corners against plane 2, d2 = of T2's against plane 1; neither all zero.
bool devillersGuigue(const V& p1, const V& q1, const V& r1, const V& p2, const V& q2, const V& r2, const int* d1,
                     const int* d2) {
  const int dp1 = d1[0], dq1 = d1[1], dr1 = d1[2];
  const int dp2 = d2[0], dq2 = d2[1], dr2 = d2[2];
  if (dp1 > 0) {
    if (dq1 > 0) return dgSecond(r1, p1, q1, p2, r2, q2, dp2, dr2, dq2);
    if (dr1 > 0) return dgSecond(q1, r1, p1, p2, r2, q2, dp2, dr2, dq2);
    return dgSecond(p1, q1, r1, p2, q2, r2, dp2, dq2, dr2);
  }
  if (dp1 < 0) {
    if (dq1 < 0) return dgSecond(r1, p1, q1, p2, q2, r2, dp2, dq2, dr2);
    if (dr1 < 0) return dgSecond(q1, r1, p1, p2, q2, r2, dp2, dq2, dr2);
    return dgSecond(p1, q1, r1, p2, r2, q2, dp2, dr2, dq2);
  }
  if (dq1 < 0) {
    if (dr1 >= 0) return dgSecond(q1, r1, p1, p2, r2, q2, dp2, dr2, dq2);
    return dgSecond(p1, q1, r1, p2, q2, r2, dp2, dq2, dr2);
  }
  if (dq1 > 0) {
    if (dr1 > 0) return dgSecond(p1, q1, r1, p2, r2, q2, dp2, dr2, dq2);
    return dgSecond(q1, r1, p1, p2, q2, r2, dp2, dq2, dr2);
  }
  if (dr1 > 0) return dgSecond(r1, p1, q1, p2, q2, r2, dp2, dq2, dr2);
  return dgSecond(r1, p1, q1, p2, r2, q2, dp2, dr2, dq2);  // dr1 < 0
}

/// Lower-dimensional s (segment or point) against t (any).
bool simplexPair(const Simplex& s, const Simplex& t, const Plane& tPlane, int tAxis) {
  if (t.dimension == 2) {
    if (s.dimension == 1)
      return segmentTriangle(s.p[0], s.p[1], tPlane.side(s.p[0]), tPlane.side(s.p[1]), tPlane, tAxis);
    return tPlane.side(s.p[0]) == 0 && Projection(tAxis).inTriangle(s.p[0], t.p[0], t.p[1], t.p[2]);
  }
  if (t.dimension == 1) {
    if (s.dimension == 1) return segmentsIntersect(s.p[0], s.p[1], t.p[0], t.p[1]);
    return pointOnSegment(s.p[0], t.p[0], t.p[1]);
  }
  if (s.dimension == 1) return pointOnSegment(t.p[0], s.p[0], s.p[1]);
  return s.p[0] == t.p[0];
}

}  // namespace

int orient2d(double ax, double ay, double bx, double by, double cx, double cy) {
  const double p = (bx - ax) * (cy - ay), q = (by - ay) * (cx - ax);
  const double det = p - q;
  const double bound = kOrient2dBound * (std::abs(p) + std::abs(q));
  if (det > bound) return 1;
  if (-det > bound) return -1;
  if (p == 0 && q == 0) return 0;
  return orient2dExact(ax, ay, bx, by, cx, cy);
}

int orient3d(const V& a, const V& b, const V& c, const V& d) {
  const V e1 = b - a, e2 = c - a, w = d - a;
  double det = 0, perm = 0;
  for (int k = 0; k < 3; ++k) {
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    const double p = e1[i] * e2[j], q = e1[j] * e2[i];
    det += w[k] * (p - q);
    perm += std::abs(w[k]) * (std::abs(p) + std::abs(q));
  }
  const double bound = kOrient3dBound * perm;
  if (det > bound) return 1;
  if (-det > bound) return -1;
  if (perm == 0) return 0;
  return orient3dExact(a, b, c, d);
}

bool trianglesIntersect(const V& a1, const V& b1, const V& c1, const V& a2, const V& b2, const V& c2) {
  // Möller's rejection first (the common case): all corners of one triangle strictly on one
  // side of the other's plane. Valid for degenerate triangles too: a collinear triangle's
  // exact normal is zero, so every side against it is 0 and it rejects nothing.
  const auto oneSide = [](const int* s) {
    return (s[0] > 0 && s[1] > 0 && s[2] > 0) || (s[0] < 0 && s[1] < 0 && s[2] < 0);
  };
  const Plane t2(a2, b2, c2);
  const int s1[3] = {t2.side(a1), t2.side(b1), t2.side(c1)};
  if (oneSide(s1)) return false;
  const Plane t1(a1, b1, c1);
  const int s2[3] = {t1.side(a2), t1.side(b2), t1.side(c2)};
  if (oneSide(s2)) return false;
  // A non-zero side against a plane proves that plane's triangle proper; with both, the
  // triangles are proper and not coplanar: Devillers-Guigue, two more orientations.
  const auto anyNonZero = [](const int* s) { return (s[0] | s[1] | s[2]) != 0; };
  if (anyNonZero(s1) && anyNonZero(s2)) return devillersGuigue(a1, b1, c1, a2, b2, c2, s1, s2);
  const int axis1 = t1.projectionAxis();
  const int axis2 = t2.projectionAxis();
  if (axis1 >= 0 && axis2 >= 0) return properTriangles(t1, axis1, s1, t2, axis2, s2);
  const Simplex r1 = reduce(a1, b1, c1, axis1);
  const Simplex r2 = reduce(a2, b2, c2, axis2);
  if (r1.dimension <= r2.dimension) return simplexPair(r1, r2, t2, axis2);
  return simplexPair(r2, r1, t1, axis1);
}

template <class S>
Vec3<S> closestPointOnSegment(const Vec3<S>& p, const Vec3<S>& a, const Vec3<S>& b) {
  return detail::closestOnSegment(p, a, b);
}

template <class S>
Vec3<S> closestPointOnTriangle(const Vec3<S>& p, const Vec3<S>& a, const Vec3<S>& b, const Vec3<S>& c) {
  return detail::closestOnTriangle(p, a, b, c);
}

template Vec3<float> closestPointOnSegment(const Vec3<float>&, const Vec3<float>&, const Vec3<float>&);
template Vec3<double> closestPointOnSegment(const Vec3<double>&, const Vec3<double>&, const Vec3<double>&);
template Vec3<float> closestPointOnTriangle(const Vec3<float>&, const Vec3<float>&, const Vec3<float>&,
                                            const Vec3<float>&);
template Vec3<double> closestPointOnTriangle(const Vec3<double>&, const Vec3<double>&, const Vec3<double>&,
                                             const Vec3<double>&);

}  // namespace weft
