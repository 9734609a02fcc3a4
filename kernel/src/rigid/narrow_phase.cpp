// weft/rigid/narrow_phase.cpp — contact manifolds between convex hulls: the exact
// separating-axis test, the Opposing Face Geometry heuristic and the separating-plane
// witness (see the design note in narrow_phase.hpp).
//
// Frames. A query works in A's shape frame: B is placed there by the relative pose
// x_A = R x_B + p (R = RA^T RB, p = RA^T (pB - pA)), so A's faces and edges are used as
// stored and only B's features are rotated. A manifold whose reference face is B's is
// built in B's frame (the inverse relative pose) and its normal flipped at the end.
//
// The separating-axis test (Gregorius, GDC 2013). The candidate axes are the face
// normals of A, those of B, and for each edge pair that builds a face of the Minkowski
// difference M = B - A (their arcs on the Gauss map cross: A's arc between its two face
// normals, B's arc between its two negated face normals) the cross product of the two
// edges, oriented away from A's centroid. Together these are the face normals of M, so
// the largest separation along them is the exact SAT answer: the distance when the
// closest features are face-vertex or edge-edge, a lower bound of it otherwise, minus the
// penetration depth when the hulls overlap. Edge pairs closer to parallel than
// kParallelSine are skipped (their Minkowski face is a sliver of width below
// kParallelSine x the shorter edge, and its normal is ill-conditioned).
//
// No function here allocates or throws: polygons are clipped in fixed stack arrays
// (kMaxPolygon vertices a polygon; larger faces are subsampled, which keeps a convex
// polygon inside the face), the OFG keeps at most kMaxOfgFaces faces a side, and every
// loop runs in index order, so the result is deterministic.
#include "weft/rigid/narrow_phase.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>

#include "contact_manifold.hpp"
#include "narrow_phase_internal.hpp"
#include "sat_query.hpp"

