// weft/rigid/rigid_world.hpp — rigid bodies beside the particle model: what they are made
// of (RigidModel, built once), where they are (RigidState) and the step that moves them and
// makes them collide (RigidWorld).
//
// Design note
// -----------
// A body is one or more convex pieces (sphere, box, or the convex hull of points; several
// pieces make a compound, how a concave body is described). Its mass, centre of mass and
// inertia tensor come from the pieces' exact volume integrals (rigid/mass_properties.hpp)
// at the body's density; internally a body is tracked by its centre of mass. Static bodies
// never move; kinematic bodies follow a KinematicPath (their velocity is the chord of the
// path over the step, so they end each step exactly on it) and push dynamic bodies without
// being pushed; dynamic bodies obey gravity and contacts.
//
// One step of length h (RigidWorld::step), Catto's sequential impulses substepped as Box2D
// v3 runs them (docs/rigid-bodies.md has the measurements behind each choice):
//   1. kinematic bodies take their path's chord; gravity (for the swept bounds only).
//   2. broad phase: each piece's world box, swept over the step (the box at the start
//      united with the box moved by v h, grown by the rotation |w| h r and the speculative
//      distance: the extruded silhouette of the original design), sort-and-sweep along x
//      in (min x, index) order, pairs of pieces of different bodies, one at least dynamic.
//   3. narrow phase (parallel over pairs, each writing its own slot): a manifold of up to 4
//      points (rigid/narrow_phase.hpp: exact, OFG or witness) with a speculative margin of
//      speculativeDistance plus the pair's relative motion bound over the step, so a fast
//      body meets what lies in its path within the step (no tunnelling, no rollback).
//   4. constraints in pair order, lever arms and I^-1 (r x d) precomputed, per manifold the
//      inverse of its points' normal coupling; impulses of the last step's point with the
//      same pair and feature id (else the nearest within 1 cm) kept for warm starting.
//   5. `substeps` substeps of h / substeps: gravity; warm start (not an impact's impulse);
//      velocityIterations passes of friction (Coulomb cone; static coefficient below
//      staticSpeed; Jacobi within a manifold) and the manifold's normal impulses as a block
//      (a speculative point may close its gap within the substep, no more); split impulses
//      for penetration deeper than linearSlop (they move positions only); positions
//      (rotation with the world angular momentum held fixed, RK4 on the quaternion, so a
//      free body keeps L exactly and shows the tennis-racket flip); separations advanced.
//   6. restitution for points that closed faster than restitutionThreshold.
// The solver is serial and the parallel passes write disjoint slots, so the result is
// bitwise the same for any thread count. Every buffer is sized at construction; step()
// never allocates and never throws: a full pair buffer or a non-finite body is reported in
// the returned status (the state restored to the start of the step).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "weft/core/archive.hpp"
#include "weft/core/kinematic_path.hpp"
#include "weft/core/parallel.hpp"
#include "weft/integrate/stability.hpp"
#include "weft/rigid/convex_hull.hpp"
#include "weft/rigid/mass_properties.hpp"
#include "weft/rigid/narrow_phase.hpp"

