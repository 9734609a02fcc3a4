// The rigid narrow phase (weft/rigid/narrow_phase.hpp): the exact separating-axis test
// against brute force (the faces of the Minkowski difference, every face and edge-pair
// axis, a feature-pair distance and an intersection test) and analytic cases; manifolds
// of resting, tilted and crossed boxes; the witness against the exact method over random
// small-motion sequences; the OFG heuristic's agreement and recall; sphere against hull.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include "support/sanitizers.hpp"
#include "weft/rigid/convex_hull.hpp"
#include "weft/rigid/narrow_phase.hpp"

namespace weft {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr double kInf = std::numeric_limits<double>::infinity();

Matrix3d rotationAbout(const Vector3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

Matrix3d randomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0, 1);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized().toRotationMatrix();
}

Vector3d randomUnit(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0, 1);
  return Vector3d(n(rng), n(rng), n(rng)).normalized();
}

Pose makePose(const Matrix3d& r, const Vector3d& p) {
  Pose pose;
  pose.rotation = r;
  pose.position = p;
  return pose;
}

/// A box (random half extents) or the hull of random points (in a ball or on an ellipsoid).
ConvexHull randomHull(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  const double kind = u(rng);
  if (kind < 0.3) return makeBoxHull(Vector3d(0.2 + 0.8 * u(rng), 0.2 + 0.8 * u(rng), 0.2 + 0.8 * u(rng)));
  const int count = 8 + static_cast<int>(u(rng) * 16);
  std::vector<Vector3d> points;
  const Vector3d axes(0.3 + 0.7 * u(rng), 0.3 + 0.7 * u(rng), 0.3 + 0.7 * u(rng));
  for (int i = 0; i < count; ++i) {
    const Vector3d d = randomUnit(rng);
    const double r = kind < 0.65 ? std::cbrt(u(rng)) : 1.0;
    points.push_back(r * d.cwiseProduct(axes));
  }
  return makeConvexHull(points);
}

/// The hull of an upright prism on a regular `sides`-gon: corners at `radius` from the y axis,
/// caps at y = -halfHeight and y = halfHeight.
ConvexHull prismHull(int sides, double radius, double halfHeight) {
  std::vector<Vector3d> points;
  for (int k = 0; k < sides; ++k) {
    const double t = 2 * M_PI * k / sides;
    points.emplace_back(radius * std::cos(t), -halfHeight, radius * std::sin(t));
    points.emplace_back(radius * std::cos(t), halfHeight, radius * std::sin(t));
  }
  return makeConvexHull(points);
}

std::vector<Vector3d> worldVertices(const ConvexHull& h, const Pose& pose) {
  std::vector<Vector3d> out;
  for (const Vector3d& v : h.vertices) out.push_back(pose.rotation * v + pose.position);
  return out;
}

/// Separation along axis L from A to B by brute force over the vertices.
double axisSeparation(const std::vector<Vector3d>& a, const std::vector<Vector3d>& b, const Vector3d& l) {
  double maxA = -kInf, minB = kInf;
  for (const Vector3d& x : a) maxA = std::max(maxA, l.dot(x));
  for (const Vector3d& x : b) minB = std::min(minB, l.dot(x));
  return minB - maxA;
}

/// The largest separation over every face normal and every (non-parallel) edge-pair cross
/// product, both signs, supports by brute force: >= the SAT value (it contains all the
/// Minkowski face normals) and <= the distance (each is a separating-axis bound).
double allAxesSeparation(const ConvexHull& a, const Pose& pa, const ConvexHull& b, const Pose& pb) {
  const auto va = worldVertices(a, pa), vb = worldVertices(b, pb);
  double best = -kInf;
  const auto test = [&](const Vector3d& l) {
    best = std::max({best, axisSeparation(va, vb, l), axisSeparation(va, vb, -l)});
  };
  for (const ConvexFace& f : a.faces) test(pa.rotation * f.normal);
  for (const ConvexFace& f : b.faces) test(pb.rotation * f.normal);
  for (const ConvexEdge& ea : a.edges) {
    const Vector3d da = pa.rotation * (a.vertices[ea.v1] - a.vertices[ea.v0]);
    for (const ConvexEdge& eb : b.edges) {
      const Vector3d db = pb.rotation * (b.vertices[eb.v1] - b.vertices[eb.v0]);
      const Vector3d c = da.cross(db);
      if (c.norm() > 1e-5 * da.norm() * db.norm()) test(c.normalized());
    }
  }
  return best;
}

/// The SAT value from the hull of the Minkowski difference M = B - A: max over M's faces
/// of -offset (the separation along the face's inward normal).
double minkowskiSeparation(const ConvexHull& a, const Pose& pa, const ConvexHull& b, const Pose& pb) {
  std::vector<Vector3d> points;
  for (const Vector3d& x : worldVertices(b, pb))
    for (const Vector3d& y : worldVertices(a, pa)) points.push_back(x - y);
  const ConvexHull m = makeConvexHull(points);
  double best = -kInf;
  for (const ConvexFace& f : m.faces) best = std::max(best, -f.offset);
  return best;
}

