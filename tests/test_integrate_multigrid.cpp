// tests/test_integrate_multigrid.cpp — implicit Euler's aggregation multigrid
// preconditioner (kernel/src/integrate/aggregation_multigrid.cpp): the cycle is a
// symmetric positive definite operator whatever the model (grid, triangle mesh, rope, with
// pinned particles), it clusters A's spectrum far better than block-Jacobi, CG's
// iterations with it barely grow with the grid, and results are bitwise the same on 1 and
// 2 threads, and degenerate models (no springs, one particle, all pinned) step like
// block-Jacobi. Preconditioner::Auto (the default) is block-Jacobi bit for bit until a
// solve passes its threshold, then the multigrid at that step length unless the
// multigrid's first solve there costs more, on 1 and 2 threads and across checkpoints.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <string>
#include <vector>

#include "integrate/aggregation_multigrid.hpp"
#include "support/test_support.hpp"
#include "weft/weft.hpp"

using namespace weft;
using weft::test::addNoise;
using weft::test::flagOptions;

namespace {

struct Case {
  std::string name;
  ModelAndState<double> cloth;
};

std::vector<Case> cases() {
  std::vector<Case> out;
  out.push_back({"grid flag 12x12, top row pinned", makeFlag<double>(12)});
  // (no GridLayout: the multigrid aggregates by pairwise matching)
  out.push_back({"triangle mesh 10x10, two corners pinned", test::makeMeshSheets(10)});
  out.push_back({"rope of 30", makeRope<double>(30)});
  return out;
}

// Dense (3n x 3n) matrix of a linear map given by its action on basis vectors; rows and
// columns of pinned particles are left out (the CG's filter keeps dv = 0 there).
template <class Apply>
Eigen::MatrixXd denseOnFree(const Model<double>& model, Apply&& apply) {
  const Index n = model.particleCount();
  std::vector<Index> dof;
  for (Index i = 0; i < n; ++i)
    if (!model.isPinned(i))
      for (Index c = 0; c < 3; ++c) dof.push_back(3 * i + c);
  const auto m = static_cast<Index>(dof.size());
  Eigen::MatrixXd out(m, m);
  Vec3Array<double> e = Vec3Array<double>::Zero(n, 3), y(n, 3);
  for (Index k = 0; k < m; ++k) {
    e(dof[k] / 3, dof[k] % 3) = 1;
    apply(e, y);
    e(dof[k] / 3, dof[k] % 3) = 0;
    for (Index j = 0; j < m; ++j) out(j, k) = y(dof[j] / 3, dof[j] % 3);
  }
  return out;
}

double conditionNumber(const Eigen::VectorXd& eigenvalues) { return eigenvalues.maxCoeff() / eigenvalues.minCoeff(); }

// A residual to precondition: noise of unit size on the free particles, 0 on pinned ones.
Vec3Array<double> residualOnFree(const Model<double>& model, std::uint32_t seed) {
  Vec3Array<double> r = Vec3Array<double>::Zero(model.particleCount(), 3);
  addNoise<double>(r, 1.0, seed);
  for (Index i = 0; i < model.particleCount(); ++i)
    if (model.isPinned(i)) r.row(i).setZero();
  return r;
}

}  // namespace