namespace weft {

enum class BodyMotion { Static, Kinematic, Dynamic };
const char* bodyMotionName(BodyMotion motion);

/// One convex piece of a body, placed in the body's frame.
struct RigidShapeDesc {
  enum class Kind { Sphere, Box, Hull };
  Kind kind = Kind::Box;
  double radius = 0.5;                                           // Sphere, m
  Eigen::Vector3d halfExtents{0.5, 0.5, 0.5};                    // Box, m
  std::vector<Eigen::Vector3d> points;                           // Hull: its convex hull is the piece, m
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();              // piece origin in the body frame, m
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // piece axes in the body frame
};

struct RigidBodyDesc {
  std::string name;
  BodyMotion motion = BodyMotion::Dynamic;
  std::vector<RigidShapeDesc> shapes;  // >= 1 piece
  double density = 1000;               // kg/m^3 (> 0)
  double mass = 0;  // > 0: the body's mass (inertia scaled to match); 0: from density; in [1e-15, 1e15] kg either way
                    // when dynamic; 0 for static and kinematic bodies (refused otherwise)
  Eigen::Vector3d position = Eigen::Vector3d::Zero();               // body frame origin, world, m (|each| <= 1e150)
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // body frame axes, world
  // Dynamic bodies only (zero for static ones and for kinematic ones, which move by `path`):
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();         // of the centre of mass, m/s (at most kMaxSpeed)
  Eigen::Vector3d angularVelocity = Eigen::Vector3d::Zero();  // world, rad/s (no point faster than kMaxSpeed)
  double staticFriction = 0.6;   // >= 0; a pair uses the geometric mean of its bodies' coefficients
  double kineticFriction = 0.5;  // in [0, staticFriction]
  double restitution = 0;        // in [0, 1]; a pair uses the larger
  KinematicPath path;            // Kinematic: how it moves (its rotation about path.center)
};

/// How bodies that approach fast meet without passing through each other.
/// Speculative: contacts are made before the bodies touch (within the speculative distance
/// and, with `continuous`, the pair's motion over the step) and the solver lets each gap
/// close and no more: one solve a step, whatever the speed (a step that still ends with two
/// bodies let deep into each other is taken again in halves: RigidOptions::redoDeepSteps).
/// Rollback: the original design's loop
/// for bodies, as the particles do it: only touching contacts are solved; a step is
/// advanced in chunks, a chunk is cut (halved) before it is taken while a pair that is
/// apart could approach deeper than `rollbackPenetration` within it (the time of impact,
/// bisected), and taken back and halved when a contact ends deeper than that.
enum class RigidTimeOfImpact { Speculative, Rollback };
const char* rigidTimeOfImpactName(RigidTimeOfImpact mode);

/// A dynamic body's mass, given or from its density and volume, must be within these (kg).
inline constexpr double kMinBodyMass = 1e-15, kMaxBodyMass = 1e15;
/// A body's position (each coordinate, m) must be within +-this: the squares of distances
/// between bodies stay finite (as for particles in double). Velocities: weft::kMaxSpeed, for
/// the centre of mass and for the farthest point of a spinning body.
inline constexpr double kFarthestBody = 1e150;
/// The largest RigidOptions::maxPairs (the pair buffers are reserved up front).
inline constexpr Index kMaxRigidPairs = Index(1) << 28;

struct RigidOptions {
  std::vector<RigidBodyDesc> bodies;  // none: no rigid bodies, nothing constructed, nothing paid
  NarrowPhaseOptions narrowPhase;
  int substeps = 4;                   // >= 1: solver substeps of a step (one collision detection)
  int velocityIterations = 8;         // in [1, 1000], per substep
  int positionIterations = 1;         // in [0, 1000], per substep: passes of the penetration recovery (split impulses)
  double speculativeDistance = 0.01;  // m (>= 0): contacts are made this far before touching
  bool continuous = true;             // grow each pair's margin by its motion over the step (true with Rollback)
  double linearSlop = 0.005;          // m: penetration left alone (>= 0)
  double penetrationRate = 0.2;       // share of the penetration removed per step, (0, 1]
  double maxPushVelocity = 3;         // m/s (> 0)
  double restitutionThreshold = 0.5;  // m/s: slower impacts do not bounce
  double staticSpeed = 0.01;          // m/s: tangential speed under which static friction applies
  Index maxPairs = 0;                 // capacity of candidate pairs; 0 = 16 per piece + 64; at most 2^28
  RigidTimeOfImpact timeOfImpact = RigidTimeOfImpact::Speculative;
  double rollbackPenetration = 0.005;  // Rollback: deepest penetration a chunk may end with, m (> 0)
  int maxHalvings = 12;                // Rollback and redoDeepSteps: shortest chunk step / 2^maxHalvings (0..30)
  // Speculative: a step that ends with two bodies let into each other deeper than
  // RigidStats::kDeepShare of the thinner piece's inner radius (and deeper than they started)
  // is taken back and taken again in halves, each halved again while it does so (at most
  // maxHalvings times); the narrow phase runs again at the end of every step, on the pairs
  // that could have got that deep, to tell. Off: one solve a step, and such a step warns.
  bool redoDeepSteps = true;
  // With particles in the same Simulation (rigid/particle_coupling.hpp):
  bool particleContacts = true;      // particles and bodies push each other
  bool particleSupports = true;      // held particles carry the bodies on them (SupportContact); acts
                                     // through particleContacts (the reader refuses it set without them)
  double particleThickness = 0.005;  // particle radius against bodies, m (> 0)
};

/// Validates the options (every body and field); throws std::invalid_argument naming the
/// field (e.g. "rigid.bodies[2].shapes[0].halfExtents.y") and the value.
void validateRigidOptions(const RigidOptions& options);

/// What the bodies are made of: built once, read by every step.
struct RigidPiece {
  Index body = 0;
  RigidShapeDesc::Kind kind = RigidShapeDesc::Kind::Hull;  // Sphere or Hull (a box is a hull)
  double radius = 0;                                       // Sphere, m
  Index hull = -1;                                         // Hull: index into RigidModel::hulls
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();        // piece origin relative to the centre of mass, body axes, m
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // piece axes in body axes
  double boundingRadius = 0;                               // about `centre`, m
  double innerRadius = 0;  // Sphere: radius; Hull: from the vertices' mean to the nearest face plane, m
  Eigen::Vector3d centre =
      Eigen::Vector3d::Zero();  // bounding sphere centre, body frame relative to the centre of mass, m
  Eigen::Vector3d localMin = Eigen::Vector3d::Zero();  // the piece's box in its own frame, m
  Eigen::Vector3d localMax = Eigen::Vector3d::Zero();
};

struct RigidModel {
  Index bodyCount() const { return static_cast<Index>(motion.size()); }
  Index pieceCount() const { return static_cast<Index>(pieces.size()); }
  std::vector<std::string> names;
  std::vector<BodyMotion> motion;
  std::vector<double> inverseMass;              // 1/kg (0: static or kinematic)
  std::vector<double> mass;                     // kg
  std::vector<Eigen::Matrix3d> inertia;         // about the centre of mass, body axes, kg m^2
  std::vector<Eigen::Matrix3d> inverseInertia;  // body axes (0: static or kinematic)
  std::vector<Eigen::Vector3d> centreOfMass;    // in the body frame (from the given origin), m
  std::vector<double> reach;                    // distance from the centre of mass to the farthest point, m
  std::vector<double> staticFriction, kineticFriction, restitution;
  std::vector<KinematicPath> paths;  // per body (used by kinematic ones)
  std::vector<Index> firstPiece;     // body b's pieces are [firstPiece[b], firstPiece[b + 1])
  std::vector<RigidPiece> pieces;
  std::vector<ConvexHull> hulls;
};

/// Builds the model (hulls, mass properties); throws std::invalid_argument for bad bodies.
std::shared_ptr<const RigidModel> buildRigidModel(const std::vector<RigidBodyDesc>& bodies);

/// Where the bodies are: centre-of-mass positions and velocities, orientations.
struct RigidState {
  std::vector<Eigen::Vector3d> x;     // centre of mass, world, m
  std::vector<Eigen::Quaterniond> q;  // body axes in world (unit)
  std::vector<Eigen::Vector3d> v;     // m/s
  std::vector<Eigen::Vector3d> w;     // world angular velocity, rad/s
  double time = 0;                    // s
};

/// FNV-1a over the bits of every body's position, orientation and velocities (equal
/// hashes: bitwise equal states).
std::uint64_t rigidStateHash(const RigidState& state);

/// The initial state the descriptions give.
RigidState initialRigidState(const RigidModel& model, const std::vector<RigidBodyDesc>& bodies);

/// Findings of one step (or sums over steps).
struct RigidStats {
  std::int64_t candidatePairs = 0;    // broad phase pairs
  std::int64_t touchingPairs = 0;     // pairs with a manifold
  std::int64_t contacts = 0;          // manifold points
  std::int64_t warmStarted = 0;       // of which started from the last step's impulses (same pair and feature)
  std::int64_t witnessHits = 0;       // narrow phase queries answered by the cached witness
  std::int64_t narrowQueries = 0;     // hull-hull queries in all
  std::int64_t supportContacts = 0;   // contacts with held points (SupportContact)
  std::int64_t chunks = 0;            // chunks taken (1 per step, more under Rollback and in redone steps)
  std::int64_t rollbacks = 0;         // Rollback: chunks cut before or taken back after solving
  std::int64_t halvingLimitHits = 0;  // Rollback: chunks taken at the shortest length though too deep
  std::int64_t redoneSteps = 0;       // Speculative: steps taken again in chunks (RigidOptions::redoDeepSteps)
  double maxPenetration = 0;          // deepest contact at the start of the step's solve, m (>= 0)
  /// The deepest contact between two bodies as a share of the thinner piece's innerRadius
  /// (1: the thinner piece's middle has reached the other's surface), its depth (m), its
  /// pair of bodies (-1 when there is none) and the time its step, or the part of a step
  /// (a chunk of Rollback or of a redone step), started (s). Above
  /// kDeepShare the contacts have let the bodies into each other: the step is too long
  /// for them, or they started overlapping.
  static constexpr double kDeepShare = 0.5;
  double deepestShare = 0;
  double deepestDepth = 0;
  Index deepestA = -1, deepestB = -1;
  double deepestTime = 0;
  void add(const RigidStats& s);
};

/// A contact of a dynamic body with a point that something else holds: a particle lying
/// on a static or kinematic body, or a pinned one (rigid/particle_coupling.hpp gathers
/// them before each step). The point does not yield along the normal and moves with
/// `velocity`: the body rests on it and feels its friction (a tablecloth pulled from under
/// a box), while what holds the point takes the reaction.
struct SupportContact {
  Index body = 0;                                      // a dynamic body
  Eigen::Vector3d point = Eigen::Vector3d::Zero();     // on the body's surface, world, m
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();   // unit, from the support into the body
  double separation = 0;                               // m (< 0: penetrating)
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // of the support point, m/s
  std::uint64_t key = 0;  // the same point in consecutive steps (warm starting); increasing in a list
};

class RigidWorld {
 public:
  RigidWorld(std::shared_ptr<const RigidModel> model, RigidState initial, const RigidOptions& options,
             const Eigen::Vector3d& gravity);
  /// The initial state from options.bodies (which built `model`).
  RigidWorld(std::shared_ptr<const RigidModel> model, const RigidOptions& options, const Eigen::Vector3d& gravity);
  /// Builds the model from options.bodies.
  RigidWorld(const RigidOptions& options, const Eigen::Vector3d& gravity);