double pointSegmentDistance(const Vector3d& x, const Vector3d& p, const Vector3d& q, double* param = nullptr) {
  const Vector3d d = q - p;
  const double t = d.squaredNorm() > 0 ? std::clamp((x - p).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
  if (param) *param = t;
  return (p + t * d - x).norm();
}

/// Distance of two segments: the interior stationary point of |p1 + s d1 - p2 - t d2|^2 if it
/// lies in the unit square, else the best of the four sides (point-to-segment distances).
/// `interior` says whether the minimum is at an interior point of both segments.
double segmentDistance(const Vector3d& p1, const Vector3d& q1, const Vector3d& p2, const Vector3d& q2, bool& interior) {
  const Vector3d d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.dot(d1), b = d1.dot(d2), c = d2.dot(d2), d = d1.dot(r), e = d2.dot(r);
  const double det = a * c - b * b;
  interior = false;
  double best = kInf;
  if (det > 1e-12 * a * c) {
    const double s = (b * e - c * d) / det, t = (a * e - b * d) / det;
    if (s > 1e-6 && s < 1 - 1e-6 && t > 1e-6 && t < 1 - 1e-6) {
      interior = true;
      return (p1 + s * d1 - p2 - t * d2).norm();
    }
  }
  best = std::min({pointSegmentDistance(p1, p2, q2), pointSegmentDistance(q1, p2, q2), pointSegmentDistance(p2, p1, q1),
                   pointSegmentDistance(q2, p1, q1)});
  return best;
}

bool insidePolygon(const ConvexHull& h, const Pose& pose, int f, const Vector3d& x, double slack) {
  const auto idx = h.faceIndices(f);
  const Vector3d n = pose.rotation * h.faces[f].normal;
  for (std::size_t k = 0; k < idx.size(); ++k) {
    const Vector3d v0 = pose.rotation * h.vertices[idx[k]] + pose.position;
    const Vector3d v1 = pose.rotation * h.vertices[idx[(k + 1) % idx.size()]] + pose.position;
    const Vector3d e = v1 - v0;
    if (e.cross(x - v0).dot(n) < slack * e.norm()) return false;
  }
  return true;
}

struct BruteForce {
  bool intersecting = false;
  double distance = kInf;  // when not intersecting
  bool generic = false;    // the closest features are vertex-face (strictly inside) or edge-edge (interiors)
};

/// Intersection: a vertex of one inside the other, or an edge of one through a face of the
/// other. Distance (when apart): the least vertex-face (projection inside the polygon) and
/// edge-edge distance.
BruteForce bruteForce(const ConvexHull& a, const Pose& pa, const ConvexHull& b, const Pose& pb) {
  BruteForce r;
  const auto inside = [](const ConvexHull& h, const Pose& pose, const Vector3d& x) {
    const Vector3d l = pose.rotation.transpose() * (x - pose.position);
    for (const ConvexFace& f : h.faces)
      if (f.normal.dot(l) - f.offset > 0) return false;
    return true;
  };
  const auto pierces = [](const ConvexHull& h, const Pose& pose, const Vector3d& p, const Vector3d& q) {
    for (int f = 0; f < h.faceCount(); ++f) {
      const Vector3d n = pose.rotation * h.faces[f].normal;
      const double off = h.faces[f].offset + n.dot(pose.position);
      const double dp = n.dot(p) - off, dq = n.dot(q) - off;
      if ((dp > 0) == (dq > 0)) continue;
      const Vector3d x = p + dp / (dp - dq) * (q - p);
      if (insidePolygon(h, pose, f, x, 0)) return true;
    }
    return false;
  };
  const auto va = worldVertices(a, pa), vb = worldVertices(b, pb);
  for (const Vector3d& x : va) r.intersecting = r.intersecting || inside(b, pb, x);
  for (const Vector3d& x : vb) r.intersecting = r.intersecting || inside(a, pa, x);
  for (const ConvexEdge& e : a.edges) r.intersecting = r.intersecting || pierces(b, pb, va[e.v0], va[e.v1]);
  for (const ConvexEdge& e : b.edges) r.intersecting = r.intersecting || pierces(a, pa, vb[e.v0], vb[e.v1]);
  if (r.intersecting) return r;
  const auto vertexFace = [&](const std::vector<Vector3d>& points, const ConvexHull& h, const Pose& pose) {
    for (const Vector3d& x : points) {
      for (int f = 0; f < h.faceCount(); ++f) {
        const Vector3d n = pose.rotation * h.faces[f].normal;
        const double d = n.dot(x) - h.faces[f].offset - n.dot(pose.position);
        if (d <= 0) continue;
        const Vector3d y = x - d * n;
        if (insidePolygon(h, pose, f, y, 0) && d < r.distance) {
          r.distance = d;
          r.generic = insidePolygon(h, pose, f, y, 1e-6);
        }
      }
    }
  };
  vertexFace(va, b, pb);
  vertexFace(vb, a, pa);
  for (const ConvexEdge& ea : a.edges) {
    for (const ConvexEdge& eb : b.edges) {
      bool interior = false;
      const double d = segmentDistance(va[ea.v0], va[ea.v1], vb[eb.v0], vb[eb.v1], interior);
      if (d < r.distance - 1e-12) {
        r.distance = d;
        r.generic = interior;
      }
    }
  }
  return r;
}

/// B at a random rotation placed along a random direction so that its SAT separation from
/// A is `target` (bisection on the distance: the SAT value is convex along a line).
Pose placeAt(const ConvexHull& a, const Pose& pa, const ConvexHull& b, const Matrix3d& rb, const Vector3d& dir,
             double target, int iterations = 45) {
  double lo = 0, hi = 2 * (a.boundingRadius + b.boundingRadius) + std::abs(target) + 1;
  const auto at = [&](double t) {
    return makePose(rb, pa.position + pa.rotation * a.centroid + dir * t - rb * b.centroid);
  };
  for (int it = 0; it < iterations; ++it) {
    const double mid = 0.5 * (lo + hi);
    (hullSeparation(a, pa, b, at(mid)) < target ? lo : hi) = mid;
  }
  return at(0.5 * (lo + hi));
}

ContactManifold collide(const ConvexHull& a, const Pose& pa, const ConvexHull& b, const Pose& pb, double margin,
                        NarrowPhaseMethod method, int ofgFaces = 6) {
  NarrowPhaseOptions options;
  options.method = method;
  options.ofgFaces = ofgFaces;
  PairCache cache;
  ContactManifold m;
  collideHulls(a, pa, b, pb, margin, options, cache, m);
  return m;
}

::testing::AssertionResult sameManifold(const ContactManifold& x, const ContactManifold& y, double tol) {
  if (x.pointCount != y.pointCount)
    return ::testing::AssertionFailure() << "point counts " << x.pointCount << " vs " << y.pointCount;
  if (x.pointCount == 0) return ::testing::AssertionSuccess();
  if ((x.normal - y.normal).norm() > tol)
    return ::testing::AssertionFailure() << "normals " << x.normal.transpose() << " vs " << y.normal.transpose();
  for (int k = 0; k < x.pointCount; ++k) {
    const ContactPoint &p = x.points[k], &q = y.points[k];
    if (std::abs(p.separation - q.separation) > tol || (p.position - q.position).norm() > tol ||
        p.featureId != q.featureId)
      return ::testing::AssertionFailure()
             << "point " << k << ": separation " << p.separation << " vs " << q.separation << ", position "
             << p.position.transpose() << " vs " << q.position.transpose() << ", ids " << p.featureId << " vs "
             << q.featureId;
  }
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------

TEST(RigidNarrow, MethodNames) {
  EXPECT_STREQ(narrowPhaseMethodName(NarrowPhaseMethod::Exact), "exact");
  EXPECT_STREQ(narrowPhaseMethodName(NarrowPhaseMethod::Ofg), "ofg");
  EXPECT_STREQ(narrowPhaseMethodName(NarrowPhaseMethod::Witness), "witness");
}

TEST(RigidNarrow, ExactSeparationAgreesWithBruteForce) {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(0, 1);
  int separated = 0, overlapping = 0, generic = 0, minkowskiChecked = 0;
  for (int trial = 0; trial < 600; ++trial) {
    const ConvexHull a = randomHull(rng), b = randomHull(rng);
    const Pose pa = makePose(randomRotation(rng), Vector3d(u(rng), u(rng), u(rng)) - Vector3d::Constant(0.5));
    const Vector3d dir = randomUnit(rng);
    const double target = -0.3 + 0.6 * u(rng);
    const Pose pb = placeAt(a, pa, b, randomRotation(rng), dir, target);
    const double s = hullSeparation(a, pa, b, pb);
    SCOPED_TRACE(::testing::Message() << "trial " << trial << " separation " << s);
    // Every axis by brute force: the SAT value is the maximum over the Minkowski faces, a
    // subset, and equals the maximum over all directions when the hulls overlap.
    const double all = allAxesSeparation(a, pa, b, pb);
    EXPECT_LE(s, all + 1e-9);
    if (s < 0) {
      EXPECT_NEAR(s, all, 1e-9);
    }
    // The faces of the Minkowski difference (quickhull): the same maximum.
    if (trial % 3 == 0) {
      EXPECT_NEAR(s, minkowskiSeparation(a, pa, b, pb), 1e-7);
      ++minkowskiChecked;
    }
    const BruteForce bf = bruteForce(a, pa, b, pb);
    if (s > 1e-9) {
      ++separated;
      EXPECT_FALSE(bf.intersecting);
      EXPECT_GE(bf.distance, s - 1e-9);
      if (bf.generic) {
        ++generic;
        EXPECT_NEAR(bf.distance, s, 1e-9);
      }
    } else if (s < -1e-9) {
      ++overlapping;
      EXPECT_TRUE(bf.intersecting);
    }
  }
  std::printf(
      "[ exact SAT ] %d separated (%d with face-vertex/edge-edge closest features), %d overlapping, "
      "%d checked against the Minkowski hull\n",
      separated, generic, overlapping, minkowskiChecked);
  EXPECT_GT(separated, 150);
  EXPECT_GT(overlapping, 150);
  EXPECT_GT(generic, 100);
}

TEST(RigidNarrow, AnalyticBoxes) {
  const ConvexHull box = makeBoxHull(Vector3d(0.5, 0.5, 0.5));
  const Pose origin;
  // Axis-aligned boxes at known offsets: the gap along the offset axis.
  for (const double gap : {0.25, 0.01, 0.0, -0.01, -0.3}) {
    EXPECT_NEAR(hullSeparation(box, origin, box, makePose(Matrix3d::Identity(), Vector3d(1 + gap, 0.2, -0.1))), gap,
                1e-12);
    EXPECT_NEAR(hullSeparation(box, origin, box, makePose(Matrix3d::Identity(), Vector3d(0.1, -0.2, -1 - gap))), gap,
                1e-12);
  }
  // A box turned 45 degrees about x resting edge-down on a box: the vertical gap, found on
  // the lower box's top face; two points along the edge.
  const Matrix3d r45x = rotationAbout(Vector3d::UnitX(), M_PI / 4);
  for (const double gap : {0.02, -0.005}) {
    const Pose pb = makePose(r45x, Vector3d(0, 0.5 + std::sqrt(0.5) + gap, 0));
    EXPECT_NEAR(hullSeparation(box, origin, box, pb), gap, 1e-12);
    const ContactManifold m = collide(box, origin, box, pb, 0.03, NarrowPhaseMethod::Exact);
    ASSERT_EQ(m.pointCount, 2);
    EXPECT_NEAR((m.normal - Vector3d::UnitY()).norm(), 0, 1e-12);
    for (int k = 0; k < 2; ++k) {
      EXPECT_NEAR(m.points[k].separation, gap, 1e-12);
      EXPECT_NEAR(std::abs(m.points[k].position.x()), 0.5, 1e-12);
      EXPECT_NEAR(m.points[k].position.y(), 0.5 + 0.5 * gap, 1e-12);
    }
  }
  // Crossed edges: A turned about x (top ridge along x), B turned about z (bottom ridge
  // along z): the edge-pair axis (vertical) decides, one point between the ridges.
  const Pose pa = makePose(r45x, Vector3d::Zero());
  for (const double gap : {0.05, 0.0, -0.02}) {
    const Pose pb = makePose(rotationAbout(Vector3d::UnitZ(), M_PI / 4), Vector3d(0, std::sqrt(2.0) + gap, 0));
    EXPECT_NEAR(hullSeparation(box, pa, box, pb), gap, 1e-12);
    const ContactManifold m = collide(box, pa, box, pb, 0.1, NarrowPhaseMethod::Exact);
    ASSERT_EQ(m.pointCount, 1);
    EXPECT_NEAR((m.normal - Vector3d::UnitY()).norm(), 0, 1e-12);
    EXPECT_NEAR(m.points[0].separation, gap, 1e-12);
    EXPECT_NEAR((m.points[0].position - Vector3d(0, std::sqrt(0.5) + 0.5 * gap, 0)).norm(), 0, 1e-12);
    // The same from B's side: the normal flips, the separation does not.
    const ContactManifold swapped = collide(box, pb, box, pa, 0.1, NarrowPhaseMethod::Exact);
    ASSERT_EQ(swapped.pointCount, 1);
    EXPECT_NEAR((swapped.normal + Vector3d::UnitY()).norm(), 0, 1e-12);
    EXPECT_NEAR(swapped.points[0].separation, gap, 1e-12);
  }
}

TEST(RigidNarrow, BoxRestingOnBox) {
  const ConvexHull ground = makeBoxHull(Vector3d(2, 0.5, 2));
  const ConvexHull box = makeBoxHull(Vector3d(0.5, 0.5, 0.5));
  const Pose pa;
  for (const double gap : {0.004, 0.0, -0.002}) {
    const Pose pb = makePose(Matrix3d::Identity(), Vector3d(0.3, 1 + gap, -0.2));
    const ContactManifold m = collide(ground, pa, box, pb, 0.01, NarrowPhaseMethod::Exact);
    ASSERT_EQ(m.pointCount, 4);
    EXPECT_NEAR((m.normal - Vector3d::UnitY()).norm(), 0, 1e-12);
    for (int k = 0; k < 4; ++k) {
      EXPECT_NEAR(m.points[k].separation, gap, 1e-12);
      EXPECT_NEAR(std::abs(m.points[k].position.x() - 0.3), 0.5, 1e-12);
      EXPECT_NEAR(std::abs(m.points[k].position.z() + 0.2), 0.5, 1e-12);
      EXPECT_NEAR(m.points[k].position.y(), 0.5 + 0.5 * gap, 1e-12);
    }
    // Swapped: the normal from the box to the ground, same separations.
    const ContactManifold s = collide(box, pb, ground, pa, 0.01, NarrowPhaseMethod::Exact);
    ASSERT_EQ(s.pointCount, 4);
    EXPECT_NEAR((s.normal + Vector3d::UnitY()).norm(), 0, 1e-12);
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(s.points[k].separation, gap, 1e-12);
  }
  // Beyond the margin: nothing.
  EXPECT_EQ(
      collide(ground, pa, box, makePose(Matrix3d::Identity(), Vector3d(0, 1.02, 0)), 0.01, NarrowPhaseMethod::Exact)
          .pointCount,
      0);
}

TEST(RigidNarrow, TiltedBoxSeparations) {
  const ConvexHull ground = makeBoxHull(Vector3d(2, 0.5, 2));
  const ConvexHull box = makeBoxHull(Vector3d(0.5, 0.5, 0.5));
  const Pose pa;
  const double angle = 0.02;
  const Matrix3d r = rotationAbout(Vector3d(1, 0, 0.3), angle);
  const Vector3d centre(0.1, 1.0, 0.05);
  const Pose pb = makePose(r, centre);
  const double margin = 0.05;
  const ContactManifold m = collide(ground, pa, box, pb, margin, NarrowPhaseMethod::Exact);
  ASSERT_EQ(m.pointCount, 4);
  EXPECT_NEAR((m.normal - Vector3d::UnitY()).norm(), 0, 1e-12);
  // Each point is a bottom corner of the box: its separation is the corner's height above
  // the ground's top (y = 0.5), its position the corner lowered by half that.
  int matched = 0;
  for (int k = 0; k < 4; ++k) {
    for (int c = 0; c < 4; ++c) {
      const Vector3d corner = r * Vector3d(c & 1 ? 0.5 : -0.5, -0.5, c & 2 ? 0.5 : -0.5) + centre;
      const double s = corner.y() - 0.5;
      if ((m.points[k].position - (corner - Vector3d(0, 0.5 * s, 0))).norm() < 1e-12) {
        EXPECT_NEAR(m.points[k].separation, s, 1e-12);
        ++matched;
      }
    }
  }
  EXPECT_EQ(matched, 4);
  // With a margin below the highest corner, only the corners within it remain.
  double lowest = kInf, highest = -kInf;
  for (int k = 0; k < 4; ++k) {
    lowest = std::min(lowest, m.points[k].separation);
    highest = std::max(highest, m.points[k].separation);
  }
  const ContactManifold tight = collide(ground, pa, box, pb, 0.5 * (lowest + highest), NarrowPhaseMethod::Exact);
  EXPECT_GE(tight.pointCount, 1);
  EXPECT_LT(tight.pointCount, 4);
  for (int k = 0; k < tight.pointCount; ++k) EXPECT_LE(tight.points[k].separation, 0.5 * (lowest + highest));
}

TEST(RigidNarrow, FeatureIdsStableUnderSmallMotion) {
  const ConvexHull ground = makeBoxHull(Vector3d(2, 0.5, 2));
  const ConvexHull box = makeBoxHull(Vector3d(0.5, 0.5, 0.5));
  const ConvexHull plank = makeBoxHull(Vector3d(1.0, 0.2, 0.3));
  const Pose pa;
  std::mt19937_64 rng(7);
  // Resting inside the top face (vertex ids), overhanging the edge (clip ids), and a
  // plank crossing a box (clipped against two side planes).
  struct Case {
    const ConvexHull* a;
    const ConvexHull* b;
    Pose pb;
    int points;
  };
  const Case cases[] = {
      {&ground, &box, makePose(rotationAbout(Vector3d::UnitY(), 0.3), Vector3d(0.2, 0.999, 0.1)), 4},
      {&ground, &box, makePose(rotationAbout(Vector3d::UnitY(), 0.4), Vector3d(1.8, 0.999, 0.3)), 4},
      {&box, &plank, makePose(rotationAbout(Vector3d::UnitY(), 0.7), Vector3d(0.1, 0.699, 0.05)), 4},
  };
  for (const Case& c : cases) {
    const ContactManifold m0 = collide(*c.a, pa, *c.b, c.pb, 0.01, NarrowPhaseMethod::Exact);
    ASSERT_EQ(m0.pointCount, c.points);
    std::vector<std::uint32_t> ids0;
    for (int k = 0; k < m0.pointCount; ++k) ids0.push_back(m0.points[k].featureId);
    std::sort(ids0.begin(), ids0.end());
    EXPECT_EQ(std::unique(ids0.begin(), ids0.end()), ids0.end()) << "distinct ids";
    for (int trial = 0; trial < 50; ++trial) {
      const Pose moved =
          makePose(rotationAbout(randomUnit(rng), 1e-5) * c.pb.rotation, c.pb.position + 1e-5 * randomUnit(rng));
      const ContactManifold m = collide(*c.a, pa, *c.b, moved, 0.01, NarrowPhaseMethod::Exact);
      ASSERT_EQ(m.pointCount, m0.pointCount);
      std::vector<std::uint32_t> ids;
      for (int k = 0; k < m.pointCount; ++k) ids.push_back(m.points[k].featureId);
      std::sort(ids.begin(), ids.end());
      EXPECT_EQ(ids, ids0);
    }
  }
}

TEST(RigidNarrow, ManyPointsReducedToFour) {
  // A 16-gon prism lying on a box: the clipped polygon has 16 points, four are kept: the
  // deepest among them (up to 0.1 mm), spread over the face.
  const ConvexHull prism = prismHull(16, 0.5, 0.3);
  const ConvexHull ground = makeBoxHull(Vector3d(2, 0.5, 2));
  const Pose pb = makePose(rotationAbout(Vector3d(1, 0, 0.5), 1e-3), Vector3d(0, 0.5 + 0.3 - 0.001, 0));
  const ContactManifold m = collide(ground, Pose{}, prism, pb, 0.01, NarrowPhaseMethod::Exact);
  ASSERT_EQ(m.pointCount, 4);
  double deepest = kInf;
  for (const Vector3d& v : worldVertices(prism, pb)) deepest = std::min(deepest, v.y() - 0.5);
  double minSep = kInf;
  for (int k = 0; k < 4; ++k) minSep = std::min(minSep, m.points[k].separation);
  EXPECT_NEAR(minSep, deepest, 1e-4);  // the deepest up to the reduction's depth tolerance (0.1 linear slop)
  // Spread: the quadrilateral covers most of the 16-gon's area (a square in a circle: 2/pi).
  const auto p = [&](int k) { return m.points[k].position; };
  double area = 0;
  for (int k = 1; k + 1 < 4; ++k) area += 0.5 * std::abs((p(k) - p(0)).cross(p(k + 1) - p(0)).y());
  // The four points may come in any order: take the largest of the three triangulations.
  double area2 =
      0.5 * std::abs((p(1) - p(0)).cross(p(3) - p(0)).y()) + 0.5 * std::abs((p(3) - p(1)).cross(p(2) - p(1)).y());
  EXPECT_GT(std::max(area, area2), 0.55 * M_PI * 0.25);
}

TEST(RigidNarrow, FacesWithManyVertices) {
  // A 200-gon prism (caps beyond the 128 vertices a clipped polygon keeps: subsampled)
  // standing on a box, and a box standing on its cap: four points at the right depth.
  const ConvexHull prism = prismHull(200, 0.6, 0.2);
  ASSERT_EQ(prism.faceCount(), 202);
  const ConvexHull ground = makeBoxHull(Vector3d(2, 0.5, 2));
  const ConvexHull box = makeBoxHull(Vector3d(0.3, 0.3, 0.3));
  const ContactManifold m = collide(ground, Pose{}, prism, makePose(Matrix3d::Identity(), Vector3d(0, 0.7 - 0.002, 0)),
                                    0.01, NarrowPhaseMethod::Exact);
  ASSERT_EQ(m.pointCount, 4);
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(m.points[k].separation, -0.002, 1e-12);
    EXPECT_LE(std::hypot(m.points[k].position.x(), m.points[k].position.z()), 0.6 + 1e-12);
  }
  const ContactManifold n =
      collide(prism, Pose{}, box, makePose(rotationAbout(Vector3d::UnitY(), 0.1), Vector3d(0.1, 0.5 - 0.001, 0)), 0.01,
              NarrowPhaseMethod::Exact);
  ASSERT_EQ(n.pointCount, 4);
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(n.points[k].separation, -0.001, 1e-12);
}

// ---------------------------------------------------------------------------------------
// Witness

TEST(RigidNarrow, WitnessMatchesExactOverSmallMotions) {
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> n(0, 1);
  long queries = 0, separatedHits = 0, touchingHits = 0, contacts = 0;
  const double baseMargin = 0.01;
  std::vector<ConvexHull> shapes;
  for (int i = 0; i < 40; ++i) shapes.push_back(randomHull(rng));
  // 10 000 sequences; a tenth under the sanitizers (the same code paths, 10-20x slower).
  const int sequences = weft::test::kSanitized ? 1000 : 10000;
  for (int sequence = 0; sequence < sequences; ++sequence) {
    const ConvexHull& a = shapes[sequence % shapes.size()];
    const ConvexHull& b = shapes[(sequence * 7 + 3) % shapes.size()];
    const Pose pa = makePose(randomRotation(rng), Vector3d::Zero());
    Pose pb = placeAt(a, pa, b, randomRotation(rng), randomUnit(rng), -0.02 + 0.05 * u(rng), 24);
    // A random walk of the relative pose: speed and spin between 1e-5 and 1e-2 per step.
    const double speed = std::pow(10.0, -5 + 3 * u(rng)), spin = std::pow(10.0, -5 + 3 * u(rng));
    const Vector3d velocity = speed * randomUnit(rng), omega = spin * randomUnit(rng);
    PairCache cache;
    NarrowPhaseOptions witness;
    witness.method = NarrowPhaseMethod::Witness;
    for (int step = 0; step < 12; ++step) {
      // The world's margin changes from step to step (it grows with the pair's motion).
      const double margin = baseMargin * (1 + 0.5 * u(rng));
      ContactManifold w;
      const NarrowPhaseOutcome outcome = collideHulls(a, pa, b, pb, margin, witness, cache, w);
      const ContactManifold e = collide(a, pa, b, pb, margin, NarrowPhaseMethod::Exact);
      ASSERT_TRUE(sameManifold(w, e, 1e-9)) << "sequence " << sequence << " step " << step;
      ++queries;
      contacts += e.pointCount > 0;
      separatedHits += outcome == NarrowPhaseOutcome::WitnessSeparated;
      touchingHits += outcome == NarrowPhaseOutcome::WitnessTouching;
      pb.position += velocity + 0.2 * speed * Vector3d(n(rng), n(rng), n(rng));
      pb.rotation = rotationAbout(omega, omega.norm()) * pb.rotation;
    }
  }
  std::printf("[ witness ] %ld queries, %ld with contact: %ld separated hits, %ld touching hits (%.1f %% of queries)\n",
              queries, contacts, separatedHits, touchingHits, 100.0 * (separatedHits + touchingHits) / queries);
  EXPECT_GT(touchingHits, 0);
  EXPECT_GT(separatedHits, 0);
}

TEST(RigidNarrow, WitnessRestingPairHitRate) {
  const ConvexHull ground = makeBoxHull(Vector3d(2, 0.5, 2));
  const ConvexHull box = makeBoxHull(Vector3d(0.5, 0.5, 0.5));
  const Pose pa;
  std::mt19937_64 rng(99);
  std::normal_distribution<double> n(0, 1);
  Pose pb = makePose(rotationAbout(Vector3d::UnitY(), 0.2), Vector3d(0.3, 0.999, 0.2));
  PairCache cache;
  NarrowPhaseOptions options;
  options.method = NarrowPhaseMethod::Witness;
  int hits = 0;
  const int steps = 1000;
  for (int step = 0; step < steps; ++step) {
    ContactManifold w;
    hits += collideHulls(ground, pa, box, pb, 0.01, options, cache, w) == NarrowPhaseOutcome::WitnessTouching;
    ASSERT_TRUE(sameManifold(w, collide(ground, pa, box, pb, 0.01, NarrowPhaseMethod::Exact), 1e-9));
    ASSERT_EQ(w.pointCount, 4);
    // Resting jitter: micrometres and microradians around the rest pose.
    pb.position = Vector3d(0.3, 0.999, 0.2) + 1e-6 * Vector3d(n(rng), n(rng), n(rng));
    pb.rotation = rotationAbout(Vector3d(n(rng), n(rng), n(rng)), 1e-6) * rotationAbout(Vector3d::UnitY(), 0.2);
  }
  std::printf("[ witness ] resting box: %d of %d queries reused the manifold\n", hits, steps);
  EXPECT_GE(hits, steps - 5);
}

TEST(RigidNarrow, WitnessSeparatedSlowPair) {
  const ConvexHull box = makeBoxHull(Vector3d(0.5, 0.5, 0.5));
  std::mt19937_64 rng(5);
  const Pose pa = makePose(randomRotation(rng), Vector3d::Zero());
  Pose pb = makePose(randomRotation(rng), Vector3d(2.0, 0.3, 0.1));
  PairCache cache;
  NarrowPhaseOptions options;
  options.method = NarrowPhaseMethod::Witness;
  for (int step = 0; step < 200; ++step) {
    ContactManifold w;
    const NarrowPhaseOutcome outcome = collideHulls(box, pa, box, pb, 0.01, options, cache, w);
    EXPECT_EQ(w.pointCount, 0);
    EXPECT_EQ(outcome, step == 0 ? NarrowPhaseOutcome::FullQuery : NarrowPhaseOutcome::WitnessSeparated);
    pb.position.x() -= 1e-4;
    pb.rotation = rotationAbout(Vector3d(0.2, 1, 0.3), 1e-3) * pb.rotation;
  }
}

// ---------------------------------------------------------------------------------------
// OFG

TEST(RigidNarrow, OfgMatchesExactOnBoxFaceContacts) {
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(0, 1);
  int compared = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const ConvexHull a = makeBoxHull(Vector3d(0.3 + u(rng), 0.3 + u(rng), 0.3 + u(rng)));
    const ConvexHull b = makeBoxHull(Vector3d(0.2 + 0.5 * u(rng), 0.2 + 0.5 * u(rng), 0.2 + 0.5 * u(rng)));
    // B resting on one of A's faces with a random turn about that face's normal, a small
    // tilt, and an offset keeping B's centre above the face.
    const int axis = trial % 3;
    const double side = (trial / 3) % 2 ? 1.0 : -1.0;
    Vector3d normal = Vector3d::Zero();
    normal[axis] = side;
    const Matrix3d turn = rotationAbout(normal, 2 * M_PI * u(rng));
    const Matrix3d tilt = rotationAbout(randomUnit(rng), 0.01 * u(rng));
    const Matrix3d rb = tilt * turn;
    const Pose pa;
    Vector3d offset = Vector3d::Zero();
    for (int k = 0; k < 3; ++k)
      if (k != axis) offset[k] = (u(rng) - 0.5) * 1.6 * a.vertices[0].cwiseAbs()[k];
    const Pose pb = placeAt(a, pa, b, rb, (normal + offset).normalized(), -0.004 + 0.008 * u(rng));
    const ContactManifold e = collide(a, pa, b, pb, 0.01, NarrowPhaseMethod::Exact);
    if (e.pointCount < 3) continue;  // an overhang turned it into an edge-like contact
    for (const int k : {4, 6}) {
      const ContactManifold o = collide(a, pa, b, pb, 0.01, NarrowPhaseMethod::Ofg, k);
      EXPECT_TRUE(sameManifold(o, e, 1e-12)) << "trial " << trial << " k " << k;
    }
    ++compared;
  }
  EXPECT_GT(compared, 200);
}

