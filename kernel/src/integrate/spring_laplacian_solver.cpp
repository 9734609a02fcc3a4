#include "spring_laplacian_solver.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cstring>
#include <stdexcept>
#include <string>

namespace weft::detail {

namespace {

/// The elimination tree of the symmetric matrix whose lower triangle `lower` holds (Liu's
/// algorithm with path compression): parent[j] = -1 for a root.
std::vector<int> eliminationTree(const Eigen::SparseMatrix<double>& lower) {
  const Eigen::SparseMatrix<double> upper = lower.transpose();  // column k: rows i <= k
  const int n = static_cast<int>(upper.cols());
  std::vector<int> parent(static_cast<size_t>(n), -1), ancestor(static_cast<size_t>(n), -1);
  for (int k = 0; k < n; ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(upper, k); it; ++it)
      for (int i = it.index(); i != -1 && i < k;) {
        const int next = ancestor[static_cast<size_t>(i)];
        ancestor[static_cast<size_t>(i)] = k;
        if (next == -1) parent[static_cast<size_t>(i)] = k;
        i = next;
      }
  return parent;
}

/// A post-order of the forest `parent` (children in increasing order, roots in increasing
/// order): every subtree becomes a contiguous range ending at its root.
std::vector<int> postorder(const std::vector<int>& parent) {
  const int n = static_cast<int>(parent.size());
  std::vector<int> head(static_cast<size_t>(n), -1), next(static_cast<size_t>(n), -1), order, stack;
  order.reserve(static_cast<size_t>(n));
  for (int j = n - 1; j >= 0; --j)  // child lists, each in increasing order
    if (parent[static_cast<size_t>(j)] != -1) {
      next[static_cast<size_t>(j)] = head[static_cast<size_t>(parent[static_cast<size_t>(j)])];
      head[static_cast<size_t>(parent[static_cast<size_t>(j)])] = j;
    }
  for (int root = 0; root < n; ++root) {
    if (parent[static_cast<size_t>(root)] != -1) continue;
    stack.push_back(root);
    while (!stack.empty()) {
      const int top = stack.back();
      const int child = head[static_cast<size_t>(top)];
      if (child == -1) {
        order.push_back(top);
        stack.pop_back();
      } else {
        head[static_cast<size_t>(top)] = next[static_cast<size_t>(child)];  // consumed
        stack.push_back(child);
      }
    }
  }
  return order;
}

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

/// One level of nested dissection of the matrix graph (`lower`: its lower triangle): two
/// parts that no edge joins and the separator between them, as part[i] = 0, 1 or 2. The
/// largest connected component is cut at one level of a breadth-first search from a
/// pseudo-peripheral node (every edge joins equal or adjacent levels, so a level separates
/// the levels before it from those after), at the level that minimises (larger side) +
/// (separator); the other components go whole to the smaller side. Empty when a side would be
/// empty (small or tiny components).
std::vector<int> bisect(const Eigen::SparseMatrix<double>& lower) {
  const int n = static_cast<int>(lower.cols());
  if (n == 0) return {};
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
  size_t largest = 0;
  for (size_t c = 1; c < components.size(); ++c)
    if (components[c].size() > components[largest].size()) largest = c;
  std::vector<int> part(static_cast<size_t>(n), -1);
  const std::vector<int>& big = components[largest];
  if (big.size() >= 64) {
    for (int i : big) level[static_cast<size_t>(i)] = -1;
    const int far = search(big.front()).back();
    for (int i : big) level[static_cast<size_t>(i)] = -1;
    const std::vector<int> visited = search(far);
    const int levels = level[static_cast<size_t>(visited.back())] + 1;
    std::vector<int> count(static_cast<size_t>(levels), 0);
    for (int i : visited) ++count[static_cast<size_t>(level[static_cast<size_t>(i)])];
    int cut = -1, before = 0;
    double bestCost = static_cast<double>(visited.size());
    for (int l = 1; l + 1 < levels; ++l) {
      before += count[static_cast<size_t>(l - 1)];
      const int after = static_cast<int>(visited.size()) - before - count[static_cast<size_t>(l)];
      const double cost = std::max(before, after) + count[static_cast<size_t>(l)];
      if (cost < bestCost) {
        bestCost = cost;
        cut = l;
      }
    }
    if (cut > 0)
      for (int i : visited) {
        const int l = level[static_cast<size_t>(i)];
        part[static_cast<size_t>(i)] = l < cut ? 0 : (l > cut ? 1 : 2);
      }
  }
  if (part[static_cast<size_t>(big.front())] < 0) return {};
  std::array<size_t, 2> sizes{0, 0};
  for (int i = 0; i < n; ++i)
    if (part[static_cast<size_t>(i)] == 0 || part[static_cast<size_t>(i)] == 1)
      ++sizes[static_cast<size_t>(part[static_cast<size_t>(i)])];
  for (size_t c = 0; c < components.size(); ++c) {
    if (c == largest) continue;
    const int side = sizes[0] <= sizes[1] ? 0 : 1;
    for (int i : components[c]) part[static_cast<size_t>(i)] = side;
    sizes[static_cast<size_t>(side)] += components[c].size();
  }
  return part;
}

}  // namespace

template <class S>
SpringLaplacianSolver<S>::SpringLaplacianSolver(const Model<S>& model, double theta, const char* what)
    : model_(&model),
      theta_(theta),
      what_(what),
      n_(model.particleCount()),
      free_(static_cast<size_t>(model.particleCount())),
      position_(static_cast<size_t>(model.particleCount())),
      inversePosition_(static_cast<size_t>(model.particleCount())),
      work_(static_cast<size_t>(4 * model.particleCount()), 0.0) {
  for (Index i = 0; i < n_; ++i) free_[static_cast<size_t>(i)] = model.isPinned(i) ? 0 : 1;
  // The ordering depends on the pattern only: found once, here. With a separator (one level
  // of nested dissection), the two parts, each in minimum-degree order, then the separator:
  // the parts' columns never reach each other's rows, so they are the solve's two tasks.
  const Eigen::SparseMatrix<double> pattern = assemble(1.0, 0.0);
  const std::vector<int> part = bisect(pattern);
  std::vector<int> order;  // order[k]: the particle in the factor's k-th row
  order.reserve(static_cast<size_t>(n_));
  if (!part.empty()) {
    for (int side = 0; side < 3; ++side) {
      std::vector<int> nodes;
      for (Index i = 0; i < n_; ++i)
        if (part[static_cast<size_t>(i)] == side) nodes.push_back(static_cast<int>(i));
      appendMinimumDegree(pattern, nodes, order);
      if (side < 2) partition_[static_cast<size_t>(side)] = static_cast<Index>(order.size());
    }
  } else {
    // Minimum degree on the whole, post-ordered (the fill is the same) so that every subtree
    // of the elimination tree is a contiguous range of columns: prepare() cuts between them.
    std::vector<int> all(static_cast<size_t>(n_));
    for (Index i = 0; i < n_; ++i) all[static_cast<size_t>(i)] = static_cast<int>(i);
    std::vector<int> amd;
    appendMinimumDegree(pattern, all, amd);
    std::vector<int> rank(static_cast<size_t>(n_));
    for (Index k = 0; k < n_; ++k) rank[static_cast<size_t>(amd[static_cast<size_t>(k)])] = static_cast<int>(k);
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> permutation(n_);
    for (Index i = 0; i < n_; ++i) permutation.indices()[i] = rank[static_cast<size_t>(i)];
    Eigen::SparseMatrix<double> permuted(n_, n_);
    permuted.selfadjointView<Eigen::Lower>() = pattern.selfadjointView<Eigen::Lower>().twistedBy(permutation);
    for (int k : postorder(eliminationTree(permuted))) order.push_back(amd[static_cast<size_t>(k)]);
  }
  for (Index k = 0; k < n_; ++k) {
    position_[static_cast<size_t>(order[static_cast<size_t>(k)])] = static_cast<int>(k);
    inversePosition_[static_cast<size_t>(k)] = order[static_cast<size_t>(k)];
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
  f.rows = f.lower.transpose();
  f.rows.makeCompressed();
  f.inverseD = ldlt.vectorD().cwiseInverse();
  f.split = partition_[1] > 0 && independent(f.lower, partition_) ? partition_ : splitColumns(f.lower);
  // Where each top row's terms from the first and the second task's columns end.
  const int* outer = f.rows.outerIndexPtr();
  const int* inner = f.rows.innerIndexPtr();
  f.cuts.assign(static_cast<size_t>(2 * (n_ - f.split[1])), 0);
  for (Index i = f.split[1]; i < n_; ++i) {
    int p = outer[i];
    while (p < outer[i + 1] && inner[p] < f.split[0]) ++p;
    f.cuts[static_cast<size_t>(2 * (i - f.split[1]))] = p;
    while (p < outer[i + 1] && inner[p] < f.split[1]) ++p;
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
std::array<Index, 2> SpringLaplacianSolver<S>::splitColumns(const Eigen::SparseMatrix<double>& lower) {
  // The factor's columns are post-ordered, so for any b the columns [0, b) are the subtrees
  // of their local roots (the columns whose parent is >= b), contiguous and in order, and a
  // cut between two of them gives two ranges that never read each other's unknowns. Column
  // b - 1 is always such a root: moving it to the top range makes its children roots. The
  // cut minimising (larger task) + (top range) is kept, in work = entries + 1 per column.
  const Index n = lower.cols();
  if (n == 0) return {0, 0};
  const int* outer = lower.outerIndexPtr();
  const int* inner = lower.innerIndexPtr();
  std::vector<double> subtree(static_cast<size_t>(n));
  std::vector<std::vector<Index>> children(static_cast<size_t>(n));
  std::vector<Index> roots;
  double total = 0;
  for (Index j = 0; j < n; ++j) {
    subtree[static_cast<size_t>(j)] += static_cast<double>(outer[j + 1] - outer[j]) + 1.0;
    total += static_cast<double>(outer[j + 1] - outer[j]) + 1.0;
    if (outer[j + 1] > outer[j]) {  // the parent is the column's first (smallest) row
      const Index parent = inner[outer[j]];
      subtree[static_cast<size_t>(parent)] += subtree[static_cast<size_t>(j)];
      children[static_cast<size_t>(parent)].push_back(j);
    } else {
      roots.push_back(j);
    }
  }
  std::array<Index, 2> best{0, 0};
  double bestCost = total;  // everything in the top range
  double top = 0;
  for (Index b = n; b > 0;) {
    // roots (increasing) partition [0, b); the best cut between them
    double left = 0;
    for (size_t k = 0; k + 1 < roots.size(); ++k) {
      left += subtree[static_cast<size_t>(roots[k])];
      const double cost = std::max(left, total - top - left) + top;
      if (cost < bestCost) {
        bestCost = cost;
        best = {roots[k] + 1, b};
      }
    }
    if (top > 0.5 * total) break;     // the top range alone costs more than any gain left
    const Index last = roots.back();  // == b - 1
    roots.pop_back();
    for (Index c : children[static_cast<size_t>(last)]) roots.push_back(c);
    top += static_cast<double>(outer[last + 1] - outer[last]) + 1.0;
    b = last;
  }
  // The ranges rest on the ordering being a post-order: checked (else the tasks would race).
  return independent(lower, best) ? best : std::array<Index, 2>{0, 0};
}

template <class S>
bool SpringLaplacianSolver<S>::independent(const Eigen::SparseMatrix<double>& lower, std::array<Index, 2> split) {
  // The first range's columns must reach no row of the second (the reverse holds by order).
  const int* outer = lower.outerIndexPtr();
  const int* inner = lower.innerIndexPtr();
  for (Index j = 0; j < split[0]; ++j)
    for (int p = outer[j]; p < outer[j + 1]; ++p)
      if (inner[p] >= split[0] && inner[p] < split[1]) return false;
  return true;
}

namespace {

// A particle's row of the solve's buffer: x, y, z and a zero pad, as one vector of four
// (GCC's vector extension: one 256-bit load and one multiply-add per factor entry where the
// machine has AVX, two 128-bit halves elsewhere; the same elementwise rounding either way).
typedef double Row __attribute__((vector_size(32), aligned(8)));

inline Row load(const double* y, Index row) {
  Row r;
  std::memcpy(&r, y + 4 * row, sizeof r);
  return r;
}
inline void store(double* y, Index row, Row r) { std::memcpy(y + 4 * row, &r, sizeof r); }

/// sum_p value[p] y(inner[p]) over entries [p, stop) of a row of L, in increasing column
/// (the unknown computed last comes last), four partial sums: the additions, not the loads,
/// were the limit with one or two (each waits for the previous one's result).
inline Row rowSum(const int* inner, const double* value, int p, int stop, const double* y) {
  Row s0 = {0, 0, 0, 0}, s1 = s0, s2 = s0, s3 = s0;
  for (; p + 3 < stop; p += 4) {
    s0 += value[p] * load(y, inner[p]);
    s1 += value[p + 1] * load(y, inner[p + 1]);
    s2 += value[p + 2] * load(y, inner[p + 2]);
    s3 += value[p + 3] * load(y, inner[p + 3]);
  }
  for (; p < stop; ++p) s0 += value[p] * load(y, inner[p]);
  return (s0 + s1) + (s2 + s3);
}

/// y(i) -= sum_j L_ij y(j) over rows i in [begin, end) of L (`rows`: L^T by columns).
void forwardRows(const Eigen::SparseMatrix<double>& rows, Index begin, Index end, double* y) {
  const int* outer = rows.outerIndexPtr();
  for (Index i = begin; i < end; ++i)
    store(y, i, load(y, i) - rowSum(rows.innerIndexPtr(), rows.valuePtr(), outer[i], outer[i + 1], y));
}

/// x(j) = y(j) / D_j - sum_i L_ij x(i) over columns j in [begin, end), decreasing j; the
/// terms in decreasing i (the unknown just computed, j + 1, comes last), four partial sums.
void backwardColumns(const Eigen::SparseMatrix<double>& lower, const double* inverseD, Index begin, Index end,
                     double* y) {
  const int* outer = lower.outerIndexPtr();
  const int* inner = lower.innerIndexPtr();
  const double* value = lower.valuePtr();
  for (Index j = end - 1; j >= begin; --j) {
    Row s0 = {0, 0, 0, 0}, s1 = s0, s2 = s0, s3 = s0;
    const int first = outer[j];
    int p = outer[j + 1] - 1;
    for (; p - 3 >= first; p -= 4) {
      s0 += value[p] * load(y, inner[p]);
      s1 += value[p - 1] * load(y, inner[p - 1]);
      s2 += value[p - 2] * load(y, inner[p - 2]);
      s3 += value[p - 3] * load(y, inner[p - 3]);
    }
    for (; p >= first; --p) s0 += value[p] * load(y, inner[p]);
    store(y, j, load(y, j) * inverseD[j] - ((s0 + s1) + (s2 + s3)));
  }
}

}  // namespace

template <class S>
void SpringLaplacianSolver<S>::solve(const Factor& f, const Executor& exec) {
  const Index n = n_;
  const Index a = f.split[0], b = f.split[1];
  double* y = work_.data();
  const double* inverseD = f.inverseD.data();
  // L y = b: the two independent ranges, each also summing the top rows' terms from its own
  // columns (into border_), then the top rows: y - first task's sum - second's - their own.
  const int* outer = f.rows.outerIndexPtr();
  const int* inner = f.rows.innerIndexPtr();
  const double* value = f.rows.valuePtr();
  const Index top = n - b;
  double* border = border_.data();  // per top row: the first task's sum, then the second's
  exec.parallelFor(2, 1, [&](Index task, Index) {
    forwardRows(f.rows, task == 0 ? 0 : a, task == 0 ? a : b, y);
    for (Index k = 0; k < top; ++k) {
      const int begin = task == 0 ? outer[b + k] : f.cuts[static_cast<size_t>(2 * k)];
      store(border, 2 * k + task, rowSum(inner, value, begin, f.cuts[static_cast<size_t>(2 * k + task)], y));
    }
  });
  for (Index k = 0; k < top; ++k) {
    const Index i = b + k;
    const Row own = rowSum(inner, value, f.cuts[static_cast<size_t>(2 * k + 1)], outer[i + 1], y);
    store(y, i, ((load(y, i) - load(border, 2 * k)) - load(border, 2 * k + 1)) - own);
  }
  // L^T x = D^-1 y: the top range first, then the two ranges.
  backwardColumns(f.lower, inverseD, b, n, y);
  exec.parallelFor(2, 1, [&](Index task, Index) {
    if (task == 0)
      backwardColumns(f.lower, inverseD, 0, a, y);
    else
      backwardColumns(f.lower, inverseD, a, b, y);
  });
}

template class SpringLaplacianSolver<float>;
template class SpringLaplacianSolver<double>;

}  // namespace weft::detail
