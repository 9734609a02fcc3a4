// weft/collide/self_collision.hpp — a cloth against itself and against other cloths:
// proximity and continuous detection between its own vertices, edges and triangles, a
// response with friction, and a failsafe that never leaves two triangles intersecting.
//
// Design note
// -----------
// Every cloth of a Model is one triangle set here, so a cloth folding onto itself and two
// cloths meeting are the same problem. The pass runs on each chunk x0 -> x1 of a step (the
// chunks of the collision pipeline, after the obstacles' contact pass), each vertex moving
// on a straight line over the chunk, time s in [0, 1]:
//
//   candidates  The triangles' BVH (built once) is refit with swept boxes (x0 and x1,
//               inflated by half the thickness plus a skin) and queried for overlapping
//               triangle pairs, neighbours included: the candidates. The list is kept while
//               every vertex's x0 and x1 stay inside its skin box (its box at the gathering,
//               grown by the skin; as molecular dynamics keeps Verlet lists): a cloth moving
//               less than the skin per step gathers anew every few steps, not every chunk.
//               Each pass boxes every triangle over its chunk (without the skin) and skips
//               the candidate pairs whose boxes are farther apart than the thickness; of the
//               others, each triangle tests only the vertices and edges it owns (the
//               lowest-numbered triangle having them, Model::surfaceTopology) against the
//               other triangle, so every vertex-triangle (VT) and edge-edge (EE) pair is
//               listed once; a primitive pair sharing a particle is skipped, and so is one
//               whose chunk boxes are farther apart than the thickness.
//   flat        Normal-cone culling (Provot 1997; Volino and Magnenat-Thalmann 1994), on by
//   regions     default (SelfCollisionOptions::cullFlatRegions). A BVH node whose triangles
//               are edge-connected (fixed at construction) and whose normals, for every
//               position of the vertices inside their skin boxes, lie within less than 90
//               degrees of one axis is a height field over the plane normal to that axis: it
//               cannot touch itself, and its pairs are not gathered (the query does not even
//               visit them). The cone is conservative: a triangle's normal at its boxes'
//               centres, widened by the most the corners' moving anywhere in their boxes can
//               turn it (|n' - n| <= |d1| |e2| + |e1| |d2| + |d1| |d2| for edges e and
//               corner displacements d); a node's cone holds its children's. The skin is
//               then small (5 % of the shortest edge, at most half the thickness), so that
//               the cones stay narrow; with culling off it is half the thickness. What is
//               assumed and not tested is Provot's second condition, that the region's
//               boundary does not overlap itself in projection: a flat region wound into a
//               spiral ramp within one BVH node (a patch a few triangles across) would be
//               missed; the exact check (countSelfIntersections) is what proves a run.
//   detection   Conservative advancement on the distance d(s) between the moving
//               primitives. d is Lipschitz in s with the constant L = the largest relative
//               displacement of a vertex of one primitive against a vertex of the other
//               (the closest points are convex combinations of the corners), so from s the
//               distance stays above theta / 2 until s + (d(s) - theta / 2) / L. Stepping so,
//               and always evaluating s = 1, a query either finds an s with d(s) < theta or
//               proves d >= theta / 2 on all of [0, 1]: a pair that touches (d = 0) is never
//               missed, whatever the configuration (coplanar motion, parallel edges, a
//               vertex on an edge, contact at the start or at the end), because nothing is
//               solved for: there is no cubic whose roots could be lost. Steps are at least
//               theta / (2 L) long, so a query costs at most 2 L / theta + 2 distance
//               evaluations (capped at 64; a capped query reports a contact, which only
//               costs a response). tests/test_collide_self_collision.cpp checks this against
//               minimum distances found independently in long double.
//   response    Each contact (d < thickness at some s) gives a normal n (between the closest
//               points at s) and weights beta (VT: 1 on the vertex, -b_i on the triangle's
//               corners at barycentric b; EE: 1 - a, a on one edge, -(1 - b), -b on the
//               other). Sweeps over the contacts in a fixed order (Gauss-Seidel): the end
//               positions are pushed apart along n to the thickness (x1_i += w_i beta_i
//               lambda n, lambda = (thickness - sum beta_i x1_i . n) / sum w_i beta_i^2, w
//               the inverse masses) and an approaching relative normal velocity becomes zero
//               (inelastic); three more sweeps are sequential impulses, each contact's
//               accumulated push and impulse kept >= 0 (a contact takes back what a later
//               one sharing its vertices made excessive: no jitter of resting layers); a last
//               sweep applies Coulomb friction to the tangential relative velocity, bounded
//               by friction x (normal impulse + push / chunk length), applied to the end
//               positions too so a resting layer does not creep. A particle resting on an
//               obstacle (the obstacle pass's supports) that a contact would push into it
//               moves only in the obstacle's tangent plane: the other side takes the push.
//               Detection and response alternate up to `iterations` times; after a response
//               only the candidates with a vertex it moved (or that were in contact) are
//               advanced again.
//   early stop  Every detection also tests each contact against the failsafe's threshold
//               theta (below). When none comes below it, every pair is proven to stay at
//               least m apart over the chunk (m: the least of the contacts' theta / 2 and
//               of half the thinnest thickness, what a pair not in contact keeps); if the response then
//               moves no vertex by more than m / 4 (as stored), no distance falls by more
//               than m / 2 and nothing can intersect: the chunk ends there. Resting layers,
//               in contact in every pass and moved by a rounding error, take one pass.
//   failsafe    The last detection's contacts are also tested against a much smaller threshold
//               theta = min(thickness / 4, d(0) / 2) (d(0): the pair's distance at the chunk
//               start). A pair found below it has all its free vertices stopped: they stay
//               at x0 with zero velocity, the state they had at the start of the chunk.
//               Detection repeats until no pair is found; each round stops at least one
//               more vertex, and a pair whose vertices are all stopped cannot approach, so
//               it ends. Since the chunk started without intersections and no pair came
//               within theta / 2 > 0 of touching, the chunk ends without intersections. (This
//               is Provot's and Harmon et al.'s rigid impact zones taken to the zero-velocity
//               limit: simpler, exact, and it only acts when the impulses did not converge,
//               at the price of the stopped vertices' momentum; SelfCollisionStats::frozen
//               says how often.) A pair whose vertices are all pinned or kinematic cannot be
//               stopped and is counted as unresolved.
//   limit       A gathering lists at most maxCandidatesPerTriangle x triangles pairs (and
//               meets at most as many overlapping pairs of BVH nodes). A cloth keeps about
//               3 to 30 per triangle however it folds (tests and benchmarks: fold 6,
//               two-cloths 9, twist wrung tight 33, the folded 128² cloth unculled 55).
//               Far more comes from a chunk whose swept boxes are long: a cloth moving many
//               times its spacing in one chunk (the count grows with the square of the
//               motion), or one pushed out across the scene at once (started deep inside an
//               obstacle), where the pass would cost the square of the triangles. The query
//               stops as soon as its count passes the limit; the Simulation rolls the chunk
//               back and retries it halved, as for a deep penetration (a fast cloth's
//               candidates fall with the square of the chunk), and at
//               CollisionOptions::maxHalvings fails the step with
//               StepCode::TooManyCandidates, the state as it was.
//
// Work: gathering and detection run in parallel over fixed blocks of triangle pairs, each
// block writing its own lists; the lists are concatenated in block order and the response runs serially
// over them, so the result is bitwise the same for any thread count. Buffers are kept, so
// once warmed up a step allocates nothing. Distances are computed in double for either
// precision. The exact check (countSelfIntersections) is separate: the exact triangle-triangle
// test of geometry.hpp on every pair of triangles sharing no particle, through the BVH.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "weft/core/archive.hpp"
#include "weft/core/parallel.hpp"
#include "weft/core/types.hpp"
#include "weft/model/model.hpp"