namespace weft {

namespace {

// ---------------------------------------------------------------------------------------
// The three methods

/// The exact method. Fills `result` (for the witness cache) and the manifold.
void exactQuery(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB, const Relative& rel,
                double margin, SatResult& sat, Reference& reference, bool& regular, ContactManifold& out) {
  clearManifold(out);
  sat = satQuery(a, b, rel, margin);
  reference = Reference::None;
  regular = false;
  if (!sat.complete || !(sat.best() <= margin)) return;
  reference = chooseReference(sat);
  switch (reference) {
    case Reference::FaceA:
    case Reference::FaceB:
      regular = buildManifold(reference, a, poseA, b, poseB, rel, sat.faceA.index, sat.faceB.index, margin, out);
      break;
    case Reference::Edge:
      edgeContact(a, b, rel, sat.edgeA, sat.edgeB, sat.edgeAxis, sat.edgeBest, poseA, out);
      regular = true;
      break;
    case Reference::None:
      break;
  }
}

/// Opposing Face Geometry (the original design's 8 steps), in A's frame.
void ofgQuery(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB, const Relative& rel,
              double margin, int k, ContactManifold& out) {
  clearManifold(out);
  const Relative inv = inversePose(rel);
  // 1. Bounding spheres of the whole hulls.
  const Vector3d centreB = rel.rotation * b.centroid + rel.position;
  if ((centreB - a.centroid).norm() > a.boundingRadius + b.boundingRadius + margin) return;

  const auto faceCentre = [](const ConvexHull& h, int f) {
    Vector3d c = Vector3d::Zero();
    const std::span<const int> idx = h.faceIndices(f);
    for (const int v : idx) c += h.vertices[static_cast<std::size_t>(v)];
    return idx.empty() ? c : Vector3d(c / static_cast<double>(idx.size()));
  };
  // The k faces of h whose centres are closest to `target` (h's frame), sorted by distance
  // (insertion into a sorted array; ties keep index order).
  const auto closestFaces = [&](const ConvexHull& h, const Vector3d& target, int kk, int* faces, double* dist) {
    int m = 0;
    for (int f = 0; f < h.faceCount(); ++f) {
      const double d = (faceCentre(h, f) - target).squaredNorm();
      if (m == kk && !(d < dist[m - 1])) continue;
      int pos = m < kk ? m++ : kk - 1;
      while (pos > 0 && d < dist[pos - 1]) {
        dist[pos] = dist[pos - 1];
        faces[pos] = faces[pos - 1];
        --pos;
      }
      dist[pos] = d;
      faces[pos] = f;
    }
    return m;
  };
  // Centre of a face selection (mean of the face centres) and its bounding radius.
  const auto selectionSphere = [&](const ConvexHull& h, const int* faces, int m, Vector3d& centre) {
    centre = Vector3d::Zero();
    for (int s = 0; s < m; ++s) centre += faceCentre(h, faces[s]);
    centre /= static_cast<double>(std::max(m, 1));
    double r2 = 0;
    for (int s = 0; s < m; ++s)
      for (const int v : h.faceIndices(faces[s]))
        r2 = std::max(r2, (h.vertices[static_cast<std::size_t>(v)] - centre).squaredNorm());
    return std::sqrt(r2);
  };

  std::array<int, kMaxOfgFaces> facesA, facesB;
  std::array<double, kMaxOfgFaces> distA, distB;
  // 2. The k faces of A closest to B's centre; 3. their centre and sphere.
  const int ka = closestFaces(a, centreB, std::min(k, a.faceCount()), facesA.data(), distA.data());
  Vector3d selA;
  const double radiusA = selectionSphere(a, facesA.data(), ka, selA);
  // 4. The k faces of B closest to that centre; 5. their centre and sphere.
  const Vector3d selAinB = inv.rotation * selA + inv.position;
  const int kb = closestFaces(b, selAinB, std::min(k, b.faceCount()), facesB.data(), distB.data());
  Vector3d selBlocal;
  const double radiusB = selectionSphere(b, facesB.data(), kb, selBlocal);
  const Vector3d selB = rel.rotation * selBlocal + rel.position;
  // 6. The two selections' spheres.
  if (ka == 0 || kb == 0 || (selB - selA).norm() > radiusA + radiusB + margin) return;
  // 7. Sort each set by the distance of its faces to the other selection's centre.
  const auto resort = [&](const ConvexHull& h, const Vector3d& target, int* faces, double* dist, int m) {
    for (int s = 0; s < m; ++s) dist[s] = (faceCentre(h, faces[s]) - target).squaredNorm();
    for (int s = 1; s < m; ++s) {
      const int f = faces[s];
      const double d = dist[s];
      int pos = s;
      while (pos > 0 && d < dist[pos - 1]) {
        dist[pos] = dist[pos - 1];
        faces[pos] = faces[pos - 1];
        --pos;
      }
      dist[pos] = d;
      faces[pos] = f;
    }
  };
  resort(a, selB, facesA.data(), distA.data(), ka);
  resort(b, inv.rotation * selA + inv.position, facesB.data(), distB.data(), kb);
  // 8. The selected face axes, closest first; any that separates by more than the margin
  // ends the query. The best of each side then decides as in the exact method (no edges).
  SatResult sat;
  for (int s = 0; s < std::max(ka, kb); ++s) {
    if (s < ka) {
      const double sep = faceSeparationA(a, b, rel, facesA[static_cast<std::size_t>(s)]);
      if (sep > margin) return;
      sat.faceA.add(sep, facesA[static_cast<std::size_t>(s)]);
    }
    if (s < kb) {
      const double sep = faceSeparationB(a, b, rel, facesB[static_cast<std::size_t>(s)]);
      if (sep > margin) return;
      sat.faceB.add(sep, facesB[static_cast<std::size_t>(s)]);
    }
  }
  // The incident face is sought among the other side's selection (O(k), the OFG's point).
  if (chooseReference(sat) == Reference::FaceB)
    faceContact(b, a, inv, sat.faceB.index, facesA.data(), ka, margin, poseB, true, out);
  else
    faceContact(a, b, rel, sat.faceA.index, facesB.data(), kb, margin, poseA, false, out);
}

// Witness motion bound. Let the relative pose change from (R, p) at the last full query to
// (R', p') now, and write B's vertices about its centroid cB: x_A = R (b - cB) + q with
// q = R cB + p. For an axis n fixed in A's frame (a face of A, or any fixed direction) the
// separation min_b n . x_A - max_a n . a changes by at most
//     max_b |n . ((R' - R)(b - cB) + (q' - q))| <= |q' - q| + ||R' - R||_2 rB = deltaA,
// because a minimum of functions that each move by at most e moves by at most e. Likewise
// for an axis fixed in B's frame (a face of B), with A's centroid in B's frame w = R^T (cA - p):
//     deltaB = |w' - w| + ||R' - R||_2 rA.
// ||R' - R||_2 = 2 sin(theta / 2) <= theta for the rotation angle theta of R' R^T; we use the
// Frobenius norm, which is sqrt(2) times as large for rotations (and still an upper bound for
// slightly non-orthonormal input). Edge axes turn with the rotation, at a rate up to
// 1 / sin(angle between the edges), so no such per-axis bound holds for them; instead every
// edge axis's separation is a value of g(u) = min_{x in M} u . x, and the largest value of g
// over all unit u, G, is a maximum over directions fixed in A's frame (or in B's): G moves by
// at most min(deltaA, deltaB). G is an upper bound of every edge axis's separation, and G is
// known at the last full query: when the hulls overlapped (S <= 0) the maximum of g over all
// directions is attained at a face normal of M, i.e. G = S (plus the width of any skipped
// near-parallel sliver face); when they were apart, G is their distance, at most the length
// of any segment joining them, e.g. a manifold point's |separation| (its incident point lies
// on B's face and its projection on A's reference face). With delta = max(deltaA, deltaB):
//   - the reference face stays the best face of its hull while delta < (lead over the
//     runner-up of the same hull) / 2;
//   - the face-A/face-B preference test keeps its outcome while delta < slack / (2 + c),
//     c = kFaceRelTolerance, since x + c|x| + t moves by at most (1 + c) delta;
//   - no edge axis gets preferred while delta < (F + cE |F| + t - G) / (2 + cE).
// PairCache::axisGap stores the smallest of these, scaled to the common form "reuse while
// delta < axisGap / 2". Then the exact method would choose the same reference face, and the
// manifold, built by the same code from the current pose, is the same.
double motionBound(const ConvexHull& a, const ConvexHull& b, const PairCache& cache, const Relative& rel) {
  const Matrix3d& r0 = cache.relativeRotation;
  const Vector3d& p0 = cache.relativePosition;
  const double dr = (rel.rotation - r0).norm();  // Frobenius
  const Vector3d dq = (rel.rotation * b.centroid + rel.position) - (r0 * b.centroid + p0);
  const Vector3d dw = rel.rotation.transpose() * (a.centroid - rel.position) - r0.transpose() * (a.centroid - p0);
  const double deltaA = dq.norm() + dr * b.boundingRadius;
  const double deltaB = dw.norm() + dr * a.boundingRadius;
  // Rounding of the separations themselves (a few ulps of the coordinates).
  const double scale = 1 + a.boundingRadius + b.boundingRadius + rel.position.norm();
  return std::max(deltaA, deltaB) + 1e-13 * scale;
}

/// Fills the cache after a full exact query.
void refillCache(const SatResult& sat, Reference reference, bool regular, const ContactManifold& out,
                 const Relative& rel, double margin, PairCache& cache) {
  cache.relativeRotation = rel.rotation;
  cache.relativePosition = rel.position;
  cache.axisGap = 0;
  const double best = sat.best();
  const auto setAxis = [&](PairCache::Axis axis) {
    cache.axis = axis;
    cache.indexA = axis == PairCache::Axis::FaceA      ? sat.faceA.index
                   : axis == PairCache::Axis::EdgePair ? sat.edgeA
                                                       : -1;
    cache.indexB = axis == PairCache::Axis::FaceB      ? sat.faceB.index
                   : axis == PairCache::Axis::EdgePair ? sat.edgeB
                                                       : -1;
  };
  if (!(best <= margin) || reference == Reference::None) {
    cache.touching = false;
    if (!(best > margin)) {  // non-finite input: forget everything
      cache.axis = PairCache::Axis::None;
      cache.indexA = cache.indexB = -1;
      return;
    }
    // The axis that separates (the best one found; with an early stop, the query that stopped).
    if (sat.faceA.best >= sat.faceB.best && sat.faceA.best >= sat.edgeBest)
      setAxis(PairCache::Axis::FaceA);
    else if (sat.faceB.best >= sat.edgeBest)
      setAxis(PairCache::Axis::FaceB);
    else
      setAxis(PairCache::Axis::EdgePair);
    return;
  }
  cache.touching = true;
  if (reference == Reference::Edge) {
    setAxis(PairCache::Axis::EdgePair);
    return;  // axisGap 0: an edge manifold is never reused (its axis turns with the motion)
  }
  setAxis(reference == Reference::FaceA ? PairCache::Axis::FaceA : PairCache::Axis::FaceB);
  if (!regular) return;  // fallback point: its pair of points does not bound the distance
  // G, the upper bound of every axis's separation (see motionBound).
  double g = best + 2 * sat.sliverWidth;
  if (best > 0) {
    double closest = kInf;
    for (int k = 0; k < out.pointCount; ++k)
      closest = std::min(closest, std::abs(out.points[static_cast<std::size_t>(k)].separation));
    g = closest;
  }
  const double fa = sat.faceA.best, fb = sat.faceB.best, f = std::max(fa, fb);
  const double edgeSlack = f + kEdgeRelTolerance * std::abs(f) + kAbsTolerance - g;
  double lead, faceSlack;
  if (reference == Reference::FaceA) {
    lead = fa - sat.faceA.second;
    faceSlack = fa + kFaceRelTolerance * std::abs(fa) + kAbsTolerance - fb;
  } else {
    lead = fb - sat.faceB.second;
    faceSlack = fb - fa - kFaceRelTolerance * std::abs(fa) - kAbsTolerance;
  }
  const double gap = std::min({lead, 2 * faceSlack / (2 + kFaceRelTolerance), 2 * edgeSlack / (2 + kEdgeRelTolerance)});
  cache.axisGap = gap > 0 && std::isfinite(gap) ? gap : (gap > 0 ? 1e300 : 0.0);
}

bool validIndex(int i, int count) { return i >= 0 && i < count; }

/// The separation along the cached axis in the current pose, if that axis is one the exact
/// method would test (a face, or an edge pair that still builds a Minkowski face).
bool cachedAxisSeparation(const ConvexHull& a, const ConvexHull& b, const Relative& rel, const PairCache& cache,
                          double& separation) {
  switch (cache.axis) {
    case PairCache::Axis::FaceA:
      if (!validIndex(cache.indexA, a.faceCount())) return false;
      separation = faceSeparationA(a, b, rel, cache.indexA);
      return true;
    case PairCache::Axis::FaceB:
      if (!validIndex(cache.indexB, b.faceCount())) return false;
      separation = faceSeparationB(a, b, rel, cache.indexB);
      return true;
    case PairCache::Axis::EdgePair: {
      if (!validIndex(cache.indexA, a.edgeCount()) || !validIndex(cache.indexB, b.edgeCount())) return false;
      Vector3d axis;
      double width = 0;
      return edgePairSeparation(edgeOfA(a, cache.indexA), edgeOfB(b, rel, cache.indexB), a.centroid, separation, axis,
                                width) == EdgePairKind::MinkowskiFace;
    }
    case PairCache::Axis::None:
      break;
  }
  return false;
}

NarrowPhaseOutcome witnessQuery(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB,
                                const Relative& rel, double margin, PairCache& cache, ContactManifold& out) {
  clearManifold(out);
  double s = 0;
  if (cachedAxisSeparation(a, b, rel, cache, s)) {
    // An axis of the exact method's set separating by more than the margin: the exact
    // method's best is at least s, so it too reports no contact.
    if (s > margin) {
      cache.touching = false;
      return NarrowPhaseOutcome::WitnessSeparated;
    }
    const bool face = cache.axis == PairCache::Axis::FaceA || cache.axis == PairCache::Axis::FaceB;
    if (cache.touching && face && motionBound(a, b, cache, rel) < 0.5 * cache.axisGap) {
      // The reference face is unchanged (see motionBound). The exact method reports contact
      // iff its best S' <= margin; with the preference tests unchanged,
      // S' <= F + cE |F| + t where F bounds both face maxima:
      //   face A chosen: fb' <= fa' + cF |fa'| + t, so F = fa' + cF |fa'| + t;
      //   face B chosen: fa' < fb', so F = fb'.
      const double f = cache.axis == PairCache::Axis::FaceA ? s + kFaceRelTolerance * std::abs(s) + kAbsTolerance : s;
      if (f + kEdgeRelTolerance * std::abs(f) + kAbsTolerance <= margin) {
        buildManifold(cache.axis == PairCache::Axis::FaceA ? Reference::FaceA : Reference::FaceB, a, poseA, b, poseB,
                      rel, cache.indexA, cache.indexB, margin, out);
        return NarrowPhaseOutcome::WitnessTouching;
      }
    }
  }
  SatResult sat;
  Reference reference;
  bool regular;
  exactQuery(a, poseA, b, poseB, rel, margin, sat, reference, regular, out);
  refillCache(sat, reference, regular, out, rel, margin, cache);
  return NarrowPhaseOutcome::FullQuery;
}

}  // namespace

const char* narrowPhaseMethodName(NarrowPhaseMethod method) {
  switch (method) {
    case NarrowPhaseMethod::Exact:
      return "exact";
    case NarrowPhaseMethod::Ofg:
      return "ofg";
    case NarrowPhaseMethod::Witness:
      return "witness";
  }
  return "unknown";
}

NarrowPhaseOutcome collideHulls(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB,
                                double margin, const NarrowPhaseOptions& options, PairCache& cache,
                                ContactManifold& out) {
  clearManifold(out);
  if (a.faceCount() == 0 || b.faceCount() == 0 || a.vertexCount() == 0 || b.vertexCount() == 0)
    return NarrowPhaseOutcome::FullQuery;
  const Relative rel = relativePose(poseA, poseB);
  switch (options.method) {
    case NarrowPhaseMethod::Exact: {
      SatResult sat;
      Reference reference;
      bool regular;
      exactQuery(a, poseA, b, poseB, rel, margin, sat, reference, regular, out);
      return NarrowPhaseOutcome::FullQuery;
    }
    case NarrowPhaseMethod::Ofg:
      // RigidOptions refuses k outside [1, kMaxOfgFaces]; the clamp guards direct callers' arrays.
      ofgQuery(a, poseA, b, poseB, rel, margin, std::clamp(options.ofgFaces, 1, kMaxOfgFaces), out);
      return NarrowPhaseOutcome::FullQuery;
    case NarrowPhaseMethod::Witness:
      return witnessQuery(a, poseA, b, poseB, rel, margin, cache, out);
  }
  return NarrowPhaseOutcome::FullQuery;
}

void collideSphereHull(const Eigen::Vector3d& centre, double radius, const ConvexHull& b, const Pose& poseB,
                       double margin, ContactManifold& out) {
  clearManifold(out);
  if (b.faceCount() == 0) return;
  const Vector3d c = poseB.rotation.transpose() * (centre - poseB.position);  // B's frame
  int deepest = 0;
  double deepestDistance = -kInf;
  for (int f = 0; f < b.faceCount(); ++f) {
    const ConvexFace& face = b.faces[static_cast<std::size_t>(f)];
    const double d = face.normal.dot(c) - face.offset;
    if (d > deepestDistance) {
      deepestDistance = d;
      deepest = f;
    }
  }
  if (!(deepestDistance > -kInf)) return;  // non-finite input
  Vector3d closest = c;                    // on the hull, B's frame
  Vector3d normal = Vector3d::UnitY();     // from the sphere to the hull, B's frame
  double distance = 0;                     // signed: < 0 inside
  std::uint32_t feature = 0;
  if (deepestDistance <= 0) {
    // Inside: out through the face of least penetration.
    const ConvexFace& face = b.faces[static_cast<std::size_t>(deepest)];
    closest = c - deepestDistance * face.normal;
    normal = -face.normal;
    distance = deepestDistance;
    feature = mixId(kTagFace, u32(deepest));
  } else {
    // Outside: the closest point lies on a face that faces the centre (d > 0).
    double best2 = kInf;
    for (int f = 0; f < b.faceCount(); ++f) {
      const ConvexFace& face = b.faces[static_cast<std::size_t>(f)];
      const double d = face.normal.dot(c) - face.offset;
      if (!(d > 0) || d * d >= best2) continue;
      const std::span<const int> idx = b.faceIndices(f);
      const int n = static_cast<int>(idx.size());
      const Vector3d x = c - d * face.normal;  // projection on the plane
      bool inside = n >= 3;
      for (int k = 0; k < n && inside; ++k) {
        const Vector3d& v0 = b.vertices[static_cast<std::size_t>(idx[static_cast<std::size_t>(k)])];
        const Vector3d& v1 = b.vertices[static_cast<std::size_t>(idx[static_cast<std::size_t>((k + 1) % n)])];
        if ((v1 - v0).cross(x - v0).dot(face.normal) < 0) inside = false;
      }
      if (inside) {
        best2 = d * d;
        closest = x;
        feature = mixId(kTagFace, u32(f));
        continue;
      }
      for (int k = 0; k < n; ++k) {
        const int i0 = idx[static_cast<std::size_t>(k)], i1 = idx[static_cast<std::size_t>((k + 1) % n)];
        const Vector3d& v0 = b.vertices[static_cast<std::size_t>(i0)];
        const Vector3d e = b.vertices[static_cast<std::size_t>(i1)] - v0;
        const double l2 = e.squaredNorm();
        const double t = l2 > 0 ? std::clamp((c - v0).dot(e) / l2, 0.0, 1.0) : 0.0;
        const Vector3d y = v0 + t * e;
        const double dist2 = (c - y).squaredNorm();
        if (dist2 < best2) {
          best2 = dist2;
          closest = y;
          // The feature: a vertex at the ends, else the edge (its vertex pair, order-free).
          feature = t <= 0   ? mixId(kTagVertex, u32(i0))
                    : t >= 1 ? mixId(kTagVertex, u32(i1))
                             : mixId(mixId(kTagEdge, u32(std::min(i0, i1))), u32(std::max(i0, i1)));
        }
      }
    }
    distance = std::sqrt(best2);
    const double tiny = 1e-12 * (1 + b.boundingRadius);
    normal = distance > tiny ? Vector3d((closest - c) / distance)
                             : Vector3d(-b.faces[static_cast<std::size_t>(deepest)].normal);
  }
  const double separation = distance - radius;
  if (!(separation <= margin)) return;
  const Vector3d onSphere = c + radius * normal;
  out.normal = poseB.rotation * normal;
  out.pointCount = 1;
  out.points[0].position = poseB.rotation * (0.5 * (onSphere + closest)) + poseB.position;
  out.points[0].separation = separation;
  out.points[0].featureId = mixId(kTagSphere, feature);
}

double hullSeparation(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB) {
  if (a.faceCount() == 0 || b.faceCount() == 0) return kInf;
  return satQuery(a, b, relativePose(poseA, poseB), kInf).best();
}

}  // namespace weft
