#include "spring_laplacian_solver.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <stdexcept>
#include <string>

namespace weft::detail {

template <class S>
SpringLaplacianSolver<S>::SpringLaplacianSolver(const Model<S>& model, double theta, const char* what)
    : model_(&model),
      theta_(theta),
      what_(what),
      n_(model.particleCount()),
      free_(static_cast<size_t>(model.particleCount())),
      position_(static_cast<size_t>(model.particleCount())),
      inversePosition_(static_cast<size_t>(model.particleCount())),
      work_(static_cast<size_t>(3 * model.particleCount()), 0.0) {
  for (Index i = 0; i < n_; ++i) free_[static_cast<size_t>(i)] = model.isPinned(i) ? 0 : 1;
  // The ordering depends on the pattern only: found once, here.
  const Eigen::SparseMatrix<double> pattern = assemble(1.0, 0.0);
  Eigen::AMDOrdering<int> ordering;
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> inverse;
  ordering(pattern.selfadjointView<Eigen::Lower>(), inverse);  // AMD returns P^-1
  const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> permutation = inverse.inverse();
  for (Index i = 0; i < n_; ++i) {
    position_[static_cast<size_t>(i)] = permutation.indices()[i];
    inversePosition_[static_cast<size_t>(permutation.indices()[i])] = static_cast<int>(i);
  }
}

template <class S>
Eigen::SparseMatrix<double> SpringLaplacianSolver<S>::assemble(double h, double drag) const {
  const Springs<S>& sp = model_->springs();
  std::vector<Eigen::Triplet<double, int>> entries;
  entries.reserve(static_cast<size_t>(n_ + 3 * sp.count()));
  for (Index i = 0; i < n_; ++i)
    entries.emplace_back(static_cast<int>(i), static_cast<int>(i),
                         free_[static_cast<size_t>(i)] ? static_cast<double>(model_->mass()[i]) + h * drag : 1.0);
  for (Index s = 0; s < sp.count(); ++s) {
    const Index a = sp.a[s], b = sp.b[s];
    const double k = theta_ * h * h * static_cast<double>(sp.stiffness[s]) + h * static_cast<double>(sp.damping[s]);
    const bool aFree = free_[static_cast<size_t>(a)] != 0, bFree = free_[static_cast<size_t>(b)] != 0;
    if (aFree) entries.emplace_back(static_cast<int>(a), static_cast<int>(a), k);
    if (bFree) entries.emplace_back(static_cast<int>(b), static_cast<int>(b), k);
    if (aFree && bFree && a != b)
      entries.emplace_back(static_cast<int>(std::max(a, b)), static_cast<int>(std::min(a, b)), -k);
  }
  Eigen::SparseMatrix<double> A(n_, n_);
  A.setFromTriplets(entries.begin(), entries.end());
  return A;
}

template <class S>
bool SpringLaplacianSolver<S>::prepare(double h, double drag) {
  ++useClock_;
  for (Factor& f : cache_)
    if (f.h == h && f.drag == drag) {
      f.lastUse = useClock_;
      current_ = &f;
      return false;
    }
  // The least recently used slot is refilled; slots never move (see projective.cpp).
  Factor& f = cache_[0].lastUse <= cache_[1].lastUse ? cache_[0] : cache_[1];
  const Eigen::SparseMatrix<double> A = assemble(h, drag);
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> permutation(n_);
  for (Index i = 0; i < n_; ++i) permutation.indices()[i] = position_[static_cast<size_t>(i)];
  Eigen::SparseMatrix<double> permuted(n_, n_);
  permuted.selfadjointView<Eigen::Lower>() = A.selfadjointView<Eigen::Lower>().twistedBy(permutation);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> ldlt(permuted);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0).all())
    throw std::runtime_error(std::string(what_) +
                             " is not positive definite (a particle of zero mass that is not pinned?)");
  f.h = h;
  f.drag = drag;
  f.lastUse = useClock_;
  f.lower = ldlt.matrixL().nestedExpression();
  f.lower.makeCompressed();
  f.inverseD = ldlt.vectorD().cwiseInverse();
  current_ = &f;
  return true;
}

template <class S>
void SpringLaplacianSolver<S>::apply(const Vec3Array<S>& r, Vec3Array<S>& z, std::vector<double>& partials, Index block,
                                     const Executor& exec) {
  double* y = work_.data();
  exec.parallelFor(n_, block, [&](Index b, Index e) {
    for (Index i = b; i < e; ++i) {
      double* out = y + 3 * static_cast<Index>(position_[static_cast<size_t>(i)]);
      const bool isFree = free_[static_cast<size_t>(i)] != 0;
      for (int c = 0; c < 3; ++c) out[c] = isFree ? static_cast<double>(r(i, c)) : 0.0;
    }
  });
  solve(*current_);
  exec.parallelFor(n_, block, [&](Index b, Index e) {
    double rz = 0;
    for (int c = 0; c < 3; ++c)
      for (Index i = b; i < e; ++i) {
        const double* in = y + 3 * static_cast<Index>(position_[static_cast<size_t>(i)]);
        const S zi = free_[static_cast<size_t>(i)] != 0 ? static_cast<S>(in[c]) : S(0);
        z(i, c) = zi;
        rz += static_cast<double>(r(i, c)) * static_cast<double>(zi);
      }
    partials[static_cast<size_t>(b / block)] = rz;
  });
}

template <class S>
void SpringLaplacianSolver<S>::solve(const Factor& f) {
  const Index n = n_;
  const int* outer = f.lower.outerIndexPtr();
  const int* inner = f.lower.innerIndexPtr();
  const double* value = f.lower.valuePtr();
  double* y = work_.data();
  for (Index j = 0; j < n; ++j) {  // L y = b, column by column
    const double y0 = y[3 * j], y1 = y[3 * j + 1], y2 = y[3 * j + 2];
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      double* t = y + 3 * static_cast<Index>(inner[p]);
      const double l = value[p];
      t[0] -= l * y0;
      t[1] -= l * y1;
      t[2] -= l * y2;
    }
  }
  for (Index j = 0; j < n; ++j) {  // D z = y
    const double d = f.inverseD[j];
    y[3 * j] *= d;
    y[3 * j + 1] *= d;
    y[3 * j + 2] *= d;
  }
  for (Index j = n - 1; j >= 0; --j) {  // L^T x = z, two partial sums per coordinate
    double s0 = y[3 * j], s1 = y[3 * j + 1], s2 = y[3 * j + 2], u0 = 0, u1 = 0, u2 = 0;
    int p = outer[j];
    const int end = outer[j + 1];
    for (; p + 1 < end; p += 2) {
      const double* t = y + 3 * static_cast<Index>(inner[p]);
      const double* q = y + 3 * static_cast<Index>(inner[p + 1]);
      const double l = value[p], k = value[p + 1];
      s0 -= l * t[0];
      s1 -= l * t[1];
      s2 -= l * t[2];
      u0 -= k * q[0];
      u1 -= k * q[1];
      u2 -= k * q[2];
    }
    if (p < end) {
      const double* t = y + 3 * static_cast<Index>(inner[p]);
      const double l = value[p];
      s0 -= l * t[0];
      s1 -= l * t[1];
      s2 -= l * t[2];
    }
    y[3 * j] = s0 + u0;
    y[3 * j + 1] = s1 + u1;
    y[3 * j + 2] = s2 + u2;
  }
}

template class SpringLaplacianSolver<float>;
template class SpringLaplacianSolver<double>;

}  // namespace weft::detail
