// Peer benchmark (optional, built when CHOLMOD is found: WEFT_PEERS=1 bash tools/setup.sh
// installs Debian's libsuitesparse-dev, SuiteSparse 5.12, CHOLMOD 3.0): projective
// dynamics' global matrix P of the size² flag at dt = 1/60 (the matrix weft's own solver
// factorises, SpringLaplacianSolver::matrix), factorised and solved by CHOLMOD, timed in the
// same binary as BM_Projective_Solve and BM_Projective_Factor (bench_integrators.cpp).
//
//   BM_Peer_Cholmod_Solve/size:N/ordering:O/supernodal:K
//       one solve P X = B with the three coordinates as three columns (cholmod_solve2, its
//       workspace reused: nothing allocated after the first call). O = 0: CHOLMOD's own
//       ordering (its default: AMD, and METIS where AMD's fill is high); O = 1: weft's
//       (nested dissection + AMD, which CHOLMOD postorders as it does its own: the same
//       fill, supernodes as large as the tree allows); O = 2: METIS's nested dissection
//       (Debian's CHOLMOD links METIS 5), O = 3: CHOLMOD's own nested dissection (NESDIS),
//       both postordered: how much fill a better ordering than weft's would save (the
//       solve's cost is proportional to it). K = 0: simplicial LDL^T
//       (what Eigen's SimplicialLDLT and weft store); K = 1: supernodal LL^T (dense blocks
//       through the BLAS Debian links, reference BLAS unless OpenBLAS is installed).
//   BM_Peer_Cholmod_Factor/size:N/ordering:O/supernodal:K
//       one numeric factorisation (cholmod_factorize) with the analysis kept, what a new
//       time step costs (weft's BM_Projective_Factor also assembles and permutes P and
//       analyses its pattern each time: it times all of prepare()).
// Counters: factor_entries (strictly below the diagonal, weft's factorEntries() counts the
// same; for the supernodal factor the entries of the ideal pattern, not the explicit
// zeros its blocks store besides), allocs_per_solve (operator new only; CHOLMOD allocates
// through malloc), and for
// the solve max_difference_vs_weft, the largest difference from weft's solve of the same
// right-hand side relative to the largest coordinate of the solution (weft keeps its
// factor's entries in float: ~1e-6 expected).
// Run it with OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 to compare one thread with one
// thread: Debian's CHOLMOD is built with OpenMP (parts of its supernodal factorisation)
// and OpenBLAS threads its BLAS calls; the simplicial code is serial.
#include <benchmark/benchmark.h>
#include <suitesparse/cholmod.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_common.hpp"
#include "integrate/spring_laplacian_solver.hpp"
#include "weft/weft.hpp"

namespace {

constexpr double kStep = 1.0 / 60;

// P of the flag, CHOLMOD's factor of it and a right-hand side (the flag's positions).
class CholmodSystem {
 public:
  CholmodSystem(weft::Index size, int ordering, bool supernodal)
      : flag_(weft::makeFlag<double>(size)), solver_(flag_.model, 1.0, "BM_Peer_Cholmod") {
    cholmod_start(&common_);
    common_.supernodal = supernodal ? CHOLMOD_SUPERNODAL : CHOLMOD_SIMPLICIAL;
    common_.final_ll = supernodal ? 1 : 0;                             // simplicial: keep LDL^T, as weft does
    const Eigen::SparseMatrix<double> p = solver_.matrix(kStep, 0.0);  // lower triangle, compressed
    n_ = static_cast<std::size_t>(p.rows());
    A_ = cholmod_allocate_sparse(n_, n_, static_cast<std::size_t>(p.nonZeros()), 1, 1, -1, CHOLMOD_REAL, &common_);
    if (A_ == nullptr) {
      release();
      throw std::runtime_error("CHOLMOD could not allocate the flag's P");
    }
    auto* columns = static_cast<int*>(A_->p);
    auto* rows = static_cast<int*>(A_->i);
    auto* values = static_cast<double*>(A_->x);
    for (Eigen::Index j = 0; j <= p.cols(); ++j) columns[j] = p.outerIndexPtr()[j];
    std::copy(p.innerIndexPtr(), p.innerIndexPtr() + p.nonZeros(), rows);
    std::copy(p.valuePtr(), p.valuePtr() + p.nonZeros(), values);
    const bool weftOrdering = ordering == 1;
    if (ordering >= 2) {
      common_.nmethods = 1;
      common_.method[0].ordering = ordering == 2 ? CHOLMOD_METIS : CHOLMOD_NESDIS;
      common_.postorder = 1;
      L_ = cholmod_analyze(A_, &common_);
    } else if (weftOrdering) {
      std::vector<int> order(n_);  // order[k] = the particle in row k
      for (std::size_t i = 0; i < n_; ++i)
        order[static_cast<std::size_t>(solver_.positions()[i])] = static_cast<int>(i);
      common_.nmethods = 1;
      common_.method[0].ordering = CHOLMOD_GIVEN;
      L_ = cholmod_analyze_p(A_, order.data(), nullptr, 0, &common_);
    } else {
      L_ = cholmod_analyze(A_, &common_);
    }
    if (L_ == nullptr || !factorize()) {
      release();
      throw std::runtime_error("CHOLMOD could not factorise the flag's P");
    }
    // Entries strictly below the diagonal: lnz counts L's nonzeros with the diagonal.
    factorEntries_ = common_.lnz - static_cast<double>(n_);
    B_ = cholmod_allocate_dense(n_, 3, n_, CHOLMOD_REAL, &common_);
    if (B_ == nullptr) {
      release();
      throw std::runtime_error("CHOLMOD could not allocate the right-hand side");
    }
    auto* b = static_cast<double*>(B_->x);
    for (std::size_t i = 0; i < n_; ++i)
      for (std::size_t c = 0; c < 3; ++c)
        b[c * n_ + i] = flag_.state.x(static_cast<weft::Index>(i), static_cast<weft::Index>(c));
  }
  ~CholmodSystem() { release(); }
  CholmodSystem(const CholmodSystem&) = delete;
  CholmodSystem& operator=(const CholmodSystem&) = delete;

