#include "spring_laplacian_solver.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cstring>
#include <stdexcept>
#include <string>

#include "core/text.hpp"

namespace weft::detail {

namespace {

// Below this many particles the solve runs as one task (no dissection is looked for).
constexpr int kMinimumDissected = 64;
// Below this many factor entries, too: two tasks' dispatch would cost more than they save
// (about 30 us a solve at the rate BM_Projective_Solve measured on the 64^2 flag; set from
// that rate, not tuned).
constexpr Index kMinimumParallelEntries = 32768;

/// AMD on the submatrix of `lower` (a lower triangle) that `nodes` (increasing) induce:
/// appends the nodes to `order` in that ordering.
void appendMinimumDegree(const Eigen::SparseMatrix<double>& lower, const std::vector<int>& nodes,
                         std::vector<int>& order) {
  const int m = static_cast<int>(nodes.size());
  if (m == 0) return;
  std::vector<int> local(static_cast<size_t>(lower.cols()), -1);
  for (int k = 0; k < m; ++k) local[static_cast<size_t>(nodes[static_cast<size_t>(k)])] = k;
  std::vector<Eigen::Triplet<double, int>> entries;
  for (int k = 0; k < m; ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(lower, nodes[static_cast<size_t>(k)]); it; ++it)
      if (local[static_cast<size_t>(it.index())] >= 0)
        entries.emplace_back(local[static_cast<size_t>(it.index())], k, 1.0);
  Eigen::SparseMatrix<double> sub(m, m);
  sub.setFromTriplets(entries.begin(), entries.end());
  Eigen::AMDOrdering<int> ordering;
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> inverse;
  ordering(sub.selfadjointView<Eigen::Lower>(), inverse);  // inverse.indices()[k]: the k-th node
  for (int k = 0; k < m; ++k) order.push_back(nodes[static_cast<size_t>(inverse.indices()[k])]);
}

/// Two parts that no edge of the matrix graph (`lower`: its lower triangle) joins, and a
/// separator between them, as part[i] = 0, 1 or 2, balanced in particles; empty when the
/// graph is too small to be worth two tasks or cannot be split. Whole connected components
/// go to the lighter side, largest first; if that leaves the sides uneven, the largest
/// component is cut instead (one level of nested dissection) at one level of a
/// breadth-first search from a pseudo-peripheral node: every edge joins equal or adjacent
/// levels, so a level separates the levels before it from those after. Of all the levels
/// and both orientations the one minimising (heavier side) + (separator) is taken, and only
/// if that beats the components alone.
std::vector<int> bisect(const Eigen::SparseMatrix<double>& lower) {
  const int n = static_cast<int>(lower.cols());
  if (n < kMinimumDissected) return {};
  std::vector<std::vector<int>> adjacent(static_cast<size_t>(n));
  for (int j = 0; j < n; ++j)
    for (Eigen::SparseMatrix<double>::InnerIterator it(lower, j); it; ++it)
      if (it.index() != j) {
        adjacent[static_cast<size_t>(j)].push_back(it.index());
        adjacent[static_cast<size_t>(it.index())].push_back(j);
      }
  // Breadth-first levels from `start` over unmarked nodes; returns the nodes in visit order.
  std::vector<int> level(static_cast<size_t>(n), -1);
  const auto search = [&](int start) {
    std::vector<int> visited{start};
    level[static_cast<size_t>(start)] = 0;
    for (size_t k = 0; k < visited.size(); ++k)
      for (int next : adjacent[static_cast<size_t>(visited[k])])
        if (level[static_cast<size_t>(next)] < 0) {
          level[static_cast<size_t>(next)] = level[static_cast<size_t>(visited[k])] + 1;
          visited.push_back(next);
        }
    return visited;
  };
  std::vector<std::vector<int>> components;
  for (int i = 0; i < n; ++i)
    if (level[static_cast<size_t>(i)] < 0) components.push_back(search(i));
  // Largest first (ties: lowest first node), so the greedy assignment below is deterministic.
  std::stable_sort(components.begin(), components.end(),
                   [](const std::vector<int>& x, const std::vector<int>& y) { return x.size() > y.size(); });
  std::vector<int> part(static_cast<size_t>(n), -1);
  // The components after the largest, each to the lighter side.
  std::array<long, 2> rest{0, 0};
  for (size_t c = 1; c < components.size(); ++c) {
    const int side = rest[0] <= rest[1] ? 0 : 1;
    for (int i : components[c]) part[static_cast<size_t>(i)] = side;
    rest[static_cast<size_t>(side)] += static_cast<long>(components[c].size());
  }
  const std::vector<int>& big = components.front();
  const long whole = static_cast<long>(big.size());
  const int lighter = rest[0] <= rest[1] ? 0 : 1;
  double bestCost = static_cast<double>(std::max(rest[static_cast<size_t>(lighter)] + whole,
                                                 rest[static_cast<size_t>(1 - lighter)]));  // no cut
  int cut = -1, firstSide = 0;
  std::vector<int> visited;
  if (whole >= kMinimumDissected) {
    for (int i : big) level[static_cast<size_t>(i)] = -1;
    const int far = search(big.front()).back();
    for (int i : big) level[static_cast<size_t>(i)] = -1;
    visited = search(far);
    const int levels = level[static_cast<size_t>(visited.back())] + 1;
    std::vector<long> count(static_cast<size_t>(levels), 0);
    for (int i : visited) ++count[static_cast<size_t>(level[static_cast<size_t>(i)])];
    long before = 0;
    for (int l = 1; l + 1 < levels; ++l) {
      before += count[static_cast<size_t>(l - 1)];
      const long after = whole - before - count[static_cast<size_t>(l)];
      for (int side = 0; side < 2; ++side) {  // the levels before l go to `side`
        const double cost = static_cast<double>(
            std::max(before + rest[static_cast<size_t>(side)], after + rest[static_cast<size_t>(1 - side)]) +
            count[static_cast<size_t>(l)]);
        if (cost < bestCost) {
          bestCost = cost;
          cut = l;
          firstSide = side;
        }
      }
    }
  }
  if (cut > 0) {
    for (int i : visited) {
      const int l = level[static_cast<size_t>(i)];
      part[static_cast<size_t>(i)] = l < cut ? firstSide : (l > cut ? 1 - firstSide : 2);
    }
  } else {
    for (int i : big) part[static_cast<size_t>(i)] = lighter;
  }
  std::array<long, 2> sizes{0, 0};
  for (int p : part)
    if (p < 2) ++sizes[static_cast<size_t>(p)];
  if (sizes[0] == 0 || sizes[1] == 0) return {};  // one side only: nothing to run beside it
  return part;
}

}  // namespace

template <class S>
SpringLaplacianSolver<S>::SpringLaplacianSolver(const Model<S>& model, double theta, const char* what, bool wideIndices)
    : model_(&model),
      theta_(theta),
      what_(what),
      n_(model.particleCount()),
      narrow_(!wideIndices && model.particleCount() <= 65536),
      free_(static_cast<size_t>(model.particleCount())),
      position_(static_cast<size_t>(model.particleCount())),
      work_(static_cast<size_t>(4 * model.particleCount()), 0.0) {
  for (Index i = 0; i < n_; ++i) free_[static_cast<size_t>(i)] = model.isPinned(i) ? 0 : 1;
  // The ordering depends on the pattern only: found once, here. With a dissection, the two
  // parts, each in minimum-degree order, then the separator: the parts' columns never
  // reach each other's rows, so they are the solve's two tasks. Without, minimum degree on
  // the whole, solved as one task.
  const Eigen::SparseMatrix<double> pattern = assemble(1.0, 0.0);
  const std::vector<int> part = bisect(pattern);
  std::vector<int> order;  // order[k]: the particle in the factor's k-th row
  order.reserve(static_cast<size_t>(n_));
  for (int side = 0; side < (part.empty() ? 1 : 3); ++side) {
    std::vector<int> nodes;
    for (Index i = 0; i < n_; ++i)
      if (part.empty() || part[static_cast<size_t>(i)] == side) nodes.push_back(static_cast<int>(i));
    appendMinimumDegree(pattern, nodes, order);
    if (!part.empty() && side < 2) partition_[static_cast<size_t>(side)] = static_cast<Index>(order.size());
  }
  for (Index k = 0; k < n_; ++k) position_[static_cast<size_t>(order[static_cast<size_t>(k)])] = static_cast<int>(k);
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
template <class I>
void SpringLaplacianSolver<S>::compressColumns(const Eigen::SparseMatrix<double>& L, Compressed& lower,
                                               std::vector<I>& lowerIndex) {
  // L's strict lower triangle by columns (Eigen keeps L's unit diagonal implicit, its
  // entries by increasing row within each column), entries rounded to float.
  const Index n = L.cols();
  const int* outer = L.outerIndexPtr();
  const int* inner = L.innerIndexPtr();
  const double* value = L.valuePtr();
  const auto entries = static_cast<size_t>(outer[n] - outer[0]);
  lower.outer.resize(static_cast<size_t>(n + 1));
  for (Index j = 0; j <= n; ++j) lower.outer[static_cast<size_t>(j)] = outer[j] - outer[0];
  lower.value.resize(entries);
  lowerIndex.resize(entries);
  for (Index j = 0; j < n; ++j)
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      const auto q = static_cast<size_t>(p - outer[0]);
      lower.value[q] = static_cast<float>(value[p]);
      lowerIndex[q] = static_cast<I>(inner[p]);
    }
}

template <class S>
template <class I>
void SpringLaplacianSolver<S>::transpose(const Compressed& lower, const std::vector<I>& lowerIndex, Compressed& rows,
                                         std::vector<I>& rowIndex) {
  // A sweep over the columns in order gives each row its entries by increasing column.
  const auto n = static_cast<Index>(lower.outer.size()) - 1;
  const auto entries = lowerIndex.size();
  rows.outer.assign(static_cast<size_t>(n + 1), 0);
  for (const I i : lowerIndex) ++rows.outer[static_cast<size_t>(i) + 1];
  for (Index i = 0; i < n; ++i) rows.outer[static_cast<size_t>(i + 1)] += rows.outer[static_cast<size_t>(i)];
  std::vector<int> next(rows.outer.begin(), rows.outer.end() - 1);
  rows.value.resize(entries);
  rowIndex.resize(entries);
  for (Index j = 0; j < n; ++j)
    for (int p = lower.outer[static_cast<size_t>(j)]; p < lower.outer[static_cast<size_t>(j + 1)]; ++p) {
      const auto q = static_cast<size_t>(next[static_cast<size_t>(lowerIndex[static_cast<size_t>(p)])]++);
      rows.value[q] = lower.value[static_cast<size_t>(p)];
      rowIndex[q] = static_cast<I>(j);
    }
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
  // The slot's old factor goes first, and the double factor before the transposed copy is
  // made, so that a factorisation's peak memory holds one factor in double and one in float.
  if (current_ == &f) current_ = nullptr;
  f = Factor{};
  {
    const Eigen::SparseMatrix<double> A = assemble(h, drag);
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> permutation(n_);
    for (Index i = 0; i < n_; ++i) permutation.indices()[i] = position_[static_cast<size_t>(i)];
    Eigen::SparseMatrix<double> permuted(n_, n_);
    permuted.selfadjointView<Eigen::Lower>() = A.selfadjointView<Eigen::Lower>().twistedBy(permutation);
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> ldlt(permuted);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0).all())
      throw std::runtime_error(std::string(what_) + " at dt = " + detail::number(h) +
                               " s is not positive definite (its mass term m / dt^2 vanishes beside the springs' at "
                               "so long a step, or a particle of zero mass is not pinned)");
    if (narrow_)
      compressColumns(ldlt.matrixL().nestedExpression(), f.lower, f.lower.narrow);
    else
      compressColumns(ldlt.matrixL().nestedExpression(), f.lower, f.lower.wide);
    f.inverseD = ldlt.vectorD().cwiseInverse();
  }
  if (narrow_)
    transpose(f.lower, f.lower.narrow, f.rows, f.rows.narrow);
  else
    transpose(f.lower, f.lower.wide, f.rows, f.rows.wide);
  f.h = h;
  f.drag = drag;
  f.lastUse = useClock_;
  // The dissection's parts, unless the factor is too small for two tasks to pay (or, which the
  // ordering rules out, the first part's columns reach the second's rows: the tasks would race).
  const bool twoTasks =
      partition_[1] > 0 && f.lower.entries() >= kMinimumParallelEntries && independent(f.lower, partition_);
  f.split = twoTasks ? partition_ : std::array<Index, 2>{0, 0};
  // Where each top row's terms from the first and the second task's columns end.
  const std::vector<int>& outer = f.rows.outer;
  f.cuts.assign(static_cast<size_t>(2 * (n_ - f.split[1])), 0);
  for (Index i = f.split[1]; i < n_; ++i) {
    const auto end = outer[static_cast<size_t>(i + 1)];
    int p = outer[static_cast<size_t>(i)];
    while (p < end && f.rows.index(p) < f.split[0]) ++p;
    f.cuts[static_cast<size_t>(2 * (i - f.split[1]))] = p;
    while (p < end && f.rows.index(p) < f.split[1]) ++p;
    f.cuts[static_cast<size_t>(2 * (i - f.split[1]) + 1)] = p;
  }
  border_.resize(std::max(border_.size(), static_cast<size_t>(8 * (n_ - f.split[1]))));
  current_ = &f;
  return true;
}

