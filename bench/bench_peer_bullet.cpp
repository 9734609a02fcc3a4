// Peer benchmark (optional, built when Bullet is found: WEFT_PEERS=1 bash tools/setup.sh
// installs Debian's libbullet-dev): weft's `pile` scene in Bullet's btDiscreteDynamicsWorld,
// timed in the same binary as BM_Rigid_Pile so the two are compared as a ratio of one run.
//
//   BM_Peer_Bullet_Pile/substeps:S  one 1/60 s step of the same 1000 bodies, settled 1.5 s,
//                                   reset to that state every 60 steps (BM_Rigid_Pile's
//                                   protocol). S = 1: stepSimulation(1/60, 1, 1/60), Bullet
//                                   as most users run it (10 solver iterations); S = 4: four
//                                   internal 1/240 s steps, closer to weft's 4 substeps x 8
//                                   velocity passes. Counters: bodies, contacts (manifold
//                                   points), pairs (manifolds), mean_height (m, of the dynamic
//                                   bodies, at the settled state: the two piles are alike).
//
// The translation, body by body (weft's RigidModel gives the same mass, centre of mass and
// inertia): boxes as btBoxShape, spheres as btSphereShape, hulls as btConvexHullShape with
// initializePolyhedralFeatures() (face clipping for multi-point manifolds, what a careful
// user does) placed in the principal frame of weft's inertia about the centre of mass;
// collision margin 4 mm (Bullet's default 4 cm is a third of these bodies; boxes keep
// their size, hull margins are added outside); each body's friction sqrt(mu_kinetic), so
// Bullet's product rule gives weft's geometric mean; restitution 0 as in the scene;
// deactivation (sleeping) off, since weft simulates every body every step. Bullet's
// discrete world runs on one thread (Debian builds it without BT_THREADSAFE).
#include <benchmark/benchmark.h>
#include <btBulletDynamicsCommon.h>

#include <Eigen/Eigenvalues>
#include <memory>
#include <vector>

#include "bench_common.hpp"
#include "weft/weft.hpp"

namespace {

constexpr double kMargin = 0.004;  // m

btVector3 bt(const Eigen::Vector3d& v) { return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z())); }

btMatrix3x3 bt(const Eigen::Matrix3d& m) {
  return btMatrix3x3(btScalar(m(0, 0)), btScalar(m(0, 1)), btScalar(m(0, 2)), btScalar(m(1, 0)), btScalar(m(1, 1)),
                     btScalar(m(1, 2)), btScalar(m(2, 0)), btScalar(m(2, 1)), btScalar(m(2, 2)));
}

/// One body as Bullet sees it: its shape, mass and principal inertia, and the rotation
/// from weft's body axes to the Bullet body's axes (principal axes for hulls).
struct BodySpec {
  std::shared_ptr<btCollisionShape> shape;
  double mass = 0;
  Eigen::Vector3d inertia = Eigen::Vector3d::Zero();
  Eigen::Matrix3d principal = Eigen::Matrix3d::Identity();
  double friction = 0;
};

struct Pile {
  std::vector<BodySpec> specs;
  std::vector<btTransform> settled;
  std::vector<btVector3> settledV, settledW;
  double meanHeight = 0;
  int belowFloor = 0;  // dynamic bodies whose centre ended under the floor's top (fell through)
};

