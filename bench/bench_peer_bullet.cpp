// Peer benchmark (optional, built when Bullet is found: WEFT_PEERS=1 bash tools/setup.sh
// installs Debian's libbullet-dev 3.24): weft's `pile` scene in Bullet's btDiscreteDynamicsWorld,
// timed in the same binary as BM_Rigid_Pile so the two are compared as a ratio of one run.
//
//   BM_Peer_Bullet_Pile/substeps:S  one 1/60 s step of the same 1000 bodies, settled 1.5 s
//                                   (90 steps) in Bullet, reset to that state every 60 steps
//                                   (BM_Rigid_Pile's protocol; World::reset: in place, every
//                                   manifold dropped). S = 1: stepSimulation(1/60, 1, 1/60),
//                                   Bullet as most users run it (10 solver iterations);
//                                   S = 4: four internal 1/240 s steps, closer to weft's 4
//                                   substeps x 8 velocity passes. Counters:
//                                   bodies, contacts (manifold points), pairs (manifolds: one
//                                   per overlapping pair of boxes, the broad phase's
//                                   candidates), touching_pairs (manifolds with points); the
//                                   settled state's in_bin, below_floor, mean_height and
//                                   mean_speed (pile_summary.hpp, as BM_Rigid_Pile's).
//
// The translation, body by body, from weft's RigidModel (so mass, centre of mass and inertia
// are weft's, whatever the density or mass given):
//   - Bullet's body frame is the centre of mass with the principal axes of weft's inertia
//     tensor (a single box's or sphere's own axes), and Bullet gets the principal moments.
//   - Box -> btBoxShape, sphere -> btSphereShape, hull -> btConvexHullShape of the hull's
//     vertices; a body of one piece is that shape (a hull's points moved into the principal
//     frame), several pieces a btCompoundShape with a child per piece at its offset and
//     rotation from the centre of mass.
//   - initializePolyhedralFeatures() on boxes and hulls: pairs of them are then clipped face
//     against face into manifolds of several points, as weft's are, instead of gathering one
//     GJK point per step (what a careful Bullet user does; without it on the boxes, the floor
//     and walls meet hulls one point at a time).
//   - Collision margin 4 mm (Bullet's default 4 cm is a third of these 0.1 to 0.2 m bodies).
//     A box keeps its size (Bullet puts the margin inside it), a sphere's margin is its
//     radius; a hull's points are weft's, so where Bullet adds the margin (GJK: against
//     spheres) it is 4 mm larger, where it clips the polyhedra (against boxes and hulls) not.
//   - Friction: each body sqrt(mu_kinetic), so that Bullet's product of the two is weft's
//     geometric mean (Bullet has one coefficient; weft's static one applies under 1 cm/s).
//   - Restitution: weft's, combined as weft does (the larger of the two, through Bullet's
//     gCalculateCombinedRestitutionCallback); 0 in the pile.
//   - Static bodies mass 0 and no inertia; sleeping off (weft simulates every body every
//     step); no CCD (Bullet's default; weft's speculative contacts are always on).
// Bullet runs on one thread here: btDiscreteDynamicsWorld is serial, and Debian builds Bullet
// without BT_THREADSAFE (btCreateDefaultTaskScheduler() is null), so not even
// btDiscreteDynamicsWorldMt could use the second core.
#include <BulletCollision/CollisionDispatch/btManifoldResult.h>
#include <benchmark/benchmark.h>
#include <btBulletDynamicsCommon.h>

#include <Eigen/Eigenvalues>
#include <map>
#include <memory>
#include <vector>

#include "pile_summary.hpp"
#include "weft/weft.hpp"

namespace {

constexpr double kMargin = 0.004;  // m

btVector3 bt(const Eigen::Vector3d& v) { return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z())); }

btMatrix3x3 bt(const Eigen::Matrix3d& m) {
  return btMatrix3x3(btScalar(m(0, 0)), btScalar(m(0, 1)), btScalar(m(0, 2)), btScalar(m(1, 0)), btScalar(m(1, 1)),
                     btScalar(m(1, 2)), btScalar(m(2, 0)), btScalar(m(2, 1)), btScalar(m(2, 2)));
}