template <class S>
void SpringLaplacianSolver<S>::apply(const Vec3Array<S>& r, Vec3Array<S>& z, std::vector<double>& partials, Index block,
                                     const Executor& exec) {
  double* y = work_.data();
  exec.parallelFor(n_, block, [&](Index b, Index e) {
    for (Index i = b; i < e; ++i) {
      double* out = y + offset(i);
      const bool isFree = free_[static_cast<size_t>(i)] != 0;
      for (int c = 0; c < 3; ++c) out[c] = isFree ? static_cast<double>(r(i, c)) : 0.0;
    }
  });
  solve(*current_, exec);
  exec.parallelFor(n_, block, [&](Index b, Index e) {
    double rz = 0;
    for (int c = 0; c < 3; ++c)
      for (Index i = b; i < e; ++i) {
        const double* in = y + offset(i);
        const S zi = free_[static_cast<size_t>(i)] != 0 ? static_cast<S>(in[c]) : S(0);
        z(i, c) = zi;
        rz += static_cast<double>(r(i, c)) * static_cast<double>(zi);
      }
    partials[static_cast<size_t>(b / block)] = rz;
  });
}

template <class S>
bool SpringLaplacianSolver<S>::independent(const Compressed& lower, std::array<Index, 2> split) {
  // The first range's columns must reach no row of the second (the reverse holds by order).
  const auto columns = static_cast<Index>(lower.outer.size()) - 1;
  if (split[0] < 0 || split[0] > split[1] || split[1] > columns) return false;
  for (Index j = 0; j < split[0]; ++j)
    for (int p = lower.outer[static_cast<size_t>(j)]; p < lower.outer[static_cast<size_t>(j + 1)]; ++p)
      if (lower.index(p) >= split[0] && lower.index(p) < split[1]) return false;
  return true;
}

