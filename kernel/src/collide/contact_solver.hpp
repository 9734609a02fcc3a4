// collide/contact_solver.hpp (internal) — the contact pass between particles and the
// obstacles of weft/collide/obstacles.hpp: detection, response and the penetration measure
// that drives rollback (the design note is in that public header). Not installed: a
// Simulation owns its ContactSolver and reports what it finds.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "collide/bvh.hpp"
#include "weft/collide/obstacles.hpp"
#include "weft/core/parallel.hpp"
#include "weft/core/types.hpp"
#include "weft/model/topology.hpp"

namespace weft {

/// A mesh obstacle as the contact pass reads it (CollisionModel): a BVH over its vertices
/// at time 0.
struct MeshCollider {
  TriangleBvh<double> bvh;
  Vec3Array<double> x;  // (v x 3) vertices at time 0, m
  Triangles triangles;
  bool closed = false;  // no boundary edge: inside is defined (winding number)
  /// Per triangle, bit k set: its edge k (corners k, k + 1) is a feature edge that this
  /// triangle tests (each edge by one triangle). Empty when the mesh has none.
  std::vector<std::uint8_t> featureEdges;
  /// Per triangle, bit k set: its corner k is a corner of the mesh (an end of a feature
  /// edge) that this triangle tests against cloth triangles (each corner by one triangle).
  /// Empty when the mesh has none.
  std::vector<std::uint8_t> corners;
};

/// The response pass over one candidate state. Sized at construction (the BVHs of the mesh
/// obstacles are built there); detection and response allocate nothing.
///
/// Times t0, t1 (s, on the simulation's clock counted from its initial state) are the
/// start and end of the chunk: moving mesh obstacles are where their paths put them then.
// (Edge, a cloth or rope edge given by the particles at its ends: weft/model/topology.hpp.)

template <class S>
class ContactSolver {
 public:
  /// `edges` (particle pairs: the cloth's triangle edges, a rope's links) are tested
  /// against the edges of mesh obstacles when CollisionOptions::continuous and ::edges are
  /// on; none: vertices only.
  /// `model`: the mesh obstacles prepared once (weft/collide/collision_model.hpp), built
  /// from these options' meshes; none: the solver prepares its own.
  /// `triangles` (the cloth's) are tested against the corners of mesh obstacles when
  /// CollisionOptions::continuous and ::corners are on and a mesh has corners; none: no
  /// corner pass.
  ContactSolver(const CollisionOptions& options, Index particleCount, std::vector<Edge> edges = {},
                std::shared_ptr<const CollisionModel> model = nullptr, Triangles triangles = {});

  /// Deepest penetration (thickness - distance, >= 0) of the candidate positions x1 at
  /// time t1 over free particles (inverse mass w > 0): what rollback compares with
  /// maxPenetration.
  double deepestPenetration(const Vec3Array<S>& x1, const ScalarArray<S>& w, double t1, const Executor& exec);
  /// Resolves every contact of the candidate (x1, v1) of the chunk x0 -> x1 in place;
  /// returns what it found.
  CollisionStats resolve(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1, const ScalarArray<S>& w, double t0,
                         double t1, const Executor& exec);

  const CollisionOptions& options() const { return options_; }
  /// From now on, resolve records each particle's support: the unit normal (out of the
  /// obstacle) of the contact it resolved for that particle in its last call; for a particle
  /// it did not need to resolve, the normal of the nearest obstacle within the thickness x
  /// (1 + kSupportReach) of its end position (a resting particle sits at the thickness and
  /// needs a response only in some chunks); zero otherwise. Self-collision reads it so that
  /// it does not push a particle resting on an obstacle into that obstacle
  /// (SelfCollider::resolve). Off by default: a scene without self-collision does not pay for it.
  void recordSupports();
  /// (particles x 3) the supports of the last resolve; null unless recordSupports was called.
  const double* supports() const { return support_.empty() ? nullptr : support_.data(); }
  /// The prepared mesh obstacles this solver reads (shared when it was given one).
  const std::shared_ptr<const CollisionModel>& collisionModel() const { return model_; }
  /// Free particles in contact (distance < thickness + epsilon) in state x at time t (serial).
  std::int64_t countContacts(const Vec3Array<S>& x, const ScalarArray<S>& w, double t) const;
  /// Deepest penetration (thickness - distance, >= 0) in state x at time t (serial).
  double penetration(const Vec3Array<S>& x, const ScalarArray<S>& w, double t) const;
  /// Free particles that tunnelled between `start` (time t0) and `end` (time t1): ended
  /// inside an analytic obstacle or a closed mesh they started outside of (one that started
  /// inside is the start's problem, not a tunnelling), crossed a box along its thinnest axis,
  /// or whose straight path from start to end crosses an open mesh (a wall). Serial; for
  /// reports at the end of a run.
  std::int64_t countTunnelled(const Vec3Array<S>& start, const Vec3Array<S>& end, const ScalarArray<S>& w, double t0,
                              double t1) const;

  /// Particles (and edges) per parallel block: a contact test costs hundreds of
  /// nanoseconds, so even a 32^2 cloth is split among the threads.
  static constexpr Index kGrain = 128;
  /// How far beyond the thickness a particle still rests on an obstacle (supports), in
  /// thicknesses.
  static constexpr double kSupportReach = 0.25;

 private:
  std::int64_t resolveEdges(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1, const ScalarArray<S>& w,
                            double t0, double t1, const Executor& exec);
  std::int64_t resolveCorners(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1, const ScalarArray<S>& w,
                              double t0, double t1, const Executor& exec);

  CollisionOptions options_;
  Index particleCount_ = 0;
  std::shared_ptr<const CollisionModel> model_;
  std::vector<double> blockDepth_;  // per block of kGrain particles
  std::vector<std::int64_t> blockHits_, blockCcd_;
  std::vector<double> support_;  // (particles x 3) see supports(); empty: not recorded
  /// What the edge pass found for one edge, in the frame of mesh `mesh` (-1: nothing).
  struct EdgeHit {
    int mesh = -1;
    double alpha = 0;              // the contact point's parameter along the edge, 0 .. 1
    double point[3] = {0, 0, 0};   // the closest point on the mesh edge
    double normal[3] = {0, 0, 0};  // unit, from the mesh edge towards the cloth edge
  };
  /// Per mesh and particle: a point r (in the mesh's frame) and a clearance c with
  /// distance(r, mesh) >= c, so that distance(p, mesh) >= c - |p - r| for any p: a
  /// particle whose whole chunk stays farther than the thickness by this bound skips the
  /// mesh. A pure optimisation: the results are the same bits as without it.
  std::vector<double> clearance_;  // (meshes x particles x 4): r, c
  std::vector<Edge> edges_;
  std::vector<EdgeHit> edgeHits_;  // (edges)
  /// What the corner pass found for one cloth triangle, in the frame of mesh `mesh` (-1:
  /// nothing).
  struct CornerHit {
    int mesh = -1;
    double beta[3] = {0, 0, 0};    // the contact point on the triangle, barycentric
    double point[3] = {0, 0, 0};   // the mesh corner
    double normal[3] = {0, 0, 0};  // unit, from the corner towards the triangle
  };
  Triangles triangles_;                // the cloth's, when the corner pass runs
  std::vector<CornerHit> cornerHits_;  // (triangles)
};

extern template class ContactSolver<float>;
extern template class ContactSolver<double>;

}  // namespace weft