TEST(AggregationMultigrid, IsSymmetricPositiveDefiniteAndClustersTheSpectrumOnEveryKindOfModel) {
  for (Case& c : cases()) {
    SCOPED_TRACE(c.name);
    const Model<double>& model = c.cloth.model;
    const Index n = model.particleCount();
    // A stretched, disturbed state at a large step: stiff springs in tension, h = 1/60 s.
    Vec3Array<double> x = c.cloth.state.x * 1.05;
    addNoise<double>(x, 0.003, 11);
    const Executor exec(1);
    SpringJacobian<double> jacobian(model);
    jacobian.linearize(x, 1.0 / 60, exec, 0.01);
    detail::AggregationMultigrid<double> multigrid(model);
    multigrid.prepare(jacobian, exec);
    EXPECT_GE(multigrid.levelCount(), 2);
    const std::vector<Index> sizes = multigrid.coarseSizes();
    ASSERT_FALSE(sizes.empty());
    EXPECT_LE(sizes.back(), detail::AggregationMultigrid<double>::kCoarsestNodes);

    const Eigen::MatrixXd A = denseOnFree(model, [&](const Vec3Array<double>& p, Vec3Array<double>& y) {
      auto store = [&](Index b, Index m, const double* yx, const double* yy, const double* yz) {
        for (Index t = 0; t < m; ++t) y.row(b + t) << yx[t], yy[t], yz[t];
      };
      jacobian.systemProduct(p, makeSink<double>(store), exec);
    });
    std::vector<double> partials(static_cast<size_t>(Executor::blockCount(n, ForceField<double>::kSinkBlock)));
    const Eigen::MatrixXd B = denseOnFree(model, [&](const Vec3Array<double>& r, Vec3Array<double>& z) {
      multigrid.apply(jacobian, r, z, partials, ForceField<double>::kSinkBlock, exec);
      for (Index i = 0; i < n; ++i) {
        if (model.isPinned(i)) {
          EXPECT_TRUE(z.row(i).isZero(0)) << "pinned particle " << i;
        }
      }
    });
    const double scale = B.cwiseAbs().maxCoeff();
    EXPECT_LE((B - B.transpose()).cwiseAbs().maxCoeff(), 1e-12 * scale) << "the cycle is not symmetric";
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ofB(B);
    EXPECT_GT(ofB.eigenvalues().minCoeff(), 0) << "the cycle is not positive definite";

    // The spectrum CG sees: B A (similar to L^T A L with B = L L^T), against block-Jacobi's.
    const Eigen::LLT<Eigen::MatrixXd> L(B);
    ASSERT_EQ(L.info(), Eigen::Success);
    const Eigen::MatrixXd Lm = L.matrixL();
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> preconditioned(Lm.transpose() * A * Lm);
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(A.rows(), A.cols());
    for (Index k = 0; k < A.rows(); k += 3) D.block(k, k, 3, 3) = A.block(k, k, 3, 3);
    const Eigen::LLT<Eigen::MatrixXd> Ld(D.inverse());
    const Eigen::MatrixXd Ldm = Ld.matrixL();
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> blockJacobi(Ldm.transpose() * A * Ldm);
    const double kappaMultigrid = conditionNumber(preconditioned.eigenvalues());
    const double kappaBlockJacobi = conditionNumber(blockJacobi.eigenvalues());
    EXPECT_GT(preconditioned.eigenvalues().minCoeff(), 0);
    // One cycle is a contraction: the eigenvalues of B A lie in (0, 2) (below 1 + the
    // over-correction's excess) and well away from 0.
    EXPECT_LT(preconditioned.eigenvalues().maxCoeff(), 2.0);
    EXPECT_LT(kappaMultigrid * 20, kappaBlockJacobi)
        << "condition number " << kappaMultigrid << " with multigrid, " << kappaBlockJacobi << " with block-Jacobi";
    std::cout << c.name << ": condition number of the preconditioned system " << kappaMultigrid << " (block-Jacobi "
              << kappaBlockJacobi << "), levels";
    for (const Index s : sizes) std::cout << ' ' << s;
    std::cout << '\n';
  }
}

TEST(AggregationMultigrid, CgIterationsBarelyGrowWithTheGridWhereBlockJacobisDouble) {
  // The flag at 1/60 s (omega_max h ~ 60 ... 240): mean CG iterations over steps 2 ... 6,
  // 24^2 against 48^2.
  auto iterations = [](Index size, Preconditioner p) {
    SimulationOptions options;
    options.integrator = IntegratorKind::ImplicitEuler;
    options.dt = 1.0 / 60;
    options.threads = 1;
    options.integration.preconditioner = p;
    Simulation<double> sim(makeFlag<double>(size), options);
    EXPECT_TRUE(sim.run(1).ok());
    Index total = 0;
    for (int s = 0; s < 5; ++s) {
      EXPECT_TRUE(sim.step().ok()) << sim.status().message();
      EXPECT_EQ(sim.lastWork().linearUnconverged, 0);
      total += sim.lastWork().linearIterations;
    }
    return static_cast<double>(total) / 5;
  };
  const double mg24 = iterations(24, Preconditioner::Multigrid), mg48 = iterations(48, Preconditioner::Multigrid);
  const double bj24 = iterations(24, Preconditioner::BlockJacobi), bj48 = iterations(48, Preconditioner::BlockJacobi);
  std::cout << "CG iterations per step, 24^2 / 48^2: multigrid " << mg24 << " / " << mg48 << ", block-Jacobi " << bj24
            << " / " << bj48 << '\n';
  EXPECT_LT(mg48 * 4, bj48);
  EXPECT_LT(mg48 / mg24, 1.4);
  EXPECT_GT(bj48 / bj24, 1.6);
}