  bool factorize() { return cholmod_factorize(A_, L_, &common_) != 0 && common_.status == CHOLMOD_OK; }
  bool solve() { return cholmod_solve2(CHOLMOD_A, L_, B_, nullptr, &X_, nullptr, &Y_, &E_, &common_) != 0; }
  double factorEntries() const { return factorEntries_; }
  const char* orderingName() const {
    switch (common_.method[common_.selected].ordering) {
      case CHOLMOD_GIVEN:
        return "weft's ordering";
      case CHOLMOD_AMD:
        return "CHOLMOD: AMD";
      case CHOLMOD_METIS:
        return "CHOLMOD: METIS";
      case CHOLMOD_NESDIS:
        return "CHOLMOD: NESDIS";
      default:
        return "CHOLMOD: other";
    }
  }

  // The largest difference of X from weft's solve of the same right-hand side, relative to
  // X's largest coordinate.
  double differenceFromWeft() {
    const weft::Executor exec(1);
    solver_.prepare(kStep, 0.0);
    const auto* b = static_cast<const double*>(B_->x);
    for (std::size_t i = 0; i < n_; ++i)
      for (std::size_t c = 0; c < 3; ++c)
        solver_.buffer()[solver_.offset(static_cast<weft::Index>(i)) + static_cast<weft::Index>(c)] = b[c * n_ + i];
    solver_.solveBuffer(exec);
    const auto* x = static_cast<const double*>(X_->x);
    double largest = 0, difference = 0;
    for (std::size_t i = 0; i < n_; ++i)
      for (std::size_t c = 0; c < 3; ++c) {
        const double ours = solver_.buffer()[solver_.offset(static_cast<weft::Index>(i)) + static_cast<weft::Index>(c)];
        largest = std::max(largest, std::abs(x[c * n_ + i]));
        difference = std::max(difference, std::abs(x[c * n_ + i] - ours));
      }
    return difference / largest;
  }

 private:
  // Frees whatever was allocated (the cholmod_free_* calls accept null) and CHOLMOD's
  // workspace; once only.
  void release() {
    if (released_) return;
    released_ = true;
    cholmod_free_dense(&X_, &common_);
    cholmod_free_dense(&Y_, &common_);
    cholmod_free_dense(&E_, &common_);
    cholmod_free_dense(&B_, &common_);
    cholmod_free_factor(&L_, &common_);
    cholmod_free_sparse(&A_, &common_);
    cholmod_finish(&common_);
  }

  weft::ModelAndState<double> flag_;
  weft::detail::SpringLaplacianSolver<double> solver_;
  cholmod_common common_{};
  std::size_t n_ = 0;
  cholmod_sparse* A_ = nullptr;
  cholmod_factor* L_ = nullptr;
  cholmod_dense* B_ = nullptr;
  cholmod_dense* X_ = nullptr;
  cholmod_dense* Y_ = nullptr;
  cholmod_dense* E_ = nullptr;
  double factorEntries_ = 0;
  bool released_ = false;
};

void BM_Peer_Cholmod_Solve(benchmark::State& st) {
  CholmodSystem system(static_cast<weft::Index>(st.range(0)), static_cast<int>(st.range(1)), st.range(2) != 0);
  if (!system.solve()) {  // the first solve allocates X, Y and E
    st.SkipWithError("cholmod_solve2 failed");
    return;
  }
  const std::int64_t allocationsBefore = weftbench::allocationCount();
  std::int64_t solves = 0;
  for (auto _ : st) {
    if (!system.solve()) {
      st.SkipWithError("cholmod_solve2 failed");
      break;
    }
    ++solves;
  }
  st.counters["allocs_per_solve"] = static_cast<double>(weftbench::allocationCount() - allocationsBefore) /
                                    static_cast<double>(std::max<std::int64_t>(solves, 1));
  st.counters["factor_entries"] = system.factorEntries();
  st.counters["entries_per_second"] =
      benchmark::Counter(2.0 * system.factorEntries(), benchmark::Counter::kIsIterationInvariantRate);
  st.counters["max_difference_vs_weft"] = system.differenceFromWeft();
  st.SetLabel(system.orderingName());
}
// Both benchmarks' cases: the 64^2 and 128^2 flags, the four orderings, either factor.
void cholmodCases(benchmark::internal::Benchmark* b) {
  b->ArgNames({"size", "ordering", "supernodal"})->ArgsProduct({{64, 128}, {0, 1, 2, 3}, {0, 1}})->UseRealTime();
}

BENCHMARK(BM_Peer_Cholmod_Solve)->Apply(cholmodCases)->Unit(benchmark::kMicrosecond);

void BM_Peer_Cholmod_Factor(benchmark::State& st) {
  CholmodSystem system(static_cast<weft::Index>(st.range(0)), static_cast<int>(st.range(1)), st.range(2) != 0);
  for (auto _ : st)
    if (!system.factorize()) {
      st.SkipWithError("cholmod_factorize failed");
      break;
    }
  st.counters["factor_entries"] = system.factorEntries();
  st.SetLabel(system.orderingName());
}
BENCHMARK(BM_Peer_Cholmod_Factor)->Apply(cholmodCases)->Unit(benchmark::kMillisecond);

}  // namespace