  /// Advances by h (s, finite and > 0, or std::invalid_argument). On failure (a full pair
  /// buffer, a non-finite body) the state is restored and the status says why
  /// (StepCode::CapacityExceeded / NonFinite with `body`).
  StepStatus step(double h, const Executor& executor);

  /// Puts the state back where the last step started (the caller's step failed elsewhere).
  void undoStep() { state_ = stepStart(); }
  /// The state at the start of the last step (where the bodies came from).
  const RigidState& stepStart() const { return chunked() ? stepBegin_ : backup_; }
  /// World pose of piece `p` in state `s` (std::invalid_argument for p outside [0, pieceCount())).
  Pose piecePose(Index p, const RigidState& s) const;
  /// Room for `capacity` support contacts (allocates: call before stepping).
  void reserveSupports(Index capacity);
  /// The support contacts of the next step (copied; at most the reserved capacity, keys
  /// increasing). They hold for one step.
  void setSupports(const SupportContact* contacts, Index count);
  /// Applies an impulse (N s, world) at a world point to a dynamic body (others ignore it):
  /// how particles push bodies (rigid/particle_coupling.hpp). Throws std::invalid_argument
  /// (the world unchanged) for a body outside [0, bodyCount()) or a non-finite impulse or point.
  void applyImpulse(Index body, const Eigen::Vector3d& impulse, const Eigen::Vector3d& point);