namespace {

// A particle's row of the solve's buffer: x, y, z and a zero pad, as one vector of four
// (GCC's vector extension: one 256-bit load, one multiply and one add per factor entry where
// the machine has AVX, two 128-bit halves elsewhere; the same elementwise rounding either
// way). Always inlined: a vector of four passed by value between functions would depend on
// the machine's calling convention.
typedef double Row __attribute__((vector_size(32), aligned(8)));

__attribute__((always_inline)) inline Row load(const double* y, Index row) {
  Row r;
  std::memcpy(&r, y + 4 * row, sizeof r);
  return r;
}
__attribute__((always_inline)) inline void store(double* y, Index row, Row r) {
  std::memcpy(y + 4 * row, &r, sizeof r);
}

/// sum_p value[p] y(inner[p]) over entries [p, stop) of a row of L, in increasing column
/// (the row's nearest unknown comes last: the sum need not wait for it until its end), four
/// partial sums (on 2 threads 0.92-1.06 against 1.30-1.49 ms with two, at 128^2).
template <class I>
__attribute__((always_inline)) inline Row rowSum(const I* inner, const float* value, int p, int stop, const double* y) {
  Row s0 = {0, 0, 0, 0}, s1 = s0, s2 = s0, s3 = s0;
  for (; p + 3 < stop; p += 4) {
    s0 += static_cast<double>(value[p]) * load(y, inner[p]);
    s1 += static_cast<double>(value[p + 1]) * load(y, inner[p + 1]);
    s2 += static_cast<double>(value[p + 2]) * load(y, inner[p + 2]);
    s3 += static_cast<double>(value[p + 3]) * load(y, inner[p + 3]);
  }
  for (; p < stop; ++p) s0 += static_cast<double>(value[p]) * load(y, inner[p]);
  return (s0 + s1) + (s2 + s3);
}

/// y(i) -= sum_j L_ij y(j) over rows i in [begin, end) of L (by rows: outer, inner, value).
template <class I>
void forwardRows(const int* outer, const I* inner, const float* value, Index begin, Index end, double* y) {
  for (Index i = begin; i < end; ++i) store(y, i, load(y, i) - rowSum(inner, value, outer[i], outer[i + 1], y));
}

/// x(j) = y(j) / D_j - sum_i L_ij x(i) over columns j in [begin, end), decreasing j; the
/// terms in decreasing i (the column's parent in the elimination tree, often the unknown
/// just computed, comes last), four partial sums.
template <class I>
void backwardColumns(const int* outer, const I* inner, const float* value, const double* inverseD, Index begin,
                     Index end, double* y) {
  for (Index j = end - 1; j >= begin; --j) {
    Row s0 = {0, 0, 0, 0}, s1 = s0, s2 = s0, s3 = s0;
    const int first = outer[j];
    int p = outer[j + 1] - 1;
    for (; p - 3 >= first; p -= 4) {
      s0 += static_cast<double>(value[p]) * load(y, inner[p]);
      s1 += static_cast<double>(value[p - 1]) * load(y, inner[p - 1]);
      s2 += static_cast<double>(value[p - 2]) * load(y, inner[p - 2]);
      s3 += static_cast<double>(value[p - 3]) * load(y, inner[p - 3]);
    }
    for (; p >= first; --p) s0 += static_cast<double>(value[p]) * load(y, inner[p]);
    store(y, j, load(y, j) * inverseD[j] - ((s0 + s1) + (s2 + s3)));
  }
}

}  // namespace