/// One body as Bullet sees it: its shape (and a compound's children), mass, principal moments
/// of inertia, and the rotation from weft's body axes to the Bullet body's (principal) axes.
struct BodySpec {
  std::shared_ptr<btCollisionShape> shape;
  std::vector<std::shared_ptr<btCollisionShape>> children;
  double mass = 0;
  Eigen::Vector3d inertia = Eigen::Vector3d::Zero();
  Eigen::Matrix3d principal = Eigen::Matrix3d::Identity();
  double friction = 0, restitution = 0;
};

/// A piece's shape; a hull's points are mapped by `place` (from the piece's frame to the one
/// the shape lives in: the Bullet body's for a single piece, the piece's own for a child).
std::shared_ptr<btCollisionShape> pieceShape(const weft::RigidShapeDesc& desc, const weft::RigidModel& model,
                                             const weft::RigidPiece& piece, const Eigen::Affine3d& place) {
  if (desc.kind == weft::RigidShapeDesc::Kind::Sphere) return std::make_shared<btSphereShape>(btScalar(desc.radius));
  if (desc.kind == weft::RigidShapeDesc::Kind::Box) {
    auto box = std::make_shared<btBoxShape>(bt(desc.halfExtents));
    box->setMargin(btScalar(kMargin));  // keeps the box's size: Bullet's box margin is inside it
    box->initializePolyhedralFeatures();
    return box;
  }
  auto hull = std::make_shared<btConvexHullShape>();
  for (const Eigen::Vector3d& v : model.hulls[static_cast<std::size_t>(piece.hull)].vertices)
    hull->addPoint(bt(Eigen::Vector3d(place * v)), false);
  hull->recalcLocalAabb();
  hull->setMargin(btScalar(kMargin));
  hull->initializePolyhedralFeatures();
  return hull;
}

BodySpec translate(const weft::RigidModel& model, const weft::RigidBodyDesc& desc, weft::Index b) {
  BodySpec s;
  const auto first = static_cast<std::size_t>(model.firstPiece[b]);
  const std::size_t count = desc.shapes.size();
  const weft::RigidPiece& only = model.pieces[first];
  const bool dynamic = model.motion[b] == weft::BodyMotion::Dynamic;
  // Principal axes: a single box's or sphere's own (exact, whatever the moments' degeneracy),
  // else the eigenvectors of weft's inertia about the centre of mass (right-handed).
  if (count == 1 && desc.shapes[0].kind != weft::RigidShapeDesc::Kind::Hull) {
    s.principal = only.rotation;
  } else {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(model.inertia[b]);
    s.principal = eigen.eigenvectors();
    if (s.principal.determinant() < 0) s.principal.col(2) *= -1;
  }
  if (dynamic) {
    s.mass = model.mass[b];
    s.inertia = (s.principal.transpose() * model.inertia[b] * s.principal).diagonal();
  }
  s.friction = std::sqrt(model.kineticFriction[b]);
  s.restitution = model.restitution[b];
  // Each piece in the Bullet body's frame (centre of mass, principal axes).
  auto placement = [&](const weft::RigidPiece& piece) {
    Eigen::Affine3d t = Eigen::Affine3d::Identity();
    t.linear() = s.principal.transpose() * piece.rotation;
    t.translation() = s.principal.transpose() * piece.offset;
    return t;
  };
  const Eigen::Affine3d single = placement(only);
  const bool placed = single.translation().norm() < 1e-9 && single.linear().isIdentity(1e-9);
  if (count == 1 && (desc.shapes[0].kind == weft::RigidShapeDesc::Kind::Hull || placed)) {
    s.shape = pieceShape(desc.shapes[0], model, only, single);
    return s;
  }
  auto compound = std::make_shared<btCompoundShape>();
  for (std::size_t k = 0; k < count; ++k) {
    const weft::RigidPiece& piece = model.pieces[first + k];
    const Eigen::Affine3d t = placement(piece);
    s.children.push_back(pieceShape(desc.shapes[k], model, piece, Eigen::Affine3d::Identity()));
    compound->addChildShape(btTransform(bt(Eigen::Matrix3d(t.linear())), bt(Eigen::Vector3d(t.translation()))),
                            s.children.back().get());
  }
  s.shape = compound;
  return s;
}

