// tests/test_integrate_laplacian.cpp — the prefactored solve with the springs' scalar matrix
// (kernel/src/integrate/spring_laplacian_solver.cpp), projective dynamics' global step and
// implicit Euler's projective preconditioner: its two-task triangular solves with the
// factor's entries in float give P^-1 b to ~1e-6, and corrections with them converge to it
// (checked against the matrix assembled here from the model), on grids, triangle meshes,
// ropes, pinned and disconnected models, bitwise the same on 1 and 2 threads and with 16-
// or 32-bit row indices; a grid's
// columns split into two balanced tasks with a small separator, two separate cloths into
// one task each.
#include <gtest/gtest.h>

#include <Eigen/SparseCore>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "integrate/spring_laplacian_solver.hpp"
#include "support/test_support.hpp"
#include "weft/weft.hpp"

using namespace weft;

namespace {

struct Case {
  std::string name;
  ModelAndState<double> cloth;
};

// Two ropes that share no spring: a forest with two trees (and a third, the pinned
// particle's own one-node tree).
ModelAndState<double> twoRopes(Index k) {
  ModelBuilder<double> b;
  for (Index r = 0; r < 2; ++r) {
    const Index first = b.particleCount();
    for (Index i = 0; i < k; ++i) b.addParticle(Vec3d(0.1 * static_cast<double>(i), static_cast<double>(r), 0), 0.01);
    for (Index i = 0; i + 1 < k; ++i) b.addSpring(first + i, first + i + 1, SpringMaterial{500, 0.02});
  }
  b.pin(0);
  return b.build();
}

std::vector<Case> cases() {
  std::vector<Case> out;
  out.push_back({"grid flag 40x40", makeFlag<double>(40)});
  out.push_back({"triangle mesh 17x17", test::makeMeshSheets(17)});
  out.push_back({"rope of 50", makeRope<double>(50)});
  out.push_back({"two ropes, one pinned end", twoRopes(25)});
  out.push_back({"two triangle meshes 30x30", test::makeMeshSheets(30, 2)});
  out.push_back({"grid flag 64x64 (two tasks)", makeFlag<double>(64)});
  return out;
}

// P = M + h c I + sum_s (theta h^2 ks + h kd) L_s on free rows, identity on pinned ones,
// assembled independently of the solver.
Eigen::SparseMatrix<double> assembled(const Model<double>& model, double theta, double h, double drag) {
  const Index n = model.particleCount();
  std::vector<Eigen::Triplet<double>> entries;
  for (Index i = 0; i < n; ++i) entries.emplace_back(i, i, model.isPinned(i) ? 1.0 : model.mass()[i] + h * drag);
  const Springs<double>& sp = model.springs();
  for (Index s = 0; s < sp.count(); ++s) {
    const Index a = sp.a[s], b = sp.b[s];
    const double k = theta * h * h * sp.stiffness[s] + h * sp.damping[s];
    if (!model.isPinned(a)) entries.emplace_back(a, a, k);
    if (!model.isPinned(b)) entries.emplace_back(b, b, k);
    if (!model.isPinned(a) && !model.isPinned(b)) {
      entries.emplace_back(a, b, -k);
      entries.emplace_back(b, a, -k);
    }
  }
  Eigen::SparseMatrix<double> P(n, n);
  P.setFromTriplets(entries.begin(), entries.end());
  return P;
}

// The solver's answer to P x = rhs (rhs: n x 3), through its own buffer.
Eigen::MatrixXd solveWith(detail::SpringLaplacianSolver<double>& solver, const Eigen::MatrixXd& rhs,
                          const Executor& exec) {
  const Index n = rhs.rows();
  for (Index i = 0; i < n; ++i)
    for (Index c = 0; c < 3; ++c) solver.buffer()[solver.offset(i) + c] = rhs(i, c);
  solver.solveBuffer(exec);
  Eigen::MatrixXd x(n, 3);
  for (Index i = 0; i < n; ++i)
    for (Index c = 0; c < 3; ++c) x(i, c) = solver.buffer()[solver.offset(i) + c];
  return x;
}

}  // namespace