struct PairSample {
  const ConvexHull* a;
  const ConvexHull* b;
  Pose pa, pb;
};

/// Prints the OFG's recall (of the pairs the exact method finds in contact, the share the
/// OFG finds), how often its manifold is the exact one, and its false contacts, per k.
void printOfgRecall(const char* name, const std::vector<PairSample>& samples, double margin) {
  for (const int k : {1, 2, 4, 6, 8}) {
    int exactContacts = 0, found = 0, same = 0, falseContacts = 0, apart = 0;
    for (const PairSample& p : samples) {
      const ContactManifold e = collide(*p.a, p.pa, *p.b, p.pb, margin, NarrowPhaseMethod::Exact);
      const ContactManifold o = collide(*p.a, p.pa, *p.b, p.pb, margin, NarrowPhaseMethod::Ofg, k);
      if (e.pointCount > 0) {
        ++exactContacts;
        found += o.pointCount > 0;
        same += sameManifold(o, e, 1e-9) ? 1 : 0;
      } else {
        ++apart;
        falseContacts += o.pointCount > 0;
      }
    }
    std::printf("[ ofg %s k=%d ] recall %.1f %% (%d of %d contacts), same manifold %.1f %%, false contacts %d of %d\n",
                name, k, 100.0 * found / std::max(exactContacts, 1), found, exactContacts,
                100.0 * same / std::max(exactContacts, 1), falseContacts, apart);
  }
}

