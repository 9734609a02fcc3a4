#include "repulsion.hpp"

#include <algorithm>
#include <cmath>

namespace weft::detail {

namespace {

// A linear hash, cx + 181 cy + 9973 cz modulo the bucket count: neighbouring cells along x
// land in neighbouring buckets (a query's cells share cache lines), and a cloth up to 181
// cells wide and flat in a coordinate plane fills distinct buckets. (An RK4 step of the 128^2
// hanging cloth with repulsion, 1 thread, BM_Scene_EffectCost/effect:5: 4.3 ms with this
// hash, 7.2 ms with a xor of per-axis products, 9.9 ms with Fibonacci hashing, whose
// uniform scatter costs cache misses.)
inline std::uint32_t hashCell(Index cx, Index cy, Index cz, std::uint32_t mask) {
  return (static_cast<std::uint32_t>(cx) + 181u * static_cast<std::uint32_t>(cy) +
          9973u * static_cast<std::uint32_t>(cz)) &
         mask;
}

// floor(q) as a cell coordinate, clamped to +-2^30 (NaN to the lower bound), so any
// position, even a diverging one, gives a defined cell.
template <class S>
inline Index cellOf(S q) {
  const S f = std::floor(q);
  const S lo = S(-1073741824.0), hi = S(1073741824.0);
  return static_cast<Index>(f > lo ? (f < hi ? f : hi) : lo);
}

}  // namespace

template <class S>
Repulsion<S>::Repulsion(const Model<S>& model, const RepulsionEffect& effect)
    : model_(&model),
      radius_(static_cast<S>(effect.radius)),
      stiffness_(static_cast<S>(effect.stiffness)),
      inverseCell_(static_cast<S>(0.5 / effect.radius)) {
  const Index n = model.particleCount();
  std::uint32_t buckets = 1;
  while (buckets < 2u * static_cast<std::uint32_t>(n)) buckets <<= 1;
  mask_ = buckets - 1;
  cellX_.setZero(n);
  cellY_.setZero(n);
  cellZ_.setZero(n);
  bucket_.setZero(n);
  bucketStart_.assign(static_cast<size_t>(buckets) + 1, 0);
  sorted_.setZero(n);
}

template <class S>
void Repulsion<S>::prepare(const Vec3Array<S>& x, const Executor& exec) {
  const Index n = model_->particleCount();
  exec.parallelFor(n, 2048, [&](Index b, Index e) {
    for (Index i = b; i < e; ++i) {
      const Index cx = cellOf(x(i, 0) * inverseCell_), cy = cellOf(x(i, 1) * inverseCell_),
                  cz = cellOf(x(i, 2) * inverseCell_);
      cellX_[i] = cx;
      cellY_[i] = cy;
      cellZ_[i] = cz;
      bucket_[i] = static_cast<Index>(hashCell(cx, cy, cz, mask_));
    }
  });
  // Counting sort by bucket, in particle order: deterministic whatever the thread count.
  std::fill(bucketStart_.begin(), bucketStart_.end(), 0);
  for (Index i = 0; i < n; ++i) ++bucketStart_[bucket_[i] + 1];
  for (size_t k = 1; k < bucketStart_.size(); ++k) bucketStart_[k] += bucketStart_[k - 1];
  for (Index i = 0; i < n; ++i) sorted_[bucketStart_[bucket_[i]]++] = i;
  // The fill advanced each start to the next bucket's start: shift back by one bucket.
  for (size_t k = bucketStart_.size() - 1; k > 0; --k) bucketStart_[k] = bucketStart_[k - 1];
  bucketStart_[0] = 0;
}

template <class S>
void Repulsion<S>::add(Index begin, Index count, const Vec3Array<S>& x, S* ax, S* ay, S* az) const {
  const S* __restrict X = x.col(0).data();
  const S* __restrict Y = x.col(1).data();
  const S* __restrict Z = x.col(2).data();
  const S* __restrict w = model_->inverseMass().data();
  const S r = radius_, r2 = radius_ * radius_, k = stiffness_;
  for (Index t = 0; t < count; ++t) {
    const Index i = begin + t;
    if (w[i] == S(0)) continue;  // a pinned particle does not move (it still pushes others)
    const S xi = X[i], yi = Y[i], zi = Z[i];
    // Cells are 2r wide, so the ball of radius r around x_i overlaps two cells per axis:
    // its own and the neighbour on the side of the cell it is nearer to.
    const auto lower = [&](S q, Index c) { return q - static_cast<S>(c) < S(0.5) ? c - 1 : c; };
    const Index x0 = lower(xi * inverseCell_, cellX_[i]), y0 = lower(yi * inverseCell_, cellY_[i]),
                z0 = lower(zi * inverseCell_, cellZ_[i]);
    S fx = 0, fy = 0, fz = 0;
    for (Index cz = z0; cz <= z0 + 1; ++cz)
      for (Index cy = y0; cy <= y0 + 1; ++cy)
        for (Index cx = x0; cx <= x0 + 1; ++cx) {
          const std::uint32_t h = hashCell(cx, cy, cz, mask_);
          // Branch-free per candidate (which candidates are near is unpredictable): a pair
          // outside the cell, out of reach, coincident or the particle itself adds 0.
          for (Index q = bucketStart_[h]; q < bucketStart_[h + 1]; ++q) {
            const Index j = sorted_[q];
            const S ex = xi - X[j], ey = yi - Y[j], ez = zi - Z[j];
            const S d2 = ex * ex + ey * ey + ez * ez;
            // Bitwise & on purpose (no branch per test); as ints, which clang does not warn about.
            const bool near = (int(cellX_[j] == cx) & int(cellY_[j] == cy) & int(cellZ_[j] == cz) & int(d2 < r2) &
                               int(d2 > S(0))) != 0;
            const S d = std::sqrt(d2);
            const S s = near ? k * (r - d) / d : S(0);
            fx += s * ex;
            fy += s * ey;
            fz += s * ez;
          }
        }
    ax[t] += w[i] * fx;
    ay[t] += w[i] * fy;
    az[t] += w[i] * fz;
  }
}

template class Repulsion<float>;
template class Repulsion<double>;

}  // namespace weft::detail
