// weft/model/topology.hpp — what is derived from a Model's springs and triangles.
//
// Design note
// -----------
// Several parts of a step read lists that follow from the model's connectivity alone:
// the particle -> spring incidence (the Gather force strategy's per-particle sum and
// implicit Euler's spring Jacobian), the particle -> triangle incidence (wind's gather),
// a greedy edge colouring of the springs (the Coloured force strategy), whether the
// triangles are exactly a cloth grid's (wind's stencil path), and the edges the contact
// pass tests against mesh edges (structural and shear springs). They belong to the Model
// (as MuJoCo keeps flex_edge and flex_evpair in mjModel and Jolt keeps its update groups
// in the shared soft-body settings), not to each Simulation: the Model computes each one
// the first time something asks for it, under a std::call_once, keeps it, and hands the
// same object to every Simulation that shares the Model. A scene that never asks for one
// (a grid flag on the stencil path needs no incidence) neither computes nor stores it.
//
// Invariants: every list is in ascending index order (spring s, triangle t), so a sum
// over a particle's list has one fixed order on every thread count; a colour holds no
// two springs that share a particle; entries never change once computed.
#pragma once

#include <array>
#include <vector>

#include "weft/core/types.hpp"

namespace weft {

/// A pair of particles joined by an edge (a cloth's side or a rope's link).
using Edge = std::array<Index, 2>;

/// Compressed lists particle -> items: particle i's items are entries[offsets[i] ..
/// offsets[i + 1]), ascending.
struct Incidence {
  IndexArray offsets;  // (n + 1)
  IndexArray entries;  // (total), meaning fixed by the list (see each accessor)

  Index begin(Index i) const { return offsets[i]; }
  Index end(Index i) const { return offsets[i + 1]; }
};

/// The triangles' edges and which triangle "owns" each edge and each vertex, for the
/// self-collision pass (weft/collide/self_collision.hpp): it visits pairs of triangles
/// whose boxes overlap and tests only the primitives the two triangles own, so every
/// vertex-triangle and edge-edge pair is tested once. A vertex and an edge are owned by the
/// lowest-numbered triangle that has them.
struct SurfaceTopology {
  std::vector<Edge> edges;  // the triangles' sides, each once as (low, high), ascending
  Incidence ownedEdges;     // triangle -> the edges (indices into `edges`) it owns
  Incidence ownedVertices;  // triangle -> the particles it owns
};

/// The springs permuted into colour order: colour c holds springs [offsets[c],
/// offsets[c + 1]) of the permuted arrays, no two of which share a particle.
template <class S>
struct SpringColouring {
  std::vector<Index> offsets;  // (colours + 1)
  IndexArray a, b;             // (m) endpoints, colour order
  ScalarArray<S> restLength;   // (m) m
  ScalarArray<S> stiffness;    // (m) N/m
  ScalarArray<S> damping;      // (m) N s/m

  Index colourCount() const { return offsets.empty() ? 0 : static_cast<Index>(offsets.size()) - 1; }
};

}  // namespace weft