TEST(AggregationMultigrid, TheCycleIsBitwiseTheSameOnOneAndTwoThreads) {
  // 64^2: the fine passes and the first coarse level (1,024 nodes) run in parallel blocks.
  ModelAndState<double> flag = makeFlag<double>(64);
  const Model<double>& model = flag.model;
  const Index n = model.particleCount();
  Vec3Array<double> x = flag.state.x * 1.05;
  addNoise<double>(x, 0.002, 3);
  const Vec3Array<double> r = residualOnFree(model, 4);
  Vec3Array<double> z[2];
  std::vector<double> partials[2];
  for (const int threads : {1, 2}) {
    const Executor exec(threads);
    SpringJacobian<double> jacobian(model);
    jacobian.linearize(x, 1.0 / 60, exec);
    detail::AggregationMultigrid<double> multigrid(model);
    multigrid.prepare(jacobian, exec);
    auto& out = z[threads - 1];
    out.resize(n, 3);
    partials[threads - 1].assign(static_cast<size_t>(Executor::blockCount(n, ForceField<double>::kSinkBlock)), 0.0);
    multigrid.apply(jacobian, r, out, partials[threads - 1], ForceField<double>::kSinkBlock, exec);
  }
  EXPECT_TRUE((z[0].array() == z[1].array()).all());
  EXPECT_EQ(partials[0], partials[1]);
  EXPECT_GT(std::accumulate(partials[0].begin(), partials[0].end(), 0.0), 0.0);  // r . B r > 0
  // Each partial is r . z over its block (summed in another order).
  const Index block = ForceField<double>::kSinkBlock;
  for (size_t k = 0; k < partials[0].size(); ++k) {
    const Index b = static_cast<Index>(k) * block, m = std::min(block, n - b);
    const auto terms = r.middleRows(b, m).array() * z[0].middleRows(b, m).array();
    EXPECT_NEAR(partials[0][k], terms.sum(), 1e-12 * terms.abs().sum()) << "block " << k;
  }
}

TEST(AggregationMultigrid, TheGridStencilProductAgreesWithTheGeneralOne) {
  // A 37 x 45 grid (odd and even sides) with its top row and a patch inside pinned, so grid
  // levels have empty slots inside as well as around: cycled with the stencil product on
  // its grid levels and with the general edge product everywhere, the same preconditioner
  // up to rounding.
  ClothGridSpec spec;
  spec.width = 37;
  spec.height = 45;
  spec.spacing = 0.02;
  ModelBuilder<double> builder;
  addClothGrid(builder, spec);
  for (Index c = 0; c < spec.width; ++c) builder.pin(gridIndex(spec, 0, c));
  for (Index r = 17; r < 24; ++r)
    for (Index c = 9; c < 16; ++c) builder.pin(gridIndex(spec, r, c));
  ModelAndState<double> cloth = builder.build();
  const Model<double>& model = cloth.model;
  ASSERT_TRUE(model.grid().has_value());
  const Index n = model.particleCount();
  Vec3Array<double> x = cloth.state.x * 1.04;
  addNoise<double>(x, 0.002, 5);
  const Vec3Array<double> r = residualOnFree(model, 6);
  const Executor exec(2);
  SpringJacobian<double> jacobian(model);
  jacobian.linearize(x, 1.0 / 60, exec, 0.02);
  Vec3Array<double> z[2];
  for (const bool stencil : {true, false}) {
    detail::AggregationMultigrid<double> multigrid(model, stencil);
    EXPECT_EQ(multigrid.stencilLevelCount() > 0, stencil);
    if (stencil) {
      EXPECT_EQ(multigrid.stencilLevelCount(), multigrid.levelCount() - 1);
    }
    multigrid.prepare(jacobian, exec);
    std::vector<double> partials(static_cast<size_t>(Executor::blockCount(n, ForceField<double>::kSinkBlock)));
    z[stencil ? 0 : 1].resize(n, 3);
    multigrid.apply(jacobian, r, z[stencil ? 0 : 1], partials, ForceField<double>::kSinkBlock, exec);
  }
  const double scale = z[1].cwiseAbs().maxCoeff();
  ASSERT_GT(scale, 0);
  EXPECT_LE((z[0] - z[1]).cwiseAbs().maxCoeff(), 1e-12 * scale);
}