  const RigidModel& model() const { return *model_; }
  const RigidState& state() const { return state_; }
  /// Starts from `state`: one entry per body, positions within +-kFarthestBody, speeds (of
  /// the centre of mass and of a dynamic body's farthest point) at most kMaxSpeed,
  /// orientations non-zero quaternions (normalised here), a finite time; else
  /// std::invalid_argument naming the field and the world unchanged.
  void setState(const RigidState& state);
  /// Checkpoints (Simulation::save / load): the state, the kinematic bodies' path origins,
  /// the last step's pairs with their warm-start impulses and witness caches, its substep
  /// and the statistics, read back in the order written (unlike setState, which starts the
  /// contacts afresh). A body count other than the model's is refused.
  void saveCarry(ArchiveWriter& out) const;
  void loadCarry(ArchiveReader& in);
  const RigidOptions& options() const { return options_; }
  const RigidStats& lastStats() const { return last_; }
  const RigidStats& totalStats() const { return total_; }
  /// Position (world) of body b's frame origin, as RigidBodyDesc::position names it (this
  /// and angularMomentum: std::invalid_argument for b outside [0, bodyCount())).
  Eigen::Vector3d bodyOrigin(Index b) const;
  /// Kinetic plus gravitational potential energy of the dynamic bodies, J (potential
  /// relative to height 0 along -gravity).
  double energy() const;
  /// World angular momentum of body b about its centre of mass, kg m^2/s.
  Eigen::Vector3d angularMomentum(Index b) const;