TEST(RigidNarrow, OfgRecallOnRandomPairs) {
  // Measured and printed, not asserted. Where the OFG reaches step 8 it cannot miss a
  // contact (its separation is a maximum over a subset of the exact method's axes, so never
  // larger); its misses come from the face selections' sphere test (step 6), its false
  // contacts from the axes it does not test (edge pairs, unselected faces).
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<ConvexHull> shapes;
  for (int i = 0; i < 30; ++i) shapes.push_back(randomHull(rng));
  // A quarter of the trials under the sanitizers (measured here, asserted nowhere).
  const int trials = weft::test::kSanitized ? 150 : 600;
  std::vector<PairSample> coarse;
  for (int trial = 0; trial < trials; ++trial) {
    const ConvexHull& a = shapes[trial % shapes.size()];
    const ConvexHull& b = shapes[(trial * 11 + 5) % shapes.size()];
    const Pose pa = makePose(randomRotation(rng), Vector3d::Zero());
    coarse.push_back({&a, &b, pa, placeAt(a, pa, b, randomRotation(rng), randomUnit(rng), -0.05 + 0.1 * u(rng))});
  }
  printOfgRecall("coarse hulls", coarse, 0.01);
  // Fine against long: a 400-face ball (hull of 202 points on a sphere) and a 4 x 0.2 x 0.2 bar.
  std::vector<Vector3d> ballPoints;
  for (int i = 0; i < 202; ++i) ballPoints.push_back(0.5 * randomUnit(rng));
  const ConvexHull ball = makeConvexHull(ballPoints);
  const ConvexHull bar = makeBoxHull(Vector3d(2, 0.1, 0.1));
  std::vector<PairSample> fine;
  for (int trial = 0; trial < trials / 2; ++trial) {
    const Pose pa = makePose(randomRotation(rng), Vector3d::Zero());
    fine.push_back(
        {&ball, &bar, pa, placeAt(ball, pa, bar, randomRotation(rng), randomUnit(rng), -0.05 + 0.1 * u(rng))});
  }
  printOfgRecall("ball-bar", fine, 0.01);
}

