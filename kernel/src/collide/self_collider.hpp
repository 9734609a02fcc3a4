// collide/self_collision.hpp's pass (internal): SelfCollider, built on the continuous
// vertex-triangle and edge-edge queries of collide/primitive_contact.hpp. The design note is in the public
// weft/collide/self_collision.hpp. Not installed: a Simulation owns its SelfCollider.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "collide/bvh.hpp"
#include "collide/geometry.hpp"
#include "collide/primitive_contact.hpp"
#include "weft/collide/self_collision.hpp"
#include "weft/core/archive.hpp"
#include "weft/core/parallel.hpp"
#include "weft/core/types.hpp"
#include "weft/model/model.hpp"

namespace weft {

/// The self-collision pass of one Model (see the design note). Sized at construction.
template <class S>
class SelfCollider {
 public:
  /// The model's triangles (none: the pass does nothing); its BVH is built over x.
  SelfCollider(const Model<S>& model, const SelfCollisionOptions& options, const Vec3Array<S>& x, const Executor& exec);

  /// Resolves the chunk x0 -> x1 (length h, s) in place: x1 and v1 change.
  /// `supports` (particles x 3, ContactSolver::supports), when given: the unit normal of
  /// the obstacle each particle rests on in this chunk, or zero. A contact's response does
  /// not push such a particle into its obstacle; the other side of the contact takes that
  /// share (a cloth lying on the floor is as immovable downwards as the floor).
  /// When a gathering meets more candidates than the options' maxCandidatesPerTriangle
  /// allows, it stops there: the chunk is left unresolved (x1 and v1 partly responded to),
  /// overflowed() is true until the next resolve, and the pushes kept for the next skin
  /// boxes are the last resolved chunk's (the caller retries a shorter chunk or fails the
  /// step).
  SelfCollisionStats resolve(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1, const ScalarArray<S>& w,
                             double h, const Executor& exec, const double* supports = nullptr);
  /// Whether the last resolve stopped at the candidate limit.
  bool overflowed() const { return overflowed_; }

  const SelfCollisionOptions& options() const { return options_; }
  /// The skin, m (see the design note): the least a vertex's skin box extends beyond its
  /// chunk; a vertex the response moved in the last chunk gets more (kPush).
  double skin() const { return skin_; }
  /// Triangle pairs in the current candidate list.
  Index candidateCount() const { return static_cast<Index>(pairs_.size()); }
  /// Bytes held by the buffers that grow with the candidates and contacts: the candidate,
  /// primitive and contact lists, the BVH pair query's scratch (capacities: they keep the
  /// largest size so far, so a step allocates only when it lists more) and the response's
  /// current contacts.
  std::size_t listBytes() const;

  /// Checkpoints: the candidate list, the skin boxes it was gathered for and the last
  /// chunk's pushes (a list gathered at another time would cull other pairs, so a resumed run keeps
  /// this one, and gathers when the uninterrupted run would).
  void saveCarry(ArchiveWriter& out) const;
  void loadCarry(ArchiveReader& in);

  static constexpr Index kGrain = 256;  // triangle pairs per detection block

