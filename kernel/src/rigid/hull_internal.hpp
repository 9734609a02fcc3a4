// hull_internal.hpp — what the hull builders share (private to kernel/src/rigid).
#pragma once

#include "weft/rigid/convex_hull.hpp"

namespace weft::rigid_detail {

/// Fills edges (see the conventions at the top of convex_hull.cpp), centroid and
/// boundingRadius from vertices, faces and faceVertices. Throws std::logic_error when a
/// directed edge appears twice or an edge has only one face (the callers build closed
/// manifolds, so that is a bug here).
void finishHull(ConvexHull& hull);

}  // namespace weft::rigid_detail
