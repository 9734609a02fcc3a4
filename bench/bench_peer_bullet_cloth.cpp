// Peer benchmark (optional, built when Bullet is found: WEFT_PEERS=1 bash tools/setup.sh
// installs Debian's libbullet-dev 3.24): weft's 128² flag as a Bullet soft body
// (btSoftBody in a btSoftRigidDynamicsWorld), on the cloth-peer protocol of
// patch_protocol.hpp, timed in the same binary as weft's BM_Patch_* (bench_patch.cpp).
//
//   BM_Peer_Bullet_Cloth/piterations:I one 1/600 s step (stepSimulation(1/600, 0): one
//                                      internal step of exactly that dt), I position-solver
//                                      iterations (btSoftBody::Config::piterations: 1, 4, 10;
//                                      Bullet's default is 1). Counters: those of
//                                      StretchSeries (max_stretch, mean_stretch, ... over the
//                                      same springs, weft::stretch of the flag's structural
//                                      springs on Bullet's node positions), nodes, links.
//
// The translation, from weft's Model so that both have the same particles and springs:
//   - one node per particle at its position, with its mass (0.5 kg / 128²); the two pinned
//     corners get mass 0, Bullet's fixed nodes;
//   - one link per weft spring (structural, shear with both diagonals of a cell, bend over
//     two cells), its rest length the initial distance (weft's rest length); one face per
//     weft triangle (Bullet uses faces for aerodynamics and collisions, neither acts here);
//   - the links' material is Bullet's default, linear stiffness kLST = 1: each iteration
//     moves a link's ends all the way back to its rest length (position-based: Bullet's
//     stiffness is a fraction in [0, 1], not weft's N/m; 1 is the stiffest Bullet offers, so
//     its stretch here is its best case). Damping kDP = 0 (Bullet's default; its position
//     projection damps by itself), no drag, lift or self-collision;
//   - gravity (0, -9.81, 0) in the world and its btSoftBodyWorldInfo (weft's).
// Bullet runs on one thread (btSoftRigidDynamicsWorld's default solver is serial) and in
// single precision (Debian builds btScalar = float).
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <benchmark/benchmark.h>
#include <btBulletDynamicsCommon.h>

#include <memory>
#include <vector>

#include "patch_protocol.hpp"
#include "weft/weft.hpp"

namespace {

using weftbench::kPatchFrame;
using weftbench::kPatchSize;

class ClothWorld {
 public:
  ClothWorld(const weft::ModelAndState<double>& flag, int iterations) {
    config_ = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>();
    dispatcher_ = std::make_unique<btCollisionDispatcher>(config_.get());
    broadphase_ = std::make_unique<btDbvtBroadphase>();
    solver_ = std::make_unique<btSequentialImpulseConstraintSolver>();
    world_ =
        std::make_unique<btSoftRigidDynamicsWorld>(dispatcher_.get(), broadphase_.get(), solver_.get(), config_.get());
    const btVector3 gravity(0, btScalar(-9.81), 0);
    world_->setGravity(gravity);
    btSoftBodyWorldInfo& info = world_->getWorldInfo();
    info.m_gravity = gravity;
    info.m_sparsesdf.Initialize();

    const weft::Model<double>& model = flag.model;
    const weft::Index n = model.particleCount();
    std::vector<btVector3> x(static_cast<std::size_t>(n));
    std::vector<btScalar> m(static_cast<std::size_t>(n));
    for (weft::Index i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i);
      x[k] = btVector3(btScalar(flag.state.x(i, 0)), btScalar(flag.state.x(i, 1)), btScalar(flag.state.x(i, 2)));
      m[k] = model.isPinned(i) ? btScalar(0) : btScalar(model.mass()[i]);
    }
    body_ = std::make_unique<btSoftBody>(&info, static_cast<int>(n), x.data(), m.data());
    const weft::Springs<double>& springs = model.springs();
    for (weft::Index s = 0; s < springs.count(); ++s) body_->appendLink(springs.a[s], springs.b[s]);
    const weft::Triangles& t = model.triangles();
    for (weft::Index k = 0; k < t.count(); ++k) body_->appendFace(t.a[k], t.b[k], t.c[k]);
    body_->m_cfg.piterations = iterations;
    world_->addSoftBody(body_.get());
  }
  ~ClothWorld() { world_->removeSoftBody(body_.get()); }
  ClothWorld(const ClothWorld&) = delete;
  ClothWorld& operator=(const ClothWorld&) = delete;

  void step() { world_->stepSimulation(btScalar(kPatchFrame), 0); }
  const btSoftBody& body() const { return *body_; }

  /// Bullet's node positions, into a weft state of the flag (for weft::stretch).
  void positions(weft::State<double>& into) const {
    for (int i = 0; i < body_->m_nodes.size(); ++i)
      for (int c = 0; c < 3; ++c) into.x(i, c) = double(body_->m_nodes[i].m_x[c]);
  }

 private:
  std::unique_ptr<btSoftBodyRigidBodyCollisionConfiguration> config_;
  std::unique_ptr<btCollisionDispatcher> dispatcher_;
  std::unique_ptr<btDbvtBroadphase> broadphase_;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver_;
  std::unique_ptr<btSoftRigidDynamicsWorld> world_;
  std::unique_ptr<btSoftBody> body_;
};

void BM_Peer_Bullet_Cloth(benchmark::State& st) {
  const weft::ModelAndState<double> flag = weft::makeFlag<double>(kPatchSize);
  ClothWorld world(flag, static_cast<int>(st.range(0)));
  weft::State<double> seen = flag.state;
  weftbench::StretchSeries series;
  for (auto _ : st) {
    world.step();
    st.PauseTiming();
    world.positions(seen);
    series.add(weft::stretch(flag.model, seen));
    st.ResumeTiming();
  }
  series.report(st);
  st.counters["nodes"] = world.body().m_nodes.size();
  st.counters["links"] = world.body().m_links.size();
}

}  // namespace

BENCHMARK(BM_Peer_Bullet_Cloth)
    ->ArgName("piterations")
    ->Arg(1)
    ->Arg(4)
    ->Arg(10)
    ->Iterations(weftbench::kSpanFrames)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