 private:
  struct Contact {
    Index vertex[4];  // VT: the vertex, then the triangle's corners; EE: one edge, then the other
    bool vertexTriangle;
    bool guard;        // also below the failsafe's threshold
    double thickness;  // m, kept between the two
    double weights[4];
    double normal[3];
  };
  /// What the expansion reads of a triangle, on one cache line: its corners, the vertices
  /// it owns and the ends of the edges it owns (SurfaceTopology), in the topology's order.
  struct alignas(64) Owned {
    Index corner[3];
    Index vertex[3];
    Index edge[3][2];
    std::uint8_t vertices = 0, edges = 0;
  };
  /// A candidate pair's primitive pairs, as bits of a PrimitiveMask: bit k < 3, the first
  /// triangle's owned vertex k against the second triangle; 3 + k, the second's owned vertex k
  /// against the first; 6 + 3 ka + kb, the first's owned edge ka against the second's owned
  /// edge kb. Ascending bits are the order the pass tests them in.
  using PrimitiveMask = std::uint16_t;
  static_assert(6 + 3 * 3 <= 8 * sizeof(PrimitiveMask), "a mask holds 6 VT and 9 EE pairs");
  /// The four vertices of primitive pair `bit` of triangles (first, second), as the queries
  /// take them (VT: the vertex, then the triangle's corners; EE: one edge, then the other);
  /// true for a vertex-triangle pair.
  static bool primitiveVertices(const Owned& first, const Owned& second, int bit, Index (&v)[4]) {
    if (bit < 6) {
      const Owned& owner = bit < 3 ? first : second;
      const Owned& other = bit < 3 ? second : first;
      v[0] = owner.vertex[bit % 3];
      v[1] = other.corner[0];
      v[2] = other.corner[1];
      v[3] = other.corner[2];
      return true;
    }
    const Index(&e)[2] = first.edge[(bit - 6) / 3];
    const Index(&f)[2] = second.edge[(bit - 6) % 3];
    v[0] = e[0];
    v[1] = e[1];
    v[2] = f[0];
    v[3] = f[1];
    return false;
  }
  /// One block of kGrain candidate pairs: what the last pass found in them.
  struct Block {
    std::vector<Contact> contacts;
    std::int64_t tests = 0;
    std::int64_t guards = 0;  // contacts below their failsafe threshold
    double margin = 0;        // m: the least distance the contacts are proven to keep (theta / 2)
  };
  /// A cone of directions: unit axis and the cosine and sine of its half-angle (cos <= 0:
  /// half a sphere or more, no use for culling).
  struct Cone {
    double axis[3];
    double cos, sin;
  };
  /// Whether every vertex's x0 and x1 lie in its skin box, or do once the same offset (the
  /// centroid's motion since the gathering) is taken from all of them: then the candidates
  /// cover the chunk (distances, and so the pairs listed and the flat regions culled, do
  /// not change when every vertex moves by the same vector).
  bool candidatesCover(const Vec3Array<S>& x0, const Vec3Array<S>& x1, const Executor& exec);
  /// The mean of x's rows, summed in a fixed order.
  std::array<double, 3> centroid(const Vec3Array<S>& x, const Executor& exec);
  /// New skin boxes around the chunk x0 -> x1, the BVH pairs and the candidates (their
  /// primitive pairs are then found by detect, expandBlock); false (and no candidates) past
  /// the limit.
  bool gatherCandidates(const Vec3Array<S>& x0, const Vec3Array<S>& x1, const Executor& exec,
                        SelfCollisionStats& stats);
  /// Advancement on every candidate for the chunk x0 -> x1 into blocks_, with the failsafe's
  /// flags; false when a gathering passed the limit.
  bool detect(const Vec3Array<S>& x0, const Vec3Array<S>& x1, const ScalarArray<S>& w, const Executor& exec,
              SelfCollisionStats& stats);
  /// Sizes the blocks and flags for the candidate list in pairs_.
  void useCandidates();
  /// Finds the primitive pairs of one block's triangle pairs (at a gathering).
  void expandBlock(Index blockIndex);
  /// The triangle pairs of each block's range that may hold a contact in this chunk
  /// (thickness filter, owned primitives, advancement) into the block's contacts.
  void detectBlock(Index blockIndex, const Vec3Array<S>& x0, const Vec3Array<S>& x1, const ScalarArray<S>& w, bool all);
  /// Which internal nodes of the BVH are edge-connected (once, at construction).
  void findConnectedNodes();
  /// The normal cones of every BVH node for vertices anywhere in their skin boxes, and the
  /// flat regions (flat_) among the connected nodes.
  void findFlatRegions(const Executor& exec);
  /// resolve's passes and failsafe; false when a gathering passed the limit.
  bool resolvePasses(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1, const ScalarArray<S>& w, double h,
                     const Executor& exec, const double* supports, SelfCollisionStats& stats);
  /// Gauss-Seidel over the contacts found, in block order; returns the largest
  /// displacement of a vertex (m, as stored). `supports` as resolve's.
  double respond(Vec3Array<S>& x1, Vec3Array<S>& v1, const ScalarArray<S>& w, double h, const double* supports,
                 SelfCollisionStats& stats);

  static constexpr Index kVertexGrain = 4096;
  /// Slots a block of the leaf cones' pass computes at a time (findFlatRegions).
  static constexpr Index kConeBlock = 128;
  /// Sweeps of the response over a pass's contacts for the pushes and normal impulses
  /// (sequential impulses, each contact's accumulated push and impulse >= 0); friction
  /// follows in one more sweep.
  static constexpr int kImpulseSweeps = 4;
  /// A contact whose blocked vertices would leave it less than this share of its inverse
  /// mass along n (sum w beta^2) ignores the supports (see respond).
  static constexpr double kSupportedMass = 0.1;
  /// The skin, in thicknesses: candidates are gathered for boxes this much larger than the
  /// chunk's, and kept while every vertex stays inside its box.
  static constexpr double kSkin = 0.5;
  /// With flat regions culled, the skin is at most this share of the shortest triangle edge
  /// (a corner moving 5 % of an edge turns a triangle's normal by at most ~25 degrees).
  static constexpr double kConeSkin = 0.05;
  /// A vertex the response (or the failsafe) moved by p (per axis, signed) in the last chunk gets a skin box
  /// kPush |p| longer on that side of that axis, at most its thickness longer: a resting
  /// fold's vertices are pushed about as far every chunk, and a box that covers the push
  /// keeps the candidates gathered at the chunk's start valid for its later passes.
  static constexpr double kPush = 1.5;