class World {
 public:
  explicit World(const Pile& pile) {
    config_ = std::make_unique<btDefaultCollisionConfiguration>();
    dispatcher_ = std::make_unique<btCollisionDispatcher>(config_.get());
    broadphase_ = std::make_unique<btDbvtBroadphase>();
    solver_ = std::make_unique<btSequentialImpulseConstraintSolver>();
    world_ =
        std::make_unique<btDiscreteDynamicsWorld>(dispatcher_.get(), broadphase_.get(), solver_.get(), config_.get());
    world_->setGravity(btVector3(0, btScalar(-9.81), 0));
    for (std::size_t b = 0; b < pile.specs.size(); ++b) {
      const BodySpec& s = pile.specs[b];
      btVector3 inertia = bt(s.inertia);
      btRigidBody::btRigidBodyConstructionInfo info(btScalar(s.mass), nullptr, s.shape.get(), inertia);
      info.m_startWorldTransform = pile.settled[b];
      info.m_friction = btScalar(s.friction);
      info.m_restitution = 0;
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
  }
  btDiscreteDynamicsWorld& world() { return *world_; }
  const std::vector<std::unique_ptr<btRigidBody>>& bodies() const { return bodies_; }

 private:
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

/// weft's pile, translated; settled for 1.5 s in Bullet with `substeps`.
const Pile& pile(int substeps) {
  static std::unique_ptr<Pile> cache[5];
  std::unique_ptr<Pile>& p = cache[substeps];
  if (p) return *p;
  p = std::make_unique<Pile>();
  const weft::RigidOptions options = weft::pileScene(1000);
  const std::shared_ptr<const weft::RigidModel> model = weft::buildRigidModel(options.bodies);
  const weft::RigidState start = weft::initialRigidState(*model, options.bodies);
  for (weft::Index b = 0; b < model->bodyCount(); ++b) {
    const weft::RigidBodyDesc& desc = options.bodies[static_cast<std::size_t>(b)];
    const weft::RigidShapeDesc& shape = desc.shapes.front();  // the pile's bodies are one piece each
    const weft::RigidPiece& piece = model->pieces[static_cast<std::size_t>(model->firstPiece[b])];
    BodySpec s;
    s.friction = std::sqrt(model->kineticFriction[b]);
    const bool dynamic = model->motion[b] == weft::BodyMotion::Dynamic;
    s.mass = dynamic ? model->mass[b] : 0;
    if (shape.kind == weft::RigidShapeDesc::Kind::Sphere) {
      s.shape = std::make_shared<btSphereShape>(btScalar(shape.radius));
      s.inertia = model->inertia[b].diagonal();
    } else if (shape.kind == weft::RigidShapeDesc::Kind::Box) {
      auto box = std::make_shared<btBoxShape>(bt(shape.halfExtents));
      box->setMargin(btScalar(kMargin));
      s.shape = box;
      s.inertia = model->inertia[b].diagonal();  // a box's axes are principal
      s.principal = shape.rotation.toRotationMatrix();
    } else {
      // Principal axes of weft's inertia about the centre of mass; the hull's points in them.
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(model->inertia[b]);
      s.principal = eigen.eigenvectors();
      if (s.principal.determinant() < 0) s.principal.col(2) *= -1;
      s.inertia = eigen.eigenvalues();
      auto hull = std::make_shared<btConvexHullShape>();
      for (const Eigen::Vector3d& v : model->hulls[static_cast<std::size_t>(piece.hull)].vertices)
        hull->addPoint(bt(Eigen::Vector3d(s.principal.transpose() * (piece.rotation * v + piece.offset))), false);
      hull->recalcLocalAabb();
      hull->setMargin(btScalar(kMargin));
      hull->initializePolyhedralFeatures();
      s.shape = hull;
    }
    // Bullet's body frame: the centre of mass, weft's body axes turned to the principal ones.
    const Eigen::Matrix3d r = start.q[static_cast<std::size_t>(b)].toRotationMatrix() * s.principal;
    p->settled.emplace_back(bt(r), bt(start.x[static_cast<std::size_t>(b)]));
    p->settledV.push_back(bt(start.v[static_cast<std::size_t>(b)]));
    p->settledW.push_back(bt(start.w[static_cast<std::size_t>(b)]));
    p->specs.push_back(std::move(s));
  }
  World world(*p);
  for (int i = 0; i < 90; ++i) step(world.world(), substeps);
  double height = 0;
  int dynamicCount = 0;
  for (std::size_t b = 0; b < p->specs.size(); ++b) {
    const btRigidBody& body = *world.bodies()[b];
    p->settled[b] = body.getWorldTransform();
    p->settledV[b] = body.getLinearVelocity();
    p->settledW[b] = body.getAngularVelocity();
    if (p->specs[b].mass > 0) {
      height += body.getWorldTransform().getOrigin().y();
      p->belowFloor += body.getWorldTransform().getOrigin().y() < 0;
      ++dynamicCount;
    }
  }
  p->meanHeight = height / std::max(dynamicCount, 1);
  return *p;
}

void BM_Peer_Bullet_Pile(benchmark::State& st) {
  const int substeps = static_cast<int>(st.range(0));
  const Pile& settled = pile(substeps);
  auto world = std::make_unique<World>(settled);
  for (int i = 0; i < 5; ++i) step(world->world(), substeps);  // contact caches fill, as weft's warm-up
  int k = 0;
  for (auto _ : st) {
    if (++k == 60) {
      st.PauseTiming();
      world.reset();
      world = std::make_unique<World>(settled);
      k = 0;
      st.ResumeTiming();
    }
    step(world->world(), substeps);
  }
  btDispatcher& dispatcher = *world->world().getDispatcher();
  int contacts = 0, touching = 0;
  for (int m = 0; m < dispatcher.getNumManifolds(); ++m) {
    const int n = dispatcher.getManifoldByIndexInternal(m)->getNumContacts();
    contacts += n;
    touching += n > 0;
  }
  st.counters["bodies"] = static_cast<double>(settled.specs.size());
  st.counters["contacts"] = contacts;
  st.counters["pairs"] = touching;  // manifolds with points (Bullet keeps one per overlapping box pair)
  st.counters["mean_height"] = settled.meanHeight;
  st.counters["below_floor"] = settled.belowFloor;
}

}  // namespace

BENCHMARK(BM_Peer_Bullet_Pile)->ArgNames({"substeps"})->Arg(1)->Arg(4)->Unit(benchmark::kMillisecond)->UseRealTime();