TEST(RigidNarrow, OfgFindsRestingFaceContacts) {
  // Coarse hulls (random points, <= 24 faces) resting face-down on a box: for k >= 4 the
  // OFG finds every contact the exact method finds.
  std::mt19937_64 rng(4242);
  std::uniform_real_distribution<double> u(0, 1);
  const ConvexHull ground = makeBoxHull(Vector3d(3, 0.5, 3));
  int contacts = 0;
  for (int trial = 0; trial < 300; ++trial) {
    ConvexHull body = randomHull(rng);
    // Put a random face of the body down: rotate its normal to -y.
    const int f = static_cast<int>(u(rng) * body.faceCount()) % body.faceCount();
    const Matrix3d down =
        Eigen::Quaterniond::FromTwoVectors(body.faces[f].normal, -Vector3d::UnitY()).toRotationMatrix();
    const Matrix3d rb = rotationAbout(Vector3d::UnitY(), 2 * M_PI * u(rng)) * down;
    const Pose pb = placeAt(ground, Pose{}, body, rb, Vector3d(u(rng) - 0.5, 2, u(rng) - 0.5).normalized(),
                            -0.003 + 0.006 * u(rng));
    const ContactManifold e = collide(ground, Pose{}, body, pb, 0.01, NarrowPhaseMethod::Exact);
    if (e.pointCount == 0) continue;
    ++contacts;
    for (const int k : {4, 6, 8}) {
      const ContactManifold o = collide(ground, Pose{}, body, pb, 0.01, NarrowPhaseMethod::Ofg, k);
      EXPECT_GT(o.pointCount, 0) << "trial " << trial << " k " << k;
    }
  }
  EXPECT_GT(contacts, 250);
}

