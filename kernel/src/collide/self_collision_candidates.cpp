// The self-collision pass's candidate list (see weft/collide/self_collision.hpp): whether it
// still covers a chunk, gathering it (the BVH query with flat regions culled), the
// primitive pairs of each triangle pair, and its place in checkpoints.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <span>
#include <string>

#include "collide/self_collider.hpp"
#include "core/text.hpp"
#include "weft/collide/self_collision.hpp"

namespace weft {

template <class S>
std::array<double, 3> SelfCollider<S>::centroid(const Vec3Array<S>& x, const Executor& exec) {
  const Index n = model_->particleCount();
  exec.parallelForBlocks(n, kVertexGrain, [&](Index k, Index begin, Index end) {
    for (int a = 0; a < 3; ++a) {
      double sum = 0;
      for (Index i = begin; i < end; ++i) sum += static_cast<double>(x(i, a));
      blockSums_[static_cast<size_t>(k)][static_cast<size_t>(a)] = sum;
    }
  });
  std::array<double, 3> c{0, 0, 0};
  for (Index k = 0; k < Executor::blockCount(n, kVertexGrain);
       ++k)  // (in block order: the same bits on any thread count)
    for (int a = 0; a < 3; ++a) c[static_cast<size_t>(a)] += blockSums_[static_cast<size_t>(k)][static_cast<size_t>(a)];
  for (double& v : c) v /= static_cast<double>(n);
  return c;
}

template <class S>
bool SelfCollider<S>::candidatesCover(const Vec3Array<S>& x0, const Vec3Array<S>& x1, const Executor& exec) {
  if (!candidatesValid_) return false;
  const Index n = model_->particleCount();
  const Index blocks = Executor::blockCount(n, kVertexGrain);
  const auto everyBlock = [&] {
    return std::all_of(blockFlags_.begin(), blockFlags_.end(), [](std::uint8_t f) { return f != 0; });
  };
  blockFlags_.assign(static_cast<size_t>(blocks), 1);
  const Aabb<S>* box = skinBox_.data();
  exec.parallelForBlocks(n, kVertexGrain, [&](Index k, Index begin, Index end) {
    bool inside = true;
    for (int a = 0; a < 3; ++a)
      for (Index i = begin; i < end; ++i) {
        const S lo = box[i].lo[a], hi = box[i].hi[a];
        inside = inside && x0(i, a) >= lo && x0(i, a) <= hi && x1(i, a) >= lo && x1(i, a) <= hi;
      }
    blockFlags_[static_cast<size_t>(k)] = inside ? 1 : 0;
  });
  if (everyBlock()) return true;
  // Then with an offset o(s) = o0 + s (o1 - o0) taken from every vertex: how far the
  // centroid has moved since the gathering's chunk ended (a cloth that falls or is carried
  // keeps its list).
  const std::array<double, 3> c0 = centroid(x0, exec), c1 = centroid(x1, exec);
  double o0[3], o1[3];
  for (int a = 0; a < 3; ++a) {
    o0[a] = c0[static_cast<size_t>(a)] - gatheredCentroid_[static_cast<size_t>(a)];
    o1[a] = c1[static_cast<size_t>(a)] - gatheredCentroid_[static_cast<size_t>(a)];
  }
  exec.parallelForBlocks(n, kVertexGrain, [&](Index k, Index begin, Index end) {
    bool inside = true;
    for (int a = 0; a < 3; ++a)
      for (Index i = begin; i < end; ++i) {
        const double lo = static_cast<double>(box[i].lo[a]), hi = static_cast<double>(box[i].hi[a]);
        const double y0 = static_cast<double>(x0(i, a)) - o0[a], y1 = static_cast<double>(x1(i, a)) - o1[a];
        inside = inside && y0 >= lo && y0 <= hi && y1 >= lo && y1 <= hi;
      }
    blockFlags_[static_cast<size_t>(k)] = inside ? 1 : 0;
  });
  return everyBlock();
}

template <class S>
bool SelfCollider<S>::gatherCandidates(const Vec3Array<S>& x0, const Vec3Array<S>& x1, const Executor& exec,
                                       SelfCollisionStats& stats) {
  const Index n = model_->particleCount();
  exec.parallelFor(n, kVertexGrain, [&](Index begin, Index end) {
    for (Index i = begin; i < end; ++i) {
      const double cap = thickness_[static_cast<size_t>(i)];
      for (int a = 0; a < 3; ++a) {
        const double push = kPush * push_[3 * static_cast<size_t>(i) + static_cast<size_t>(a)];
        Aabb<S>& box = skinBox_[static_cast<size_t>(i)];
        box.lo[a] = std::min(x0(i, a), x1(i, a)) - static_cast<S>(skin_ + std::min(cap, std::max(0.0, -push)));
        box.hi[a] = std::max(x0(i, a), x1(i, a)) + static_cast<S>(skin_ + std::min(cap, std::max(0.0, push)));
      }
    }
  });
  bvh_.refitBoxes(skinBox_, exec);  // margin: half the thickness
  gatheredCentroid_ = centroid(x1, exec);
  const bool cull = !flat_.empty();
  if (cull) findFlatRegions(exec);
  const std::int64_t limit = static_cast<std::int64_t>(options_.maxCandidatesPerTriangle) * bvh_.triangleCount();
  if (!bvh_.selfOverlappingPairs(pairs_, scratch_, exec,
                                 cull ? std::span<const std::uint8_t>(flat_) : std::span<const std::uint8_t>(),
                                 limit)) {
    candidatesValid_ = false;  // (pairs_ is empty: the next chunk gathers)
    return false;
  }
  ++stats.rebuilds;
  stats.candidates += static_cast<std::int64_t>(pairs_.size());
  useCandidates();  // (their primitive pairs: expandBlock, in detect's pass over the blocks)
  return true;
}

template <class S>
void SelfCollider<S>::useCandidates() {
  const Index blocks = Executor::blockCount(static_cast<Index>(pairs_.size()), kGrain);
  if (static_cast<Index>(blocks_.size()) < blocks) blocks_.resize(static_cast<size_t>(blocks));
  blocksUsed_ = blocks;
  pairHit_.assign(pairs_.size(), 0);
  primitiveMask_.resize(pairs_.size());  // (each entry written by expandBlock)
  candidatesValid_ = true;
}

template <class S>
void SelfCollider<S>::expandBlock(Index blockIndex) {
  const Owned* owned = owned_.data();
  const double* th = thickness_.data();
  // A primitive pair whose skin boxes are farther apart than its thickness cannot come
  // that close while every vertex stays in its skin box.
  const Aabb<S>* box = skinBox_.data();
  const Index count = static_cast<Index>(pairs_.size());
  const Index begin = blockIndex * kGrain, end = std::min(count, begin + kGrain);
  for (Index pi = begin; pi < end; ++pi) {
    const TrianglePair pair = pairs_[static_cast<size_t>(pi)];
    const Owned& first = owned[pair.first];
    const Owned& second = owned[pair.second];
    PrimitiveMask mask = 0;
    const auto consider = [&](int bit) {
      Index v[4];
      const bool vertexTriangle = primitiveVertices(first, second, bit, v);
      // Pairs sharing a particle are not tested (a vertex of the triangle, a common end).
      if (vertexTriangle ? (v[0] == v[1] || v[0] == v[2] || v[0] == v[3])
                         : (v[0] == v[2] || v[0] == v[3] || v[1] == v[2] || v[1] == v[3]))
        return;
      if (primitiveBoxesApart(box, v, vertexTriangle ? 1 : 2, 0.5 * (th[v[0]] + th[v[3]]) * kBoxesApart)) return;
      mask = static_cast<PrimitiveMask>(mask | (1u << bit));
    };
    // Vertices owned by one triangle against the other, then edges owned by one against
    // edges owned by the other.
    for (int k = 0; k < first.vertices; ++k) consider(k);
    for (int k = 0; k < second.vertices; ++k) consider(3 + k);
    for (int ka = 0; ka < first.edges; ++ka)
      for (int kb = 0; kb < second.edges; ++kb) consider(6 + 3 * ka + kb);
    primitiveMask_[static_cast<size_t>(pi)] = mask;
  }
}

template <class S>
void SelfCollider<S>::saveCarry(ArchiveWriter& out) const {
  out.section("SELF");
  // What the list was gathered for: a list is only valid for the skin, the thicknesses and
  // the culling it was gathered with.
  out.value(skin_);
  out.value(fnv1a64(thickness_.data(), thickness_.size() * sizeof(double)));
  out.value(static_cast<std::uint8_t>(options_.cullFlatRegions ? 1 : 0));
  out.value(static_cast<std::uint8_t>(candidatesValid_ ? 1 : 0));
  out.vector(skinBox_);
  out.vector(pairs_);
  out.vector(push_);
  out.value(gatheredCentroid_);
}

template <class S>
void SelfCollider<S>::loadCarry(ArchiveReader& in) {
  in.section("SELF");
  const auto skin = in.value<double>();
  const auto thicknesses = in.value<std::uint64_t>();
  const auto cull = in.value<std::uint8_t>();
  if (skin != skin_ || thicknesses != fnv1a64(thickness_.data(), thickness_.size() * sizeof(double)) ||
      cull != (options_.cullFlatRegions ? 1 : 0))
    in.fail("written with other self-collision settings (skin " + detail::number(skin) + " m, flat regions " +
            (cull ? "culled" : "not culled") + "; this simulation: skin " + detail::number(skin_) +
            " m, flat regions " + (options_.cullFlatRegions ? "culled" : "not culled") +
            ", or other thicknesses): a checkpoint resumes the simulation that wrote it");
  bool valid = false;
  in.flag(valid, "the self-collision candidates' flag");
  in.field(skinBox_, "the self-collision skin boxes");
  if (skinBox_.size() != static_cast<size_t>(model_->particleCount()))
    in.fail("the self-collision skin boxes: " + std::to_string(skinBox_.size()) + " in the file, " +
            std::to_string(model_->particleCount()) + " particles in this simulation");
  in.field(pairs_, "the self-collision candidates");
  const Index triangles = model_->triangleCount();
  for (size_t k = 0; k < pairs_.size(); ++k) {
    const TrianglePair& p = pairs_[k];
    if (!(p.first >= 0 && p.first < p.second && p.second < triangles) || (k > 0 && !(pairs_[k - 1] < p)))
      in.fail("self-collision candidate " + std::to_string(k) + " (" + std::to_string(p.first) + ", " +
              std::to_string(p.second) + ") is not a sorted pair of the model's " + std::to_string(triangles) +
              " triangles");
  }
  for (const Aabb<S>& box : skinBox_)
    for (int a = 0; a < 3; ++a)
      if (!(std::isfinite(box.lo[a]) && std::isfinite(box.hi[a]) && box.lo[a] <= box.hi[a]))
        in.fail("the self-collision skin boxes are not finite boxes");
  in.field(push_, "the self-collision pushes");
  if (push_.size() != 3 * static_cast<size_t>(model_->particleCount()))
    in.fail("the self-collision pushes: " + std::to_string(push_.size()) + " entries in the file, 3 x " +
            std::to_string(model_->particleCount()) + " particles in this simulation");
  if (!std::all_of(push_.begin(), push_.end(), [](double p) { return std::isfinite(p); }))
    in.fail("the self-collision pushes are not finite");
  lastTouched_.clear();
  for (Index j = 0; j < model_->particleCount(); ++j)
    if (push_[3 * static_cast<size_t>(j)] != 0 || push_[3 * static_cast<size_t>(j) + 1] != 0 ||
        push_[3 * static_cast<size_t>(j) + 2] != 0)
      lastTouched_.push_back(j);
  in.field(gatheredCentroid_, "the self-collision centroid");
  if (!std::all_of(gatheredCentroid_.begin(), gatheredCentroid_.end(), [](double c) { return std::isfinite(c); }))
    in.fail("the self-collision centroid is not finite");
  useCandidates();
  for (Index k = 0; k < blocksUsed_; ++k) expandBlock(k);
  candidatesValid_ = valid;
}

template <class S>
std::size_t SelfCollider<S>::listBytes() const {
  // (shares_ is reserved to every block's contact capacity at once but holds, and
  // touches, only one pass's contacts: its size counts.)
  std::size_t total = vectorBytes(pairs_) + vectorBytes(pairHit_) + vectorBytes(blocks_) +
                      shares_.size() * sizeof(Share) + scratch_.heldBytes();
  total += vectorBytes(primitiveMask_);
  for (const Block& block : blocks_) total += vectorBytes(block.contacts);
  return total;
}

#define WEFT_INSTANTIATE_CANDIDATES(S)                                                                       \
  template std::array<double, 3> SelfCollider<S>::centroid(const Vec3Array<S>&, const Executor&);            \
  template bool SelfCollider<S>::candidatesCover(const Vec3Array<S>&, const Vec3Array<S>&, const Executor&); \
  template bool SelfCollider<S>::gatherCandidates(const Vec3Array<S>&, const Vec3Array<S>&, const Executor&, \
                                                  SelfCollisionStats&);                                      \
  template void SelfCollider<S>::useCandidates();                                                            \
  template void SelfCollider<S>::expandBlock(Index);                                                         \
  template void SelfCollider<S>::saveCarry(ArchiveWriter&) const;                                            \
  template void SelfCollider<S>::loadCarry(ArchiveReader&);                                                  \
  template std::size_t SelfCollider<S>::listBytes() const;
WEFT_INSTANTIATE_CANDIDATES(float)
WEFT_INSTANTIATE_CANDIDATES(double)
#undef WEFT_INSTANTIATE_CANDIDATES

}  // namespace weft