namespace weft {

struct SelfCollisionOptions {
  bool enabled = false;                   // off: the step has no self-collision pass at all
  double thickness = 0.004;               // m (> 0): the distance kept between layers of cloth; keep it below
                                          // about half the cloth's shortest edge, or neighbours count as layers
  double friction = 0.3;                  // Coulomb coefficient of cloth on cloth (>= 0)
  int iterations = 3;                     // detection + response passes per chunk (1 .. 64) before the failsafe
  std::vector<double> particleThickness;  // empty: every particle has `thickness`; else one per particle (m,
                                          // > 0), a cloth's own: a pair of primitives keeps the mean of theirs
  bool cullFlatRegions = true;            // normal-cone culling of flat, connected regions (see the design note); off:
                                          // every pair of triangles whose boxes overlap is a candidate
  int maxCandidatesPerTriangle = 256;     // (1 .. 2^20) a gathering listing more candidate pairs than this x the
                                          // triangles fails the step (StepCode::TooManyCandidates; the design note)
};

/// Throws std::invalid_argument naming the field (prefixed by `where`) and the value.
void validateSelfCollision(const SelfCollisionOptions& options, const char* where = "self_collision");
/// The same, and the thickness against the model's triangles in positions x: it must be
/// below their smallest altitude (2 x area / longest edge). A vertex is never farther than
/// that from the triangle across its opposite longest edge, a triangle it is not part of, so
/// a thicker layer would put neighbouring triangles in contact with each other at rest (and
/// make every neighbour a contact: the pass's work would grow with the square of the
/// triangles within the thickness). Throws std::invalid_argument naming the triangle.
/// With particleThickness, a triangle's thickness is the largest of its corners', and
/// `thicknessField(particle)`, when given, names the field a particle's thickness came from
/// (a scene file's body) in the message.
template <class S>
void validateSelfCollision(const SelfCollisionOptions& options, const Model<S>& model, const Vec3Array<S>& x,
                           const char* where,
                           const std::function<std::string(Index particle)>& thicknessField = nullptr);

/// Self-collision work and findings, per step and summed.
struct SelfCollisionStats {
  std::int64_t passes = 0;          // detections run (response passes and failsafe rounds)
  std::int64_t rebuilds = 0;        // of which gathered new candidates (a vertex left its skin box)
  std::int64_t candidates = 0;      // triangle pairs whose boxes overlap, summed over the gatherings
  std::int64_t tests = 0;           // VT and EE pairs whose swept boxes overlap, tested by advancement
  std::int64_t contacts = 0;        // of which closer than the thickness at some time: responded to
  std::int64_t vertexTriangle = 0;  // contacts that were VT pairs (the rest EE)
  std::int64_t failsafeChunks = 0;  // chunks in which the failsafe stopped vertices
  std::int64_t frozen = 0;          // vertices it stopped
  std::int64_t unresolved = 0;      // pairs it could not stop (every vertex pinned or kinematic)
  SelfCollisionStats& operator+=(const SelfCollisionStats& o);
};

/// Pairs of the model's triangles sharing no particle that intersect at x: the exact test of
/// geometry.hpp through a BVH built for the call (for reports and tests, not for the step).
template <class S>
std::int64_t countSelfIntersections(const Model<S>& model, const Vec3Array<S>& x, const Executor& exec);
extern template std::int64_t countSelfIntersections(const Model<float>&, const Vec3Array<float>&, const Executor&);
extern template std::int64_t countSelfIntersections(const Model<double>&, const Vec3Array<double>&, const Executor&);

/// The self-collision pass itself (SelfCollider) and its continuous primitive queries are
/// internal to weft: kernel/src/collide/self_collider.hpp. A Simulation reports what it does
/// (Simulation::lastSelfCollision, totalSelfCollision, selfIntersectionCount).
template <class S>
class SelfCollider;

}  // namespace weft
