// Internal: a prefactored solve with the springs' scalar system matrix
//
//     P = M + h c I + sum_s (theta h^2 ks + h kd) L_s      (rows of pinned particles: identity)
//
// (L_s a spring's graph Laplacian, the same matrix for x, y and z), used by implicit Euler as
// its CG preconditioner (IntegratorOptions::preconditioner = Projective), and with theta = 1
// by projective dynamics as its global matrix (projective.cpp); smaller theta trades the stiffness P assigns across
// slack springs (where the Hessian has none) against what it assigns along them.
//
// P is factorised (Eigen's SimplicialLDLT, in double for both precisions) per (h, c); the
// factor's entries are kept in float beside a 16-bit row index up to 65536 particles, a
// 32-bit one beyond (6 or 8 bytes an entry instead of 12: the solves stream the factor, so
// this is what they cost), D^-1 and every sum in double. A
// solve is then one with L~ D L~^T, still symmetric positive definite (a preconditioner),
// leaving a residual with P of ~1e-6 of the right-hand side (tests/test_integrate_laplacian.cpp);
// projective dynamics iterates in correction form, so its fixed point does not move. The two most recently used factors
// are kept, so a step with a cached h allocates nothing. The ordering is found once: one level of nested dissection
// (two parts that no spring joins and a separator; whole connected components where they balance), each part in
// approximate-minimum-degree order, the separator last; small models: minimum degree on
// the whole.
//
// The triangular solves are weft's own, both in gather form (each unknown sums its terms in
// registers and is written once; scattering into later rows instead chains every update of
// a row through a store and a load, 2-4x slower), the three coordinates interleaved so the
// factor is read once per solve. L y = b runs over the rows of L (a second copy of the
// factor, transposed), L^T x = D^-1 y over its columns, each column's terms farthest first,
// so that the sum waits for the unknown just computed only at its end. The two parts'
// columns never reach each other's rows: they run as two tasks, the separator's rows after
// (forward, with each part's share of their sums formed in its task) or before (backward)
// them. Every unknown is summed in the same order whichever thread runs its task, so the
// result is the same for any thread count. The gather into the factor's order and the
// scatter back are parallel passes over particle blocks; the scatter also forms r . z per
// block. The file is compiled without floating-point contraction (see
// kernel/CMakeLists.txt).
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
  /// preconditioner's matrix"). `wideIndices`: 32-bit row indices even where 16 bits would
  /// do (for tests: the path models over 65536 particles take).
  SpringLaplacianSolver(const Model<S>& model, double theta, const char* what, bool wideIndices = false);

  /// Makes the factor for step h and drag c current: from the cache, or factorised now
  /// (allocates; returns true then).
  bool prepare(double h, double drag);

  /// z = F P~^-1 F r (F zeroes pinned particles' rows; P~ = L~ D L~^T with the factor's
  /// entries rounded to float, within ~1e-6 of P), and partials[k] = r . z over the
  /// particles of block k (blocks of `block` particles, accumulated in double).
  void apply(const Vec3Array<S>& r, Vec3Array<S>& z, std::vector<double>& partials, Index block, const Executor& exec);

  /// The solve on the solver's own buffer, for callers that gather and scatter themselves
  /// (projective dynamics): (4 n) doubles, particle i's x, y, z at offset(i) + 0, 1, 2 (the
  /// fourth of each row is a pad that must stay 0).
  double* buffer() { return work_.data(); }
  const double* buffer() const { return work_.data(); }
  Index offset(Index i) const { return 4 * static_cast<Index>(position_[static_cast<size_t>(i)]); }
  /// buffer() = (L D L^T)^-1 buffer() with the factor prepare() made current.
  void solveBuffer(const Executor& exec) { solve(*current_, exec); }

  /// Entries of the current factor's strict lower triangle (0 before prepare()).
  Index factorEntries() const { return current_ != nullptr ? current_->lower.entries() : 0; }
  /// Bytes of the current factor (both copies, D^-1 and the cuts; 0 before prepare()).
  std::size_t factorBytes() const { return current_ != nullptr ? current_->bytes() : 0; }
  /// P's lower triangle (diagonal included) in the particles' order, for step h and drag c
  /// (allocates; for tests and benchmarks: peers factorise the same matrix).
  Eigen::SparseMatrix<double> matrix(double h, double drag) const { return assemble(h, drag); }
  /// The fill-reducing ordering: particle i is row positions()[i] of the factor.
  const std::vector<int>& positions() const { return position_; }
  /// The column ranges of the current factor's solve: [0, split[0]) and [split[0],
  /// split[1]) run as two tasks, [split[1], n) after them; {0, 0}: one task (for tests and
  /// benchmarks).
  std::array<Index, 2> split() const { return current_ != nullptr ? current_->split : std::array<Index, 2>{0, 0}; }

 private:
  /// A triangle of the factor, compressed by columns or by rows: the entries of line k are
  /// [outer[k], outer[k + 1]), their indices increasing. The indices take 16 bits when the
  /// model has at most 65536 particles and the solver was not asked for wide indices
  /// (narrow; 6 bytes an entry with its float value, the solves at 128^2 are bound by
  /// streaming the factor), else 32 (wide).
  struct Compressed {
    std::vector<int> outer;
    std::vector<std::uint16_t> narrow;
    std::vector<int> wide;
    std::vector<float> value;
    Index entries() const { return static_cast<Index>(value.size()); }
    int index(int p) const { return narrow.empty() ? wide[static_cast<size_t>(p)] : narrow[static_cast<size_t>(p)]; }
    std::size_t bytes() const {
      return outer.size() * sizeof(int) + narrow.size() * sizeof(std::uint16_t) + wide.size() * sizeof(int) +
             value.size() * sizeof(float);
    }
  };
  struct Factor {
    double h = 0;  // 0: empty slot
    double drag = -1;
    std::uint64_t lastUse = 0;
    Compressed lower;                  // strictly lower triangle of L (unit diagonal), by columns
    Compressed rows;                   // the same, by rows (L^T by columns)
    Eigen::VectorXd inverseD;          // 1 / D
    std::array<Index, 2> split{0, 0};  // [0, split[0]) and [split[0], split[1]): independent
    std::vector<int> cuts;             // per top row: where its first and second task's terms end
    std::size_t bytes() const {
      return lower.bytes() + rows.bytes() + static_cast<std::size_t>(inverseD.size()) * sizeof(double) +
             cuts.size() * sizeof(int);
    }
  };
  Eigen::SparseMatrix<double> assemble(double h, double drag) const;
  /// The factor by columns from L (Eigen's), with indices of type I (`lowerIndex`: the
  /// vector of `lower` that type takes), and its transposed copy by rows.
  template <class I>
  static void compressColumns(const Eigen::SparseMatrix<double>& L, Compressed& lower, std::vector<I>& lowerIndex);
  template <class I>
  static void transpose(const Compressed& lower, const std::vector<I>& lowerIndex, Compressed& rows,
                        std::vector<I>& rowIndex);
  void solve(const Factor& f, const Executor& exec);
  template <class I>
  void solveWith(const Factor& f, const I* rowIndex, const I* columnIndex, const Executor& exec);
  static bool independent(const Compressed& lower, std::array<Index, 2> split);

  const Model<S>* model_;
  double theta_;
  const char* what_;
  Index n_;
  bool narrow_;                      // 16-bit row indices
  std::vector<unsigned char> free_;  // 1 for free particles
  std::vector<int> position_;        // particle -> row in the factor's order
  // Aligned to Eigen's largest alignment (64 bytes), so no row of four straddles a line.
  using AlignedDoubles = std::vector<double, Eigen::aligned_allocator<double>>;
  AlignedDoubles work_;                   // (4 n) interleaved right-hand side / solution, a zero pad per row
  std::array<Index, 2> partition_{0, 0};  // the dissection's two parts, when found
  AlignedDoubles border_;                 // (2 x top rows x 4): each task's share of the top rows' sums
  std::array<Factor, 2> cache_;
  const Factor* current_ = nullptr;
  std::uint64_t useClock_ = 0;
};

extern template class SpringLaplacianSolver<float>;
extern template class SpringLaplacianSolver<double>;

}  // namespace weft::detail
