// Internal: a prefactored solve with the springs' scalar system matrix
//
//     P = M + h c I + sum_s (theta h^2 ks + h kd) L_s      (rows of pinned particles: identity)
//
// (L_s a spring's graph Laplacian, the same matrix for x, y and z), used by implicit Euler as
// its CG preconditioner (IntegratorOptions::preconditioner = Projective), and with theta = 1
// by projective dynamics as its global matrix (projective.cpp); smaller theta trades the stiffness P assigns across
// slack springs (where the Hessian has none) against what it assigns along them.
//
// P is factorised (Eigen's SimplicialLDLT with an approximate-minimum-degree ordering
// found once, in double for both precisions) per (h, c); the two most recently used
// factors are kept, so a step with a cached h allocates nothing. The triangular solves run
// on one thread over the factor's columns, the three coordinates interleaved; the gather
// into the factor's order and the scatter back are parallel passes over particle blocks.
// The scatter also forms r . z per block, so the result is the same for any thread count.
// The file is compiled without floating-point contraction (see kernel/CMakeLists.txt).
#pragma once

#include <Eigen/SparseCore>
#include <array>
#include <cstdint>
#include <vector>

#include "weft/effects/force_field.hpp"

namespace weft::detail {

template <class S>
class SpringLaplacianSolver {
 public:
  /// Finds the fill-reducing ordering (allocates). `model` must outlive the solver. `what`
  /// names the matrix in the error a failed factorisation throws ("implicit Euler: the
  /// preconditioner's matrix").
  SpringLaplacianSolver(const Model<S>& model, double theta, const char* what);

  /// Makes the factor for step h and drag c current: from the cache, or factorised now
  /// (allocates; returns true then).
  bool prepare(double h, double drag);

  /// z = F P^-1 F r (F zeroes pinned particles' rows), and partials[k] = r . z over the
  /// particles of block k (blocks of `block` particles, accumulated in double).
  void apply(const Vec3Array<S>& r, Vec3Array<S>& z, std::vector<double>& partials, Index block, const Executor& exec);

  /// The solve on the solver's own buffer, for callers that gather and scatter themselves
  /// (projective dynamics): (3 n) doubles, particle i's x, y, z at 3 position(i).
  double* buffer() { return work_.data(); }
  const double* buffer() const { return work_.data(); }
  Index position(Index i) const { return position_[static_cast<size_t>(i)]; }
  /// buffer() = (L D L^T)^-1 buffer() with the factor prepare() made current.
  void solveBuffer() { solve(*current_); }

 private:
  struct Factor {
    double h = 0;  // 0: empty slot
    double drag = -1;
    std::uint64_t lastUse = 0;
    Eigen::SparseMatrix<double> lower;  // strictly lower triangle of L (unit diagonal), columns
    Eigen::VectorXd inverseD;           // 1 / D
  };
  Eigen::SparseMatrix<double> assemble(double h, double drag) const;
  void solve(const Factor& f);

  const Model<S>* model_;
  double theta_;
  const char* what_;
  Index n_;
  std::vector<unsigned char> free_;  // 1 for free particles
  std::vector<int> position_;        // particle -> row in the factor's order
  std::vector<int> inversePosition_;
  std::vector<double> work_;  // (3 n) interleaved right-hand side / solution
  std::array<Factor, 2> cache_;
  const Factor* current_ = nullptr;
  std::uint64_t useClock_ = 0;
};

extern template class SpringLaplacianSolver<float>;
extern template class SpringLaplacianSolver<double>;

}  // namespace weft::detail