template <class S>
void SpringLaplacianSolver<S>::solve(const Factor& f, const Executor& exec) {
  if (narrow_)
    solveWith(f, f.rows.narrow.data(), f.lower.narrow.data(), exec);
  else
    solveWith(f, f.rows.wide.data(), f.lower.wide.data(), exec);
}

template <class S>
template <class I>
void SpringLaplacianSolver<S>::solveWith(const Factor& f, const I* rowIndex, const I* columnIndex,
                                         const Executor& exec) {
  const Index n = n_;
  const Index a = f.split[0], b = f.split[1];
  double* y = work_.data();
  const double* inverseD = f.inverseD.data();
  const int* outer = f.rows.outer.data();
  const float* value = f.rows.value.data();
  const int* columnOuter = f.lower.outer.data();
  const float* columnValue = f.lower.value.data();
  if (b == 0) {  // one task
    forwardRows(outer, rowIndex, value, 0, n, y);
    backwardColumns(columnOuter, columnIndex, columnValue, inverseD, 0, n, y);
    return;
  }
  // L y = b: the two independent ranges, each also summing the top rows' terms from its own
  // columns (into border_), then the top rows: y - first task's sum - second's - their own.
  const Index top = n - b;
  double* border = border_.data();  // the first task's sums (top rows), then the second's
  exec.parallelFor(2, 1, [&](Index task, Index) {
    forwardRows(outer, rowIndex, value, task == 0 ? 0 : a, task == 0 ? a : b, y);
    for (Index k = 0; k < top; ++k) {
      const int begin = task == 0 ? outer[b + k] : f.cuts[static_cast<size_t>(2 * k)];
      store(border, task * top + k, rowSum(rowIndex, value, begin, f.cuts[static_cast<size_t>(2 * k + task)], y));
    }
  });
  for (Index k = 0; k < top; ++k) {
    const Index i = b + k;
    const Row own = rowSum(rowIndex, value, f.cuts[static_cast<size_t>(2 * k + 1)], outer[i + 1], y);
    store(y, i, ((load(y, i) - load(border, k)) - load(border, top + k)) - own);
  }
  // L^T x = D^-1 y: the top range first, then the two ranges.
  backwardColumns(columnOuter, columnIndex, columnValue, inverseD, b, n, y);
  exec.parallelFor(2, 1, [&](Index task, Index) {
    if (task == 0)
      backwardColumns(columnOuter, columnIndex, columnValue, inverseD, 0, a, y);
    else
      backwardColumns(columnOuter, columnIndex, columnValue, inverseD, a, b, y);
  });
}

template class SpringLaplacianSolver<float>;
template class SpringLaplacianSolver<double>;

}  // namespace weft::detail
