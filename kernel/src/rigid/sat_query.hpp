// Part of narrow_phase.cpp (see narrow_phase_internal.hpp): the exact separating-axis test
// between convex hulls (Gregorius, GDC 2013) — face queries of A and B, then the edge pairs
// whose Gauss-map arcs cross — and the choice of the feature that builds the manifold.
#pragma once

#include <algorithm>
#include <cmath>

#include "narrow_phase_internal.hpp"

namespace weft {
namespace {

/// The exact SAT. Stops as soon as an axis separates by more than stopAbove (after the
/// face queries of A, those of B, or at that edge pair).
SatResult satQuery(const ConvexHull& a, const ConvexHull& b, const Relative& rel, double stopAbove) {
  SatResult r;
  for (int i = 0; i < a.faceCount(); ++i) r.faceA.add(faceSeparationA(a, b, rel, i), i);
  if (r.faceA.best > stopAbove) {
    r.complete = false;
    return r;
  }
  for (int j = 0; j < b.faceCount(); ++j) r.faceB.add(faceSeparationB(a, b, rel, j), j);
  if (r.faceB.best > stopAbove) {
    r.complete = false;
    return r;
  }
  // B's edge outside (rotated once), A's edges inside: no buffer of transformed edges.
  for (int j = 0; j < b.edgeCount(); ++j) {
    const EdgeFrame eb = edgeOfB(b, rel, j);
    for (int i = 0; i < a.edgeCount(); ++i) {
      // Most pairs fail the first arc test: make it from the two normals alone.
      const ConvexEdge& edge = a.edges[static_cast<std::size_t>(i)];
      const Vector3d vxu = a.faces[static_cast<std::size_t>(edge.face1)].normal.cross(
          a.faces[static_cast<std::size_t>(edge.face0)].normal);
      if (!(eb.u.dot(vxu) * eb.v.dot(vxu) < 0)) continue;
      const EdgeFrame ea = edgeOfA(a, i);
      double s = 0, width = 0;
      Vector3d axis;
      switch (edgePairSeparation(ea, eb, a.centroid, s, axis, width)) {
        case EdgePairKind::MinkowskiFace:
          if (s > r.edgeBest) {
            r.edgeBest = s;
            r.edgeA = i;
            r.edgeB = j;
            r.edgeAxis = axis;
            if (s > stopAbove) {
              r.complete = false;
              return r;
            }
          }
          break;
        case EdgePairKind::Parallel:
          r.sliverWidth = std::max(r.sliverWidth, width);
          break;
        case EdgePairKind::NotMinkowskiFace:
          break;
      }
    }
  }
  return r;
}

/// The feature that builds the manifold (see the preference tolerances above).
Reference chooseReference(const SatResult& r) {
  const double fa = r.faceA.best, fb = r.faceB.best;
  if (r.faceA.index < 0 && r.faceB.index < 0) return r.edgeA >= 0 ? Reference::Edge : Reference::None;
  const double f = std::max(fa, fb);
  if (r.edgeA >= 0 && r.edgeBest > f + kEdgeRelTolerance * std::abs(f) + kAbsTolerance) return Reference::Edge;
  if (r.faceA.index < 0) return Reference::FaceB;
  if (r.faceB.index >= 0 && fb > fa + kFaceRelTolerance * std::abs(fa) + kAbsTolerance) return Reference::FaceB;
  return Reference::FaceA;
}

}  // namespace
}  // namespace weft