/// weft's `pile`, translated, and Bullet's settled state of it.
struct Pile {
  std::vector<BodySpec> specs;
  std::vector<btTransform> settled;
  std::vector<btVector3> settledV, settledW;
  weftbench::PileSummary summary;
};

btScalar largerRestitution(const btCollisionObject* a, const btCollisionObject* b) {
  return btMax(a->getRestitution(), b->getRestitution());
}

class World {
 public:
  explicit World(const Pile& pile) {
    previousRestitution_ = gCalculateCombinedRestitutionCallback;
    gCalculateCombinedRestitutionCallback = &largerRestitution;
    config_ = std::make_unique<btDefaultCollisionConfiguration>();
    dispatcher_ = std::make_unique<btCollisionDispatcher>(config_.get());
    broadphase_ = std::make_unique<btDbvtBroadphase>();
    solver_ = std::make_unique<btSequentialImpulseConstraintSolver>();
    world_ =
        std::make_unique<btDiscreteDynamicsWorld>(dispatcher_.get(), broadphase_.get(), solver_.get(), config_.get());
    world_->setGravity(btVector3(0, btScalar(-9.81), 0));
    for (std::size_t b = 0; b < pile.specs.size(); ++b) {
      const BodySpec& s = pile.specs[b];
      btRigidBody::btRigidBodyConstructionInfo info(btScalar(s.mass), nullptr, s.shape.get(), bt(s.inertia));
      info.m_startWorldTransform = pile.settled[b];
      info.m_friction = btScalar(s.friction);
      info.m_restitution = btScalar(s.restitution);
      auto body = std::make_unique<btRigidBody>(info);
      if (s.mass > 0) {
        body->setActivationState(DISABLE_DEACTIVATION);
        body->setLinearVelocity(pile.settledV[b]);
        body->setAngularVelocity(pile.settledW[b]);
      }
      world_->addRigidBody(body.get());
      bodies_.push_back(std::move(body));
    }
  }
  ~World() {
    for (auto& b : bodies_) world_->removeRigidBody(b.get());
    gCalculateCombinedRestitutionCallback = previousRestitution_;
  }
  World(const World&) = delete;
  World& operator=(const World&) = delete;
  btDiscreteDynamicsWorld& world() { return *world_; }
  const std::vector<std::unique_ptr<btRigidBody>>& bodies() const { return bodies_; }

  /// Back to the pile's settled state with nothing carried over (weft's setState drops its
  /// contacts too): transforms and velocities, and every overlapping pair's collision
  /// algorithm and manifold dropped (the pairs stay: btDbvtBroadphase updates them as the
  /// boxes move). The next step starts cold, with new manifolds. Not a bitwise replay: the
  /// pairs keep their order from before, so the solver's order differs from a new world's
  /// (a new world would redo the broad phase's work of its first step in the timed step).
  void reset(const Pile& pile) {
    for (std::size_t b = 0; b < bodies_.size(); ++b) {
      btRigidBody& body = *bodies_[b];
      if (pile.specs[b].mass <= 0) continue;
      body.setCenterOfMassTransform(pile.settled[b]);
      body.setLinearVelocity(pile.settledV[b]);
      body.setAngularVelocity(pile.settledW[b]);
      body.setInterpolationLinearVelocity(pile.settledV[b]);
      body.setInterpolationAngularVelocity(pile.settledW[b]);
      body.clearForces();
    }
    btOverlappingPairCache& cache = *broadphase_->getOverlappingPairCache();
    btBroadphasePairArray& pairs = cache.getOverlappingPairArray();
    for (int i = 0; i < pairs.size(); ++i) cache.cleanOverlappingPair(pairs[i], dispatcher_.get());
    world_->updateAabbs();
    solver_->reset();
  }