TEST(AggregationMultigrid, DegenerateModelsStepLikeBlockJacobi) {
  // No springs; one particle; every particle pinned; a duplicated spring: multigrid steps
  // them all and agrees with block-Jacobi.
  std::vector<std::pair<std::string, ModelAndState<double>>> models;
  {
    ModelBuilder<double> b;
    for (int i = 0; i < 5; ++i) b.addParticle(Vec3d(0.1 * i, 0, 0), 0.01);
    models.emplace_back("no springs", b.build());
  }
  {
    ModelBuilder<double> b;
    b.addParticle(Vec3d(0, 0, 0), 0.01);
    models.emplace_back("one particle", b.build());
  }
  {
    ModelAndState<double> flag = makeFlag<double>(6);
    ModelBuilder<double> b;
    for (Index i = 0; i < flag.model.particleCount(); ++i)
      b.addParticle(Vec3d(flag.state.x(i, 0), flag.state.x(i, 1), flag.state.x(i, 2)), flag.model.mass()[i]);
    for (Index s = 0; s < flag.model.springCount(); ++s)
      b.addSpring(flag.model.springs().a[s], flag.model.springs().b[s], SpringMaterial{500, 0.1});
    for (Index i = 0; i < flag.model.particleCount(); ++i) b.pin(i);
    models.emplace_back("all pinned", b.build());
  }
  {
    ModelBuilder<double> b;
    for (int i = 0; i < 6; ++i) b.addParticle(Vec3d(0.1 * i, 0, 0), 0.01);
    b.pin(0);
    for (int i = 0; i + 1 < 6; ++i) b.addSpring(i, i + 1, SpringMaterial{2000, 0.1});
    b.addSpring(2, 3, SpringMaterial{2000, 0.1});  // duplicated
    models.emplace_back("rope with a duplicated spring", b.build());
  }
  for (auto& [name, built] : models) {
    SCOPED_TRACE(name);
    State<double> end[2];
    for (const Preconditioner p : {Preconditioner::BlockJacobi, Preconditioner::Multigrid}) {
      SimulationOptions options;
      options.integrator = IntegratorKind::ImplicitEuler;
      options.dt = 1.0 / 60;
      options.integration.preconditioner = p;
      options.integration.linearTolerance = 1e-10;
      Simulation<double> sim(ModelAndState<double>{built.model, built.state}, options);
      ASSERT_TRUE(sim.run(10).ok()) << sim.status().message();
      EXPECT_EQ(sim.totalWork().linearUnconverged, 0);
      end[p == Preconditioner::Multigrid] = sim.state();
    }
    EXPECT_LT((end[0].x - end[1].x).cwiseAbs().maxCoeff(), 1e-8);
  }
}

// Preconditioner::Auto (the default): block-Jacobi, and the multigrid for steps at least as
// long as the shortest whose block-Jacobi solve took more than the threshold (at first
// kAutoMultigridIterations) or stopped at the cap, unless the multigrid's first solve at
// that length costs more than that block-Jacobi solve (a multigrid iteration counted as
// 4.7 block-Jacobi iterations, its levels as 2): then back, with the threshold at 1.25
// times that cost.

namespace {

SimulationOptions implicitFlagOptions(Preconditioner p, int threads, double dt) {
  SimulationOptions options = flagOptions(IntegratorKind::ImplicitEuler, ForceStrategy::Auto, threads, dt);
  options.integration.preconditioner = p;
  return options;
}

}  // namespace