TEST(SpringLaplacianSolver, SolvesTheAssembledMatrixOnEveryKindOfModel) {
  for (const Case& test : cases()) {
    SCOPED_TRACE(test.name);
    const Model<double>& model = test.cloth.model;
    const Index n = model.particleCount();
    for (const auto& [h, drag] : {std::pair{1.0 / 60, 0.0}, std::pair{1.0 / 600, 0.0}, std::pair{1.0 / 60, 0.3}}) {
      SCOPED_TRACE(drag);
      detail::SpringLaplacianSolver<double> solver(model, 1.0, "test");
      solver.prepare(h, drag);
      const Eigen::MatrixXd rhs = Eigen::MatrixXd::Random(n, 3);
      const Executor exec(2);
      const Eigen::SparseMatrix<double> P = assembled(model, 1.0, h, drag);
      Eigen::MatrixXd x = solveWith(solver, rhs, exec);
      // The factor's entries are floats: one solve leaves ~1e-6 of the right-hand side...
      const double scale = rhs.cwiseAbs().maxCoeff();
      EXPECT_LT((P * x - rhs).cwiseAbs().maxCoeff(), 1e-5 * scale) << "h = " << h;
      // ...and each correction with the same solve takes off about as much again.
      for (int refinement = 0; refinement < 3; ++refinement) x += solveWith(solver, rhs - P * x, exec);
      EXPECT_LT((P * x - rhs).cwiseAbs().maxCoeff(), 1e-11 * scale) << "h = " << h;
      // What peers are given to factorise (the benchmarks against CHOLMOD): P's lower triangle.
      const Eigen::SparseMatrix<double> lower = P.triangularView<Eigen::Lower>();
      EXPECT_LT((solver.matrix(h, drag) - lower).cwiseAbs().sum(), 1e-12 * P.cwiseAbs().sum()) << "h = " << h;
    }
  }
}

TEST(SpringLaplacianSolver, IsBitwiseTheSameOnOneAndTwoThreads) {
  for (const Case& test : cases()) {
    SCOPED_TRACE(test.name);
    const Model<double>& model = test.cloth.model;
    detail::SpringLaplacianSolver<double> solver(model, 0.5, "test");
    solver.prepare(1.0 / 100, 0.0);
    const Eigen::MatrixXd rhs = Eigen::MatrixXd::Random(model.particleCount(), 3);
    const Executor one(1), two(2);
    const Eigen::MatrixXd x1 = solveWith(solver, rhs, one);
    const Eigen::MatrixXd residual = assembled(model, 0.5, 1.0 / 100, 0.0) * x1 - rhs;
    EXPECT_LT(residual.cwiseAbs().maxCoeff(), 1e-5 * rhs.cwiseAbs().maxCoeff());
    for (int run = 0; run < 5; ++run) {
      const Eigen::MatrixXd x2 = solveWith(solver, rhs, two);
      ASSERT_EQ(0, std::memcmp(x1.data(), x2.data(), sizeof(double) * static_cast<size_t>(x1.size())));
    }
    for (Index i = 0; i < model.particleCount(); ++i)  // each row's fourth entry is a pad
      ASSERT_EQ(solver.buffer()[solver.offset(i) + 3], 0.0);
  }
}

// Up to 65536 particles the factor's row indices take 16 bits; beyond, 32. Both must give
// the same bits (the same entries summed in the same order), the 16-bit factor 2 bytes an
// entry fewer in each copy.
TEST(SpringLaplacianSolver, SixteenAndThirtyTwoBitIndicesGiveTheSameBits) {
  std::vector<Case> models = cases();
  // Ropes at the limit (indices up to 65535, beyond int16's range) and one past it (32-bit
  // indices by themselves); their factors are small.
  models.push_back({"rope of 65536", makeRope<double>(65536)});
  models.push_back({"rope of 65537", makeRope<double>(65537)});
  for (const Case& test : models) {
    SCOPED_TRACE(test.name);
    const Model<double>& model = test.cloth.model;
    detail::SpringLaplacianSolver<double> automatic(model, 1.0, "test"), wide(model, 1.0, "test", true);
    automatic.prepare(1.0 / 60, 0.1);
    wide.prepare(1.0 / 60, 0.1);
    ASSERT_EQ(automatic.factorEntries(), wide.factorEntries());
    ASSERT_EQ(automatic.split(), wide.split());
    // Each of the two copies saves 2 bytes an entry with 16-bit indices.
    const std::size_t saved = model.particleCount() > 65536 ? 0 : 4 * static_cast<std::size_t>(wide.factorEntries());
    EXPECT_EQ(automatic.factorBytes() + saved, wide.factorBytes());
    const Eigen::MatrixXd rhs = Eigen::MatrixXd::Random(model.particleCount(), 3);
    const Executor two(2);
    const Eigen::MatrixXd a = solveWith(automatic, rhs, two), b = solveWith(wide, rhs, two);
    ASSERT_EQ(0, std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())));
    const Eigen::MatrixXd residual = assembled(model, 1.0, 1.0 / 60, 0.1) * a - rhs;
    EXPECT_LT(residual.cwiseAbs().maxCoeff(), 1e-5 * rhs.cwiseAbs().maxCoeff());
  }
}