 private:
  CalculateCombinedCallback previousRestitution_ = nullptr;
  std::unique_ptr<btDefaultCollisionConfiguration> config_;
  std::unique_ptr<btCollisionDispatcher> dispatcher_;
  std::unique_ptr<btDbvtBroadphase> broadphase_;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver_;
  std::unique_ptr<btDiscreteDynamicsWorld> world_;
  std::vector<std::unique_ptr<btRigidBody>> bodies_;
};

void step(btDiscreteDynamicsWorld& world, int substeps) {
  const double h = weft::rigidSceneTimeStep();
  world.stepSimulation(btScalar(h), substeps, btScalar(h / substeps));
}

/// weft's pile, translated and settled for 1.5 s in Bullet with `substeps`; null if the scene
/// has a body this translation does not cover (kinematic: its path is not translated).
const Pile* pile(int substeps) {
  static std::map<int, std::unique_ptr<Pile>> cache;
  std::unique_ptr<Pile>& p = cache[substeps];
  if (p) return p.get();
  const weft::RigidOptions options = weft::pileScene(1000);
  const std::shared_ptr<const weft::RigidModel> model = weft::buildRigidModel(options.bodies);
  const weft::RigidState start = weft::initialRigidState(*model, options.bodies);
  auto made = std::make_unique<Pile>();
  for (weft::Index b = 0; b < model->bodyCount(); ++b) {
    if (model->motion[b] == weft::BodyMotion::Kinematic) return nullptr;
    const auto i = static_cast<std::size_t>(b);
    BodySpec s = translate(*model, options.bodies[i], b);
    // Bullet's body frame: the centre of mass, weft's body axes turned to the principal ones.
    made->settled.emplace_back(bt(Eigen::Matrix3d(start.q[i].toRotationMatrix() * s.principal)), bt(start.x[i]));
    made->settledV.push_back(bt(start.v[i]));
    made->settledW.push_back(bt(start.w[i]));
    made->specs.push_back(std::move(s));
  }
  World world(*made);
  for (int i = 0; i < 90; ++i) step(world.world(), substeps);
  for (std::size_t b = 0; b < made->specs.size(); ++b) {
    const btRigidBody& body = *world.bodies()[b];
    made->settled[b] = body.getWorldTransform();
    made->settledV[b] = body.getLinearVelocity();
    made->settledW[b] = body.getAngularVelocity();
    if (made->specs[b].mass > 0) {
      const btVector3& x = body.getWorldTransform().getOrigin();
      made->summary.add(x.x(), x.y(), x.z(), body.getLinearVelocity().length());
    }
  }
  p = std::move(made);
  return p.get();
}

void BM_Peer_Bullet_Pile(benchmark::State& st) {
  const int substeps = static_cast<int>(st.range(0));
  const Pile* settled = pile(substeps);
  if (!settled) {
    st.SkipWithError("the pile has a kinematic body: not translated to Bullet");
    return;
  }
  World world(*settled);
  for (int i = 0; i < 5; ++i) step(world.world(), substeps);  // contact caches fill, as weft's warm-up
  int k = 0;
  for (auto _ : st) {
    if (++k == 60) {
      st.PauseTiming();
      world.reset(*settled);
      k = 0;
      st.ResumeTiming();
    }
    step(world.world(), substeps);
  }
  btDispatcher& dispatcher = *world.world().getDispatcher();
  int contacts = 0, touching = 0;
  for (int m = 0; m < dispatcher.getNumManifolds(); ++m) {
    const int n = dispatcher.getManifoldByIndexInternal(m)->getNumContacts();
    contacts += n;
    touching += n > 0;
  }
  st.counters["bodies"] = static_cast<double>(settled->specs.size());
  st.counters["contacts"] = contacts;
  st.counters["pairs"] = dispatcher.getNumManifolds();
  st.counters["touching_pairs"] = touching;
  settled->summary.report(st);
}

}  // namespace

BENCHMARK(BM_Peer_Bullet_Pile)->ArgNames({"substeps"})->Arg(1)->Arg(4)->Unit(benchmark::kMillisecond)->UseRealTime();