TEST(AutoPreconditioner, IsBlockJacobiUntilASolveTakesMoreThanTheThresholdThenTheMultigridAtThatStep) {
  // The 32^2 flag at 1/60 s: block-Jacobi's solves grow past the threshold within a few
  // steps (about 120 iterations a step later on); the multigrid's stay near 20.
  const ModelAndState<double> flag = makeFlag<double>(32);
  Simulation<double> automatic(ModelAndState<double>{flag.model, flag.state},
                               implicitFlagOptions(Preconditioner::Auto, 1, 1.0 / 60));
  Simulation<double> blockJacobi(ModelAndState<double>{flag.model, flag.state},
                                 implicitFlagOptions(Preconditioner::BlockJacobi, 1, 1.0 / 60));
  int switched = -1;  // the step after which auto moved to the multigrid
  for (int step = 0; step < 12; ++step) {
    SCOPED_TRACE(::testing::Message() << "step " << step);
    ASSERT_TRUE(automatic.step().ok()) << automatic.status().message();
    const StepWork& work = automatic.lastWork();
    EXPECT_LE(work.linearResidual, automatic.options().integration.linearTolerance);
    if (switched < 0) {
      // Until then, auto is block-Jacobi bit for bit.
      ASSERT_TRUE(blockJacobi.step().ok());
      EXPECT_EQ(work.multigridSolves, 0);
      EXPECT_EQ(stateHash(automatic.state()), stateHash(blockJacobi.state()));
      EXPECT_EQ(work.linearIterations, blockJacobi.lastWork().linearIterations);
      if (work.linearIterations > kAutoMultigridIterations) switched = step;
    } else {
      EXPECT_EQ(work.multigridSolves, 1);
      EXPECT_LT(work.linearIterations, kAutoMultigridIterations);
    }
  }
  ASSERT_GE(switched, 0) << "block-Jacobi never took more than " << kAutoMultigridIterations << " iterations";
  EXPECT_LT(switched, 6);
  EXPECT_EQ(automatic.totalWork().multigridSolves, 11 - switched);
  // A new state keeps the choice: it belongs to the model and the step, not the state.
  automatic.setState(State<double>{flag.state});
  ASSERT_TRUE(automatic.step().ok());
  EXPECT_EQ(automatic.lastWork().multigridSolves, 1);
  // A shorter step is block-Jacobi's again while its solves stay short (about 11 iterations
  // at 1/600 s), and the step that passed the threshold is the multigrid's again.
  automatic.setTimeStep(1.0 / 600);
  for (int step = 0; step < 10; ++step) {
    ASSERT_TRUE(automatic.step().ok());
    EXPECT_EQ(automatic.lastWork().multigridSolves, 0) << "step " << step << " at 1/600 s";
    EXPECT_LE(automatic.lastWork().linearIterations, kAutoMultigridIterations);
  }
  automatic.setTimeStep(1.0 / 60);
  ASSERT_TRUE(automatic.step().ok());
  EXPECT_EQ(automatic.lastWork().multigridSolves, 1);
}

TEST(AutoPreconditioner, AMultigridSolveCostlierThanBlockJacobisHandsTheStepsBack) {
  // The 16^2 flag at 0.01 s and CG 1e-8: block-Jacobi's second solve takes about 60
  // iterations, sending the step to the multigrid, whose solve then costs more (4.7 block-
  // Jacobi iterations each, 2 for its levels): the steps go back to block-Jacobi, and the
  // threshold rises above that cost, so they stay there.
  SimulationOptions options = implicitFlagOptions(Preconditioner::Auto, 1, 0.01);
  options.integration.linearTolerance = 1e-8;
  Simulation<double> sim(makeFlag<double>(16), options);
  ASSERT_TRUE(sim.step().ok());
  ASSERT_TRUE(sim.step().ok());
  const Index trigger = sim.lastWork().linearIterations;
  ASSERT_GT(trigger, kAutoMultigridIterations);
  EXPECT_EQ(sim.lastWork().multigridSolves, 0);
  // A checkpoint between the block-Jacobi solve and the multigrid's judged one: the resumed
  // run judges it against the same count.
  Simulation<double> fromTheTrigger(makeFlag<double>(16), options);
  fromTheTrigger.restore(sim.checkpoint(), "after the trigger");
  ASSERT_TRUE(sim.step().ok());
  EXPECT_EQ(sim.lastWork().multigridSolves, 1);
  const double cost = 4.7 * static_cast<double>(sim.lastWork().linearIterations) + 2;
  EXPECT_GE(cost, static_cast<double>(trigger));
  for (int step = 0; step < 10; ++step) {
    ASSERT_TRUE(sim.step().ok());
    EXPECT_EQ(sim.lastWork().multigridSolves, 0) << "step " << step;
    EXPECT_LT(static_cast<double>(sim.lastWork().linearIterations), 1.25 * cost);
  }
  // A checkpoint keeps the raised threshold: a resumed run stays with block-Jacobi too.
  const std::string bytes = sim.checkpoint();
  Simulation<double> resumed(makeFlag<double>(16), options);
  resumed.restore(bytes, "after the hand-back");
  ASSERT_TRUE(sim.run(5).ok());
  ASSERT_TRUE(resumed.run(5).ok());
  EXPECT_EQ(stateHash(resumed.state()), stateHash(sim.state()));
  EXPECT_EQ(resumed.totalWork().multigridSolves, sim.totalWork().multigridSolves);
  ASSERT_TRUE(fromTheTrigger.run(static_cast<Index>(sim.stepCount() - fromTheTrigger.stepCount())).ok());
  EXPECT_EQ(stateHash(fromTheTrigger.state()), stateHash(sim.state()));
  EXPECT_EQ(fromTheTrigger.totalWork().multigridSolves, sim.totalWork().multigridSolves);
}