TEST(SpringLaplacianSolver, SplitsAGridIntoTwoBalancedTasksAndASmallSeparator) {
  const ModelAndState<double> flag = makeFlag<double>(64);
  detail::SpringLaplacianSolver<double> solver(flag.model, 1.0, "test");
  solver.prepare(1.0 / 60, 0.0);
  const Index n = flag.model.particleCount();
  const auto split = solver.split();
  const Index first = split[0], second = split[1] - split[0], top = n - split[1];
  EXPECT_GT(first, n * 2 / 5) << first << " + " << second << " + " << top;
  EXPECT_GT(second, n * 2 / 5) << first << " + " << second << " + " << top;
  EXPECT_LT(top, n / 10) << first << " + " << second << " + " << top;
  EXPECT_GT(top, 0);  // one connected cloth: cut through
}

TEST(SpringLaplacianSolver, GivesTwoSeparateClothsOneTaskEachWithoutASeparator) {
  const ModelAndState<double> two = test::makeMeshSheets(40, 2);
  detail::SpringLaplacianSolver<double> solver(two.model, 1.0, "test");
  solver.prepare(1.0 / 60, 0.0);
  const Index n = two.model.particleCount();
  const auto split = solver.split();
  // one cloth a side (its four pinned particles, each a component of its own, go where
  // they balance), no separator
  EXPECT_NEAR(static_cast<double>(split[0]), static_cast<double>(n / 2), 4.0);
  EXPECT_EQ(split[1], n);
}

TEST(SpringLaplacianSolver, SmallModelsRunAsOneTask) {
  const ModelAndState<double> rope = makeRope<double>(50);
  detail::SpringLaplacianSolver<double> solver(rope.model, 1.0, "test");
  solver.prepare(1.0 / 60, 0.0);
  EXPECT_EQ(solver.split()[1], 0);
}

TEST(SpringLaplacianSolver, ModelsWithoutSpringsOrParticlesSolve) {
  ModelBuilder<double> b;
  b.addParticle(Vec3d(0, 0, 0), 2.0);
  b.addParticle(Vec3d(1, 0, 0), 0.5);
  b.pin(1);
  const ModelAndState<double> lonely = b.build();
  detail::SpringLaplacianSolver<double> solver(lonely.model, 1.0, "test");
  solver.prepare(0.01, 0.0);
  Eigen::MatrixXd rhs(2, 3);
  rhs << 2, 4, 6, 1, 2, 3;
  const Eigen::MatrixXd x = solveWith(solver, rhs, Executor(2));
  EXPECT_DOUBLE_EQ(x(0, 0), 1.0);
  EXPECT_DOUBLE_EQ(x(0, 2), 3.0);
  EXPECT_DOUBLE_EQ(x(1, 1), 2.0);
  ModelBuilder<double> single;
  single.addParticle(Vec3d(0, 0, 0), 0.25);
  const ModelAndState<double> one = single.build();
  detail::SpringLaplacianSolver<double> alone(one.model, 1.0, "test");
  alone.prepare(0.01, 2.0);  // P = m + h c = 0.27
  Eigen::MatrixXd b1(1, 3);
  b1 << 0.27, -0.54, 0.0;
  const Eigen::MatrixXd x1 = solveWith(alone, b1, Executor(2));
  EXPECT_NEAR(x1(0, 0), 1.0, 1e-15);
  EXPECT_NEAR(x1(0, 1), -2.0, 1e-15);
  EXPECT_EQ(x1(0, 2), 0.0);
  const ModelAndState<double> empty = ModelBuilder<double>().build();
  detail::SpringLaplacianSolver<double> none(empty.model, 1.0, "test");
  none.prepare(0.01, 0.0);
  none.solveBuffer(Executor(2));
  EXPECT_EQ(none.split()[1], 0);
}
