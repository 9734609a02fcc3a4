// weft/rigid/narrow_phase.hpp — contact manifolds between convex shapes, three ways.
//
// Design note
// -----------
// Every method answers the same question through one interface: given two convex hulls
// in world poses and a speculative margin, return up to four contact points (a manifold,
// as Box2D and Jolt build them) with one normal from A towards B and each point's
// separation along it (negative: penetration), for pairs closer than the margin.
//
//   Exact    Separating-axis test with face and edge-pair queries (Gregorius, GDC 2013,
//            "The separating axis test between convex polyhedra"): the face axes of A and
//            of B, and the cross products of edge pairs that build a face of the
//            Minkowski difference (Gauss-map arc test). The axis of largest separation
//            wins; a face axis gives a reference face whose incident face (the face of
//            the other hull most anti-parallel to it) is clipped against the reference
//            face's side planes (Sutherland-Hodgman), keeping points below the margin and
//            reducing to four (deepest, then the farthest, then the largest area); an edge
//            axis gives one point midway between the closest points of the two edges.
//            The ground truth.
//   Ofg      Opposing Face Geometry, the original design's 8 steps: bounding-sphere
//            preselection; the k faces of A closest to B's centre; their centre and
//            bounding sphere; the k faces of B closest to that centre; their centre and
//            sphere; sphere preselection of the two face sets; sort both sets by
//            distance; test face pairs closest first, the first pair within the margin
//            gives the reference and incident faces clipped as above. A heuristic: it
//            tests no edge-pair axes and only k faces a side, so it can miss contacts
//            (docs/narrow-phase.md measures how often).
//   Witness  The lecture notes' separating-plane witness: the axis (face of A, face of B
//            or edge pair) that decided the pair last time is kept in a PairCache and
//            checked first. If it still separates the pair by more than the margin the
//            answer is "no contact" after one support query per side. If the pair was
//            touching, the cache also holds the gap between the best and second-best axis
//            of the last full query and the relative pose then; while the relative motion
//            since (translation plus rotation times the bounding radii) is below half that
//            gap, no other axis can have overtaken the cached one, so its manifold is built
//            directly. Otherwise the exact query runs and refills the cache. Same answer as
//            Exact (up to ties between equally good axes), usually much faster.
//
// Functions here never allocate and never throw; they are called from parallel loops, one
// pair per call, each writing only its own ContactManifold and PairCache.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>

#include "weft/rigid/convex_hull.hpp"

namespace weft {

/// A shape's placement: world = rotation * shape + position.
struct Pose {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // m
};

struct ContactPoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world, midway between the two surfaces, m
  double separation = 0;                               // along the normal, m (< 0: penetration)
  std::uint32_t featureId = 0;  // the same while the same features touch (warm starting keys on it)
};

struct ContactManifold {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();  // world unit normal, from A towards B
  int pointCount = 0;                                 // 0: no contact within the margin
  std::array<ContactPoint, 4> points;
};

enum class NarrowPhaseMethod { Exact, Ofg, Witness };
const char* narrowPhaseMethodName(NarrowPhaseMethod method);

/// The most faces a side the Opposing Face Geometry keeps (its arrays are fixed in size).
inline constexpr int kMaxOfgFaces = 64;

struct NarrowPhaseOptions {
  NarrowPhaseMethod method = NarrowPhaseMethod::Witness;
  int ofgFaces = 6;  // k of the Opposing Face Geometry (faces kept on each side), 1..kMaxOfgFaces
};

/// What the last query of a pair found, kept by the caller between steps (one per pair).
struct PairCache {
  enum class Axis : std::uint8_t { None, FaceA, FaceB, EdgePair };
  Axis axis = Axis::None;
  int indexA = -1;        // face of A, or edge of A for EdgePair
  int indexB = -1;        // face of B, or edge of B for EdgePair
  bool touching = false;  // the last full query found separation <= margin
  double axisGap = 0;     // touching: separation of the best axis minus that of the runner-up, m
  Eigen::Matrix3d relativeRotation = Eigen::Matrix3d::Identity();  // B in A's frame at the last full query
  Eigen::Vector3d relativePosition = Eigen::Vector3d::Zero();
};

/// What one query did (for statistics: the witness hit rate).
enum class NarrowPhaseOutcome : std::uint8_t {
  FullQuery,         // the exact (or OFG) search ran
  WitnessSeparated,  // the cached axis still separates: no contact, nothing else tested
  WitnessTouching,   // the cached touching axis is still the best: manifold built directly
};

/// Contact manifold of two convex hulls (normal from A to B) for pairs whose separation
/// is below `margin` (m, >= 0); out.pointCount = 0 otherwise. `options.ofgFaces` is taken
/// into [1, kMaxOfgFaces] here; RigidWorld refuses values outside it.
NarrowPhaseOutcome collideHulls(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB,
                                double margin, const NarrowPhaseOptions& options, PairCache& cache,
                                ContactManifold& out);

/// Sphere of `radius` at `centre` (world) against a hull (normal from the sphere to the
/// hull): one point, on the closest point of the hull to the centre (inside: the face of
/// least penetration).
void collideSphereHull(const Eigen::Vector3d& centre, double radius, const ConvexHull& b, const Pose& poseB,
                       double margin, ContactManifold& out);

/// The largest separation of the two hulls along any face or edge-pair axis (the exact
/// method's answer, m; negative: penetration depth). For tests and the study.
double hullSeparation(const ConvexHull& a, const Pose& poseA, const ConvexHull& b, const Pose& poseB);

}  // namespace weft