  const Model<S>* model_;
  SelfCollisionOptions options_;
  TriangleBvh<S> bvh_;
  BvhPairScratch scratch_;
  std::vector<TrianglePair> pairs_;    // the candidates: triangle pairs, sorted
  std::vector<std::uint8_t> pairHit_;  // (pairs) a primitive of the pair was in contact in the last pass
  // (pairs) the primitive pairs of each candidate that its skin boxes let come within the
  // thickness (found at the gathering: expandBlock)
  std::vector<PrimitiveMask> primitiveMask_;
  std::vector<Block> blocks_;
  Index blocksUsed_ = 0;
  std::vector<std::uint8_t> frozen_;  // (n) stopped by the failsafe in this chunk
  std::vector<double> displacement_;  // (n) m, moved by the current response pass
  /// respond's view of one contact: each vertex's share of a relative change, the obstacle
  /// it rests on where that blocks it, and what the contact has given so far.
  struct Share {
    const Contact* contact;
    double share[4];          // of the push and the normal impulse: w beta / sw
    double frictionShare[4];  // w beta / sum w beta^2, as without supports
    const double* rests[4];   // the normal of the obstacle the vertex rests on (supports), or null
    bool blocked[4];          // it would be pushed into that obstacle: tangent plane only
    double push;              // m, accumulated along the normal (>= 0)
    double impulse;           // m/s, accumulated normal velocity change (>= 0)
  };
  std::vector<Share> shares_;              // the current response pass's contacts
  std::vector<double> push_;               // (3n, vertex-major) m, the last chunk's response moved x1 by this
  Vec3Array<S> unpushed_;                  // (n x 3) a touched vertex's x1 before this chunk's response
  std::vector<std::uint8_t> touchedFlag_;  // (n) moved by this chunk's response or failsafe
  std::vector<Index> touched_;             // those vertices, in the order first moved
  std::vector<Index> lastTouched_;         // the last chunk's: their push_ is not zero
  /// Records j's x1 before this chunk first moves it.
  void touch(Index j, const Vec3Array<S>& x1) {
    if (touchedFlag_[static_cast<size_t>(j)]) return;
    touchedFlag_[static_cast<size_t>(j)] = 1;
    touched_.push_back(j);
    for (int a = 0; a < 3; ++a) unpushed_(j, a) = x1(j, a);
  }
  std::vector<double> thickness_;          // (n) m, each particle's cloth's thickness
  std::vector<double> triangleThickness_;  // (triangles) m, the largest of its corners' thickness
  std::vector<Owned> owned_;               // (triangles) for the expansion
  double thinnest_ = 0;                    // m, the least thickness of a particle
  double skin_ = 0;                        // m
  std::vector<Aabb<S>> skinBox_;           // (n) each vertex's skin box
  std::vector<Aabb<S>> triangleBox_;       // (triangles) each triangle's box over the chunk
  std::vector<std::uint8_t> connected_;    // (nodes) the node's triangles are edge-connected
  std::vector<std::uint8_t> flat_;         // (nodes) a flat region at the last gathering: not queried
  std::vector<Cone> cones_;                // (nodes) scratch of findFlatRegions
  std::vector<Cone> leafCones_;            // (triangles, by slot) likewise
  std::vector<Aabb<S>> sweptBox_;          // (n) each vertex's box over the chunk (one per vertex: read by index)
  bool candidatesValid_ = false;
  bool overflowed_ = false;
  bool onlyMoved_ = false;           // this pass tests only candidates with a moved vertex (or a hit)
  std::vector<std::uint8_t> moved_;  // (n) moved by the last response or failsafe round
  std::vector<std::uint8_t> blockFlags_;
  std::vector<std::array<double, 3>> blockSums_;     // (vertex blocks) scratch of centroid
  std::array<double, 3> gatheredCentroid_{0, 0, 0};  // m, x1's centroid at the last gathering
};

/// Whether the boxes of a primitive pair's two sides are farther apart than `beyond` (m) on
/// some axis: v holds its four vertices (VT: the vertex, then the triangle's corners, split
/// 1; EE: one edge, then the other, split 2) and box[i] is vertex i's box. The bounds are
/// exact in S, the gap is taken in double. Expansion asks it of the skin boxes, each pass of
/// the chunk's boxes. (Forced inline: it runs once per primitive pair in both loops, and as
/// a call GCC 12 made of it, a gathering chunk of the folded 128^2 cloth took 5-8 % longer.)
template <class S>
[[gnu::always_inline]] inline bool primitiveBoxesApart(const Aabb<S>* box, const Index* v, int split, double beyond) {
  for (int a = 0; a < 3; ++a) {
    S lo1 = box[v[0]].lo[a], hi1 = box[v[0]].hi[a], lo2 = box[v[3]].lo[a], hi2 = box[v[3]].hi[a];
    for (int i = 1; i < 3; ++i) {
      if (i < split) {
        lo1 = std::min(lo1, box[v[i]].lo[a]);
        hi1 = std::max(hi1, box[v[i]].hi[a]);
      } else {
        lo2 = std::min(lo2, box[v[i]].lo[a]);
        hi2 = std::max(hi2, box[v[i]].hi[a]);
      }
    }
    if (static_cast<double>(lo1) - static_cast<double>(hi2) > beyond ||
        static_cast<double>(lo2) - static_cast<double>(hi1) > beyond)
      return true;
  }
  return false;
}

/// The factor on a thickness by which boxes must be apart to count as apart: (lo - hi) in S
/// may round, so a relative 1e-6 is kept in hand.
inline constexpr double kBoxesApart = 1 + 1e-6;

extern template class SelfCollider<float>;
extern template class SelfCollider<double>;

}  // namespace weft