TEST(AutoPreconditioner, ASolveStoppedAtTheCapHandsItsStepToTheMultigrid) {
  // With a cap of 20 iterations, block-Jacobi's solves on the 32^2 flag at 1/60 s stop at
  // the cap (none takes more than 40): the step goes to the multigrid for good, whatever
  // its solves cost (no multigrid solve costs more than an unfinished one).
  SimulationOptions options = implicitFlagOptions(Preconditioner::Auto, 1, 1.0 / 60);
  options.integration.maxLinearIterations = 20;
  Simulation<double> sim(makeFlag<double>(32), options);
  ASSERT_TRUE(sim.step().ok());  // (free fall: one iteration)
  ASSERT_TRUE(sim.step().ok());
  EXPECT_EQ(sim.lastWork().multigridSolves, 0);
  EXPECT_EQ(sim.lastWork().linearUnconverged, 1);
  for (int step = 0; step < 5; ++step) {
    ASSERT_TRUE(sim.step().ok());
    EXPECT_EQ(sim.lastWork().multigridSolves, 1);
  }
  EXPECT_EQ(sim.totalWork().multigridSolves, 5);
}

TEST(AutoPreconditioner, StaysBlockJacobiWhereItsSolvesAreShort) {
  // The 16^2 flag at 1/600 s: about 11 block-Jacobi iterations a step, where the multigrid
  // takes 2.2x the time (docs/integrators.md). Bitwise block-Jacobi's run.
  const ModelAndState<double> flag = makeFlag<double>(16);
  std::uint64_t hash[2];
  for (const Preconditioner p : {Preconditioner::Auto, Preconditioner::BlockJacobi}) {
    Simulation<double> sim(ModelAndState<double>{flag.model, flag.state}, implicitFlagOptions(p, 2, 1.0 / 600));
    Index most = 0;
    for (int step = 0; step < 100; ++step) {
      ASSERT_TRUE(sim.step().ok()) << sim.status().message();
      most = std::max(most, sim.lastWork().linearIterations);
    }
    EXPECT_LE(most, kAutoMultigridIterations);
    EXPECT_EQ(sim.totalWork().multigridSolves, 0);
    hash[p == Preconditioner::Auto ? 0 : 1] = stateHash(sim.state());
  }
  EXPECT_EQ(hash[0], hash[1]);
}

TEST(AutoPreconditioner, TheSameOnOneAndTwoThreadsAndResumedFromACheckpointOnEitherSideOfTheSwitch) {
  // (Double: its first step, free fall from the flat cloth, takes one iteration, so step 1
  // is before the switch. In float rounding makes it 68, and auto switches after it.)
  const ModelAndState<double> flag = makeFlag<double>(32);
  const auto make = [&](int threads) {
    return Simulation<double>(ModelAndState<double>{flag.model, flag.state},
                              implicitFlagOptions(Preconditioner::Auto, threads, 1.0 / 60));
  };
  Simulation<double> two = make(2), one = make(1);
  std::string before, after;  // checkpoints at step 1 (block-Jacobi) and 8 (the multigrid)
  for (int step = 1; step <= 14; ++step) {
    ASSERT_TRUE(two.step().ok()) << two.status().message();
    ASSERT_TRUE(one.step().ok()) << one.status().message();
    ASSERT_EQ(stateHash(two.state()), stateHash(one.state())) << "step " << step;
    if (step == 1) before = two.checkpoint();
    if (step == 8) {
      ASSERT_GT(two.totalWork().multigridSolves, 0) << "the switch comes before step 8";
      after = two.checkpoint();
    }
  }
  ASSERT_EQ(two.totalWork().multigridSolves, one.totalWork().multigridSolves);
  ASSERT_GT(two.totalWork().multigridSolves, 0);
  ASSERT_LT(two.totalWork().multigridSolves, 13) << "the switch comes after step 1";
  for (const std::string* bytes : {&before, &after}) {
    Simulation<double> resumed = make(1);
    resumed.restore(*bytes, bytes == &before ? "at step 1" : "at step 8");
    ASSERT_TRUE(resumed.run(static_cast<Index>(14 - resumed.stepCount())).ok());
    EXPECT_EQ(stateHash(resumed.state()), stateHash(two.state())) << (bytes == &before ? "from step 1" : "from step 8");
  }
}
