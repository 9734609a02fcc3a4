// Internal: the universal repulsion effect of the ForceField (see weft/effects/effects.hpp).
#pragma once

#include <vector>

#include "weft/core/parallel.hpp"
#include "weft/effects/effects.hpp"
#include "weft/model/model.hpp"

namespace weft::detail {

/// A spatial hash of cell size 2r over the particles, rebuilt by prepare() for each
/// evaluation, and the per-particle sum of the pushes of neighbours closer than r.
///
/// Cells are integer coordinates floor(x / 2r); a cell hashes (linearly, for locality) into one of
/// B buckets (B the power of two >= 2n); a counting sort in particle order lays the buckets out as one
/// array, so each bucket lists its particles in ascending index. A particle visits the 8
/// cells its ball of radius r overlaps (2 per axis: 8 hash lookups, where cells of size r
/// would need 27), and in each the bucket's particles whose cell matches (two cells
/// sharing a bucket are told apart, so no pair counts twice), in that fixed order.
template <class S>
class Repulsion {
 public:
  Repulsion(const Model<S>& model, const RepulsionEffect& effect);

  /// Rebuilds the hash for positions x: a parallel pass (cells, buckets), then a serial
  /// counting sort (O(n + B)).
  void prepare(const Vec3Array<S>& x, const Executor& exec);
  /// a_i += w_i sum_j k (r - d_ij) (x_i - x_j) / d_ij over particles [begin, begin + count);
  /// a pointers offset to `begin`.
  void add(Index begin, Index count, const Vec3Array<S>& x, S* ax, S* ay, S* az) const;

  Index bucketCount() const { return static_cast<Index>(bucketStart_.size()) - 1; }

 private:
  const Model<S>* model_;
  S radius_, stiffness_, inverseCell_;  // 1 / (2r)
  std::uint32_t mask_;  // B - 1
  IndexArray cellX_, cellY_, cellZ_;  // (n) cell coordinates of each particle
  IndexArray bucket_;                 // (n) bucket of each particle
  std::vector<Index> bucketStart_;    // (B + 1) start of each bucket in sorted_
  IndexArray sorted_;                 // (n) particles ordered by bucket, then index
};

extern template class Repulsion<float>;
extern template class Repulsion<double>;

}  // namespace weft::detail