  RigidWorld(const RigidWorld&) = delete;
  RigidWorld& operator=(const RigidWorld&) = delete;

 private:
  struct Pair {
    Index a, b;  // pieces, a < b
    std::uint64_t key() const { return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b); }
  };
  // One contact point as the solver sees it (hot data of the iterations first).
  struct Constraint {
    Index bodyA = 0, bodyB = 0;
    Eigen::Vector3d rA, rB;  // from the centres of mass to the point, m
    Eigen::Vector3d normal, tangent1, tangent2;
    double normalMass = 0, tangentMass1 = 0, tangentMass2 = 0;
    double separation = 0;          // m, now (advanced substep by substep)
    double previousSeparation = 0;  // m, at the start of the previous substep (impact or resting?)
    double normalImpulse = 0, tangentImpulse1 = 0, tangentImpulse2 = 0;  // accumulated, N s
    double pushImpulse = 0;  // accumulated split impulse of the penetration recovery (not carried over)
    double maxNormalImpulse = 0;
    double friction = 0;  // the coefficient chosen for this step (static or kinetic)
    double restitution = 0;
    double approachVelocity = 0;  // relative normal velocity before the solve, m/s
    std::uint64_t pairKey = 0;
    std::uint32_t featureId = 0;
    Eigen::Vector3d anchor;  // the point in body A's frame (warm starting by position when the feature id changed)
    // Precomputed for the directions k = 0 (normal), 1, 2 (tangents): r x d on each body and
    // I^-1 (r x d), so an impulse costs no matrix product in the iterations.
    double inverseMassA = 0, inverseMassB = 0;
    std::array<Eigen::Vector3d, 3> crossA, crossB, angularA, angularB;
    const Eigen::Vector3d& direction(int k) const { return k == 0 ? normal : k == 1 ? tangent1 : tangent2; }
  };
  std::shared_ptr<const RigidModel> model_;
  RigidState state_, backup_;  // backup_: where the current chunk started
  RigidState stepBegin_;       // where the step started (when taken in chunks: chunked())
  bool rollback() const { return options_.timeOfImpact == RigidTimeOfImpact::Rollback; }
  bool chunked() const { return rollback() || options_.redoDeepSteps; }  // steps in stepInChunks
  void reservePairs(std::size_t capacity);                               // every per-pair buffer (the constructor)
  RigidOptions options_;
  Eigen::Vector3d gravity_;
  RigidStats last_, total_;
  // Per piece: world pose at the start of the step and swept box.
  std::vector<Pose> piecePose_;
  std::vector<Eigen::Vector3d> boxMin_, boxMax_;
  std::vector<Index> sweepOrder_;
  // Pairs of this step and of the last (sorted by key), their caches and manifolds.
  std::vector<Pair> pairs_, lastPairs_;
  std::vector<PairCache> caches_, lastCaches_;
  std::vector<ContactManifold> manifolds_;
  std::vector<double> endDepth_;  // Rollback: per pair, how deep it ends the chunk, m
  std::vector<double> margins_;
  std::vector<NarrowPhaseOutcome> outcomes_;
  // What the next step's warm start keeps of a contact point (64 bytes, where the solver's
  // Constraint takes 576): where it was in body A's frame, its impulses, its feature. No
  // padding: checkpoints write it as bytes.
  struct WarmPoint {
    Eigen::Vector3d anchor;
    double normalImpulse = 0;         // N s
    Eigen::Vector3d frictionImpulse;  // both tangents' impulses as one world vector, N s
    std::uint32_t featureId = 0;
    std::uint32_t unused = 0;
  };
  static_assert(sizeof(WarmPoint) == 64);
  std::vector<Constraint> constraints_;
  std::vector<WarmPoint> lastPoints_;  // the last step's points, pair by pair as its constraints were
  std::vector<Index> pairFirstConstraint_, lastPairFirstConstraint_;  // per pair, CSR into constraints_ / lastPoints_
  static constexpr int kColours = 64;  // colours of the parallel passes; more: one serial colour
  // A support contact as the solver sees it: the body is B, the held point A.
  struct Support {
    Index body = 0;
    Eigen::Vector3d r;                                 // from the centre of mass to the point, m
    std::array<Eigen::Vector3d, 3> direction;          // normal, tangent1, tangent2
    std::array<Eigen::Vector3d, 3> cross, angular;     // r x d, I^-1 (r x d)
    std::array<double, 3> mass{}, impulse{}, speed{};  // effective mass; accumulated N s; d . point velocity
    double separation = 0, previousSeparation = 0, pushImpulse = 0, friction = 0;
    std::uint64_t key = 0;
  };
  std::vector<SupportContact> supportInput_;
  std::vector<Support> supports_, lastSupports_;
  struct Block {  // one manifold's points, solved together along the normal
    Index first = 0;
    int count = 0;
    int colour = 0;                                     // of the parallel passes (colourBlocks)
    Eigen::Matrix4d inverse = Eigen::Matrix4d::Zero();  // of the points' normal coupling (count x count used)
  };
  std::vector<Block> blocks_;
  std::vector<std::uint64_t> bodyColours_;  // per body: the colours its manifolds took (bit k: colour k)
  std::vector<Index> colourOrder_;          // block indices, colour by colour
  std::vector<Index> colourStart_;          // colour c is colourOrder_[colourStart_[c], colourStart_[c + 1])
  std::vector<Index> colourCount_;
  Index capacityPairs_ = 0;
  double invStep_ = 0;                     // 1 / substep of the current step
  double lastSubstep_ = 0;                 // the last step's substep, s (warm starting rescales impulses by the ratio)
  std::vector<Eigen::Matrix3d> rotation_;  // per body, this step
  std::vector<Eigen::Vector3d> pushV_, pushW_;    // per body: split-impulse velocities (positions only), m/s, rad/s
  std::vector<Eigen::Matrix3d> invInertiaWorld_;  // per body, this step
  std::vector<Eigen::Vector3d> kinematicX0_;      // per body: centre of mass at time 0 (kinematic bodies)
  std::vector<Eigen::Quaterniond> kinematicQ0_;
  std::vector<Eigen::Vector3d> targetX_;  // per body: kinematic position at the end of the step
  std::vector<Eigen::Quaterniond> targetQ_;
  StepStatus fail(StepCode code, Index body, double value);
  /// Checkpoints: what saveCarry writes and loadCarry reads, in order, as one list.
  template <class Archive, class Self>
  static void transfer(Archive& archive, Self& self);
  /// One chunk of length h. Rollback mode: `shorter` > 0 on return when the chunk must be
  /// cut (the largest length that would do, or h / 2 after a too deep end) and the state
  /// is as it was; `force` takes it whatever it finds.
  StepStatus stepChunk(double h, const Executor& executor, bool force, double& shorter);
  void broadPhase(double h, const Executor& executor, bool& overflow, Index& nonFinite);
  void narrowPhase(double h, const Executor& executor);
  /// Whether a pair ends the chunk deeper than the limit and than it started (the limit:
  /// rollbackPenetration, or with `share` kDeepShare of the thinner piece's inner radius).
  bool endsTooDeep(const Executor& executor, bool share);
  /// The loop over the chunks of a step of length h (Rollback, or speculative with redoDeepSteps).
  StepStatus stepInChunks(double h, const Executor& executor);
  void buildConstraints(double h);
  /// Colours the manifolds so that no two of one colour share a dynamic body (greedy, in
  /// pair order: the same colours for any thread count); the passes below solve a colour's
  /// manifolds in parallel, colour after colour.
  void colourBlocks();
  /// Runs fn(block index) over every manifold, colour by colour (reversed: last colour
  /// first), each colour's manifolds in parallel.
  template <class Fn>
  void forEachBlockByColour(const Executor& executor, bool reversed, Fn&& fn);
  void warmStart(const Executor& executor);
  void solveBlock(const Block& block);
  void solveVelocities(bool backward, const Executor& executor);
  /// Relative velocity of the point along direction k (0 normal, 1 and 2 tangents).
  double relativeVelocity(const Constraint& c, int k) const;
  /// Applies lambda along direction k (B gets +, A gets -).
  void apply(const Constraint& c, int k, double lambda);
  /// Coulomb friction at one point for tangential velocities (slip1, slip2), taking `share` of
  /// the correction (1: Gauss-Seidel; 1 / points: Jacobi within a manifold).
  void solveFriction(Constraint& c, double slip1, double slip2, double share);
  void solveNormal(Constraint& c);
  void advanceSeparations(double hs, const Executor& executor);
  void solvePositions(double h, const Executor& executor);
  void integratePositions(double h, bool last, const Executor& executor);
  void applyRestitution();
  void buildSupports(double h);
  void solveSupports(bool backward);
  double supportVelocity(const Support& s, int k) const;
  void applySupport(const Support& s, int k, double lambda);
};

}  // namespace weft