// ---------------------------------------------------------------------------------------
// Sphere against hull

TEST(RigidNarrow, SphereAgainstHull) {
  const ConvexHull box = makeBoxHull(Vector3d(0.5, 0.4, 0.3));
  std::mt19937_64 rng(3);
  const Pose pose = makePose(randomRotation(rng), Vector3d(0.3, -0.2, 1.0));
  const auto world = [&](const Vector3d& x) { return Vector3d(pose.rotation * x + pose.position); };
  const double radius = 0.1;
  struct Case {
    Vector3d centre;   // box frame
    Vector3d closest;  // box frame
  };
  const Case outside[] = {
      {{0.2, 0.1, 0.3 + 0.15}, {0.2, 0.1, 0.3}},                  // near a face
      {{0.5 + 0.1, 0.4 + 0.05, 0.1}, {0.5, 0.4, 0.1}},            // near an edge
      {{0.5 + 0.08, -0.4 - 0.06, 0.3 + 0.05}, {0.5, -0.4, 0.3}},  // near a vertex
      {{-0.5 - 0.02, 0.0, 0.0}, {-0.5, 0.0, 0.0}},                // touching, penetrating
  };
  for (const Case& c : outside) {
    ContactManifold m;
    collideSphereHull(world(c.centre), radius, box, pose, 0.2, m);
    ASSERT_EQ(m.pointCount, 1);
    const double distance = (c.centre - c.closest).norm();
    EXPECT_NEAR(m.points[0].separation, distance - radius, 1e-12);
    const Vector3d normal = pose.rotation * (c.closest - c.centre).normalized();
    EXPECT_NEAR((m.normal - normal).norm(), 0, 1e-12);
    const Vector3d onSphere = world(c.centre) + radius * normal;
    EXPECT_NEAR((m.points[0].position - 0.5 * (onSphere + world(c.closest))).norm(), 0, 1e-12);
  }
  // Inside: out through the nearest face (+z here, 0.05 away).
  ContactManifold m;
  collideSphereHull(world(Vector3d(0.1, 0.05, 0.25)), radius, box, pose, 0.01, m);
  ASSERT_EQ(m.pointCount, 1);
  EXPECT_NEAR(m.points[0].separation, -0.05 - radius, 1e-12);
  EXPECT_NEAR((m.normal - pose.rotation * Vector3d(0, 0, -1)).norm(), 0, 1e-12);
  // Beyond the margin: nothing.
  collideSphereHull(world(Vector3d(0, 0, 0.3 + 0.5)), radius, box, pose, 0.2, m);
  EXPECT_EQ(m.pointCount, 0);
  // On a random hull: the separation agrees with brute force over faces, edges and vertices.
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (int trial = 0; trial < 300; ++trial) {
    const ConvexHull h = randomHull(rng);
    const Vector3d c(u(rng), u(rng), u(rng));
    collideSphereHull(c, radius, h, Pose{}, kInf, m);
    ASSERT_EQ(m.pointCount, 1);
    double inside = -kInf;
    for (const ConvexFace& f : h.faces) inside = std::max(inside, f.normal.dot(c) - f.offset);
    double distance = inside;
    if (inside > 0) {
      distance = kInf;
      for (const ConvexEdge& e : h.edges)
        distance = std::min(distance, pointSegmentDistance(c, h.vertices[e.v0], h.vertices[e.v1]));
      for (int f = 0; f < h.faceCount(); ++f) {
        const double d = h.faces[f].normal.dot(c) - h.faces[f].offset;
        if (d > 0 && insidePolygon(h, Pose{}, f, c - d * h.faces[f].normal, 0)) distance = std::min(distance, d);
      }
    }
    EXPECT_NEAR(m.points[0].separation, distance - radius, 1e-12) << "trial " << trial;
  }
}

}  // namespace
}  // namespace weft
