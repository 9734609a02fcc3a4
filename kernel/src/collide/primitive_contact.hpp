// collide/primitive_contact.hpp (internal): the continuous vertex-triangle and edge-edge
// proximity queries (conservative advancement, defined in self_collision.cpp) that the
// self-collision pass and the contact pass's mesh corners are built on.
#pragma once

#include "collide/geometry.hpp"

namespace weft {

/// What a continuous proximity query found (the two queries below).
struct PrimitiveContact {
  bool hit = false;
  bool capped = false;               // the step cap was reached: reported as a contact without proof
  double time = 0;                   // s in [0, 1] where the distance was below the threshold
  double distance = 0;               // the distance there, m
  double weights[4] = {0, 0, 0, 0};  // beta of the four vertices (see the design note)
  double normal[3] = {0, 0, 0};      // unit, towards the first primitive; zero if undefined
};

/// A moving point p against a moving triangle (a, b, c), or a moving edge (p, a) against a
/// moving edge (b, c): index 0 of each array is the position at s = 0, index 1 at s = 1.
/// Returns the first s found with distance < threshold (> 0), starting at `start`; no hit
/// proves the distance stayed >= threshold / 2 over [start, 1].
PrimitiveContact vertexTriangleContact(const Vec3<double> p[2], const Vec3<double> a[2], const Vec3<double> b[2],
                                       const Vec3<double> c[2], double threshold, double start = 0);
PrimitiveContact edgeEdgeContact(const Vec3<double> p[2], const Vec3<double> q[2], const Vec3<double> a[2],
                                 const Vec3<double> b[2], double threshold, double start = 0);

/// The first evaluation of either query from start = 0, on its own: the distance at s = 0
/// and the square of the Lipschitz bound's core. A pass that has many queries to make takes
/// this look at all of them first (independent work the processor overlaps, where one query
/// after another is a chain of dependent loads, square roots and branches), and makes the
/// full query only for those `firstLookProvesApart` leaves open: for the others the full
/// query would return no hit from the same two numbers.
struct FirstLook {
  double distance = 0;
  double lipschitz2 = 0;
};
FirstLook vertexTriangleFirstLook(const Vec3<double> p[2], const Vec3<double> a[2], const Vec3<double> b[2],
                                  const Vec3<double> c[2]);
FirstLook edgeEdgeFirstLook(const Vec3<double> p[2], const Vec3<double> q[2], const Vec3<double> a[2],
                            const Vec3<double> b[2]);
/// True when the query from start = 0 at this threshold returns no hit at its first step.
bool firstLookProvesApart(const FirstLook& look, double threshold);

/// The edge-edge first looks of up to kFirstLookBatch queries at once, in structure of
/// arrays: x[i][a][k] is coordinate a of vertex i (the edges p q and a b) of query k at s = 0,
/// d[i][a][k] its displacement over the chunk. The formulas of edgeEdgeFirstLook, computed
/// without branches so that the loop vectorises; lengths[k] is the sum of the two edges'
/// lengths. A query with an edge shorter than the closest-point routine's tiny length, or
/// with a coordinate or displacement that is not finite, gets distance -1 (its full query
/// decides). The values are not always the same bits as one by one: the compiler fuses other
/// products, and the closest points of nearly parallel edges are ill-conditioned (the two
/// routines may then take different ends, a distance apart of at most about the edges'
/// length times the angle between them, itself ~1e-8 at most there). batchedLook() adds the
/// guard band that makes a proof from these values a proof for the one-by-one look.
inline constexpr int kFirstLookBatch = 32;
void edgeEdgeFirstLooks(int count, const double (&x)[4][3][kFirstLookBatch], const double (&d)[4][3][kFirstLookBatch],
                        double (&distance)[kFirstLookBatch], double (&lipschitz2)[kFirstLookBatch],
                        double (&lengths)[kFirstLookBatch]);
/// A batched edge-edge look as the pass uses it: the distance shrunk by a relative 1e-6 and by
/// 1e-7 of the edges' lengths, the Lipschitz core grown by 1e-12, so that
/// firstLookProvesApart on it implies the same for the one-by-one look (pairs within the band
/// go to the full query, which decides as it always did).
inline FirstLook batchedLook(double distance, double lipschitz2, double lengths) {
  return {distance * (1 - 1e-6) - 1e-7 * lengths, lipschitz2 * (1 + 1e-12)};
}

}  // namespace weft
