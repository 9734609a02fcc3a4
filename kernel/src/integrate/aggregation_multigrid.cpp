#include "aggregation_multigrid.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "row_blocks.hpp"

namespace weft::detail {

namespace {

// Pairwise matching (Notay 2010, without the strength threshold): in index order, each
// unmatched active node is paired with the unmatched active neighbour it is most strongly
// coupled to (the sum of the links between them; ties to the lower index), or left alone.
// Returns the pair of each node (-1: inactive) and the number of pairs.
template <class Link>
Index matchPairs(Index n, const std::vector<char>& active, const std::vector<Link>& links, std::vector<Index>& pairOf) {
  std::vector<Index> offset(static_cast<size_t>(n) + 1, 0);
  for (const Link& l : links)
    if (l.u != l.v && active[static_cast<size_t>(l.u)] && active[static_cast<size_t>(l.v)]) {
      ++offset[static_cast<size_t>(l.u) + 1];
      ++offset[static_cast<size_t>(l.v) + 1];
    }
  for (Index i = 0; i < n; ++i) offset[static_cast<size_t>(i) + 1] += offset[static_cast<size_t>(i)];
  std::vector<Index> neighbour(static_cast<size_t>(offset.back()));
  std::vector<double> strength(neighbour.size());
  std::vector<Index> fill(offset.begin(), offset.end() - 1);
  for (const Link& l : links)
    if (l.u != l.v && active[static_cast<size_t>(l.u)] && active[static_cast<size_t>(l.v)]) {
      const auto pu = static_cast<size_t>(fill[static_cast<size_t>(l.u)]++);
      const auto pv = static_cast<size_t>(fill[static_cast<size_t>(l.v)]++);
      neighbour[pu] = l.v;
      strength[pu] = l.strength;
      neighbour[pv] = l.u;
      strength[pv] = l.strength;
    }
  pairOf.assign(static_cast<size_t>(n), -1);
  std::vector<double> total(static_cast<size_t>(n), 0.0);  // strength to each neighbour of the node at hand
  Index pairs = 0;
  for (Index i = 0; i < n; ++i) {
    if (!active[static_cast<size_t>(i)] || pairOf[static_cast<size_t>(i)] >= 0) continue;
    const auto begin = static_cast<size_t>(offset[static_cast<size_t>(i)]);
    const auto end = static_cast<size_t>(offset[static_cast<size_t>(i) + 1]);
    for (size_t p = begin; p < end; ++p) total[static_cast<size_t>(neighbour[p])] += strength[p];
    Index best = -1;
    double bestStrength = 0;
    for (size_t p = begin; p < end; ++p) {
      const Index j = neighbour[p];
      const double w = total[static_cast<size_t>(j)];
      if (pairOf[static_cast<size_t>(j)] >= 0) continue;
      if (best < 0 || w > bestStrength || (w == bestStrength && j < best)) {
        best = j;
        bestStrength = w;
      }
    }
    for (size_t p = begin; p < end; ++p) total[static_cast<size_t>(neighbour[p])] = 0;
    pairOf[static_cast<size_t>(i)] = pairs;
    if (best >= 0) pairOf[static_cast<size_t>(best)] = pairs;
    ++pairs;
  }
  return pairs;
}

// The stencil product of a grid level over slots [0, count) (pointers offset to the first):
// y = G x (G: ground blocks, 6 entries each with stride n), then for each direction
// y += B_i (x_i - x_{i+o}) - B_{i-o} (x_{i-o} - x_i), directions in order. Contiguous loads
// only; every slot sums in the same order whatever the blocks, so any split into blocks
// gives the same bits.
[[gnu::noinline]] void stencilGround(Index count, Index n, const double* __restrict G, const double* __restrict x,
                                     const double* __restrict y, const double* __restrict z, double* __restrict ox,
                                     double* __restrict oy, double* __restrict oz) {
  const double *xx = G, *yy = G + n, *zz = G + 2 * n, *xy = G + 3 * n, *xz = G + 4 * n, *yz = G + 5 * n;
  for (Index i = 0; i < count; ++i) {
    ox[i] = xx[i] * x[i] + xy[i] * y[i] + xz[i] * z[i];
    oy[i] = xy[i] * x[i] + yy[i] * y[i] + yz[i] * z[i];
    oz[i] = xz[i] * x[i] + yz[i] * y[i] + zz[i] * z[i];
  }
}

[[gnu::noinline]] void stencilDirection(Index count, Index n, Index o, const double* __restrict B,
                                        const double* __restrict x, const double* __restrict y,
                                        const double* __restrict z, double* __restrict ox, double* __restrict oy,
                                        double* __restrict oz) {
  const double *xx = B, *yy = B + n, *zz = B + 2 * n, *xy = B + 3 * n, *xz = B + 4 * n, *yz = B + 5 * n;
  for (Index i = 0; i < count; ++i) {
    const double ux = x[i] - x[i + o], uy = y[i] - y[i + o], uz = z[i] - z[i + o];
    const double vx = x[i - o] - x[i], vy = y[i - o] - y[i], vz = z[i - o] - z[i];
    const Index j = i - o;
    ox[i] += (xx[i] * ux + xy[i] * uy + xz[i] * uz) - (xx[j] * vx + xy[j] * vy + xz[j] * vz);
    oy[i] += (xy[i] * ux + yy[i] * uy + yz[i] * uz) - (xy[j] * vx + yy[j] * vy + yz[j] * vz);
    oz[i] += (xz[i] * ux + yz[i] * uy + zz[i] * uz) - (xz[j] * vx + yz[j] * vy + zz[j] * vz);
  }
}

// Scatters a block into 6 arrays of stride n at slot i.
void storeBlock(double* to, Index n, Index i, const SymmetricBlock& m) {
  to[i] = m.xx;
  to[n + i] = m.yy;
  to[2 * n + i] = m.zz;
  to[3 * n + i] = m.xy;
  to[4 * n + i] = m.xz;
  to[5 * n + i] = m.yz;
}

// A cycle's per-node passes (sweeps and prolongations, on the fine and the coarse levels),
// as out-of-line loops over restrict pointers (offset to the first node) so that they
// vectorise; the same arithmetic, in the same order, as one node at a time. `inv` holds a
// level's smoother block inverses as six arrays of stride `stride` (xx yy zz xy xz yz; zero
// on pinned particles and empty slots).

// (d0, d1, d2) = w D_i^-1 (t0, t1, t2).
inline void smoothingStep(const double* __restrict inv, Index stride, Index i, double w, double t0, double t1,
                          double t2, double& d0, double& d1, double& d2) {
  const double xx = inv[i], yy = inv[stride + i], zz = inv[2 * stride + i];
  const double xy = inv[3 * stride + i], xz = inv[4 * stride + i], yz = inv[5 * stride + i];
  d0 = (xx * t0 + xy * t1 + xz * t2) * w;
  d1 = (xy * t0 + yy * t1 + yz * t2) * w;
  d2 = (xz * t0 + yz * t1 + zz * t2) * w;
}

// t = r - y on free particles, 0 on pinned ones (one axis).
template <class S>
[[gnu::noinline]] void freeDifference(Index count, const char* __restrict free, const S* __restrict r,
                                      const S* __restrict y, S* __restrict t) {
  for (Index i = 0; i < count; ++i) t[i] = free[i] != 0 ? r[i] - y[i] : S(0);
}

// z = x + w D^-1 (r - y) on free particles, 0 on pinned ones.
template <class S>
[[gnu::noinline]] void smoothAfter(Index count, const char* __restrict free, const double* __restrict inv, Index stride,
                                   double w, const S* __restrict r0, const S* __restrict r1, const S* __restrict r2,
                                   const S* __restrict y0, const S* __restrict y1, const S* __restrict y2,
                                   const S* __restrict x0, const S* __restrict x1, const S* __restrict x2,
                                   S* __restrict z0, S* __restrict z1, S* __restrict z2) {
  for (Index i = 0; i < count; ++i) {
    double d0, d1, d2;
    smoothingStep(inv, stride, i, w, static_cast<double>(r0[i] - y0[i]), static_cast<double>(r1[i] - y1[i]),
                  static_cast<double>(r2[i] - y2[i]), d0, d1, d2);
    const bool isFree = free[i] != 0;
    z0[i] = isFree ? static_cast<S>(static_cast<double>(x0[i]) + d0) : S(0);
    z1[i] = isFree ? static_cast<S>(static_cast<double>(x1[i]) + d1) : S(0);
    z2[i] = isFree ? static_cast<S>(static_cast<double>(x2[i]) + d2) : S(0);
  }
}

// A sweep: z = x + w D^-1 t, or w D^-1 t (kFromZero; x unused), t read as double and z
// rounded to Out (the fine level's first sweep reads r and writes x in the model's precision).
template <bool kFromZero, class In, class Out>
[[gnu::noinline]] void smoothSlots(Index count, const double* __restrict inv, Index stride, double w,
                                   const In* __restrict t0, const In* __restrict t1, const In* __restrict t2,
                                   const Out* __restrict x0, const Out* __restrict x1, const Out* __restrict x2,
                                   Out* __restrict z0, Out* __restrict z1, Out* __restrict z2) {
  for (Index i = 0; i < count; ++i) {
    double d0, d1, d2;
    smoothingStep(inv, stride, i, w, static_cast<double>(t0[i]), static_cast<double>(t1[i]), static_cast<double>(t2[i]),
                  d0, d1, d2);
    if constexpr (kFromZero) {
      z0[i] = static_cast<Out>(d0);
      z1[i] = static_cast<Out>(d1);
      z2[i] = static_cast<Out>(d2);
    } else {
      z0[i] = static_cast<Out>(static_cast<double>(x0[i]) + d0);
      z1[i] = static_cast<Out>(static_cast<double>(x1[i]) + d1);
      z2[i] = static_cast<Out>(static_cast<double>(x2[i]) + d2);
    }
  }
}

// Prolongation onto [0, count): x_i += scale (y_a + s_a), a = aggregate[i] (kSaved; else
// x_i += scale y_a), where a >= 0; y and s are the coarse level's axis arrays.
template <bool kSaved, class S>
[[gnu::noinline]] void prolongate(Index count, const Index* __restrict aggregate, double scale,
                                  const double* __restrict y0, const double* __restrict y1, const double* __restrict y2,
                                  const double* __restrict s0, const double* __restrict s1, const double* __restrict s2,
                                  S* __restrict x0, S* __restrict x1, S* __restrict x2) {
  for (Index i = 0; i < count; ++i) {
    const Index a = aggregate[i];
    if (a < 0) continue;
    const double c0 = kSaved ? y0[a] + s0[a] : y0[a];
    const double c1 = kSaved ? y1[a] + s1[a] : y1[a];
    const double c2 = kSaved ? y2[a] + s2[a] : y2[a];
    x0[i] = static_cast<S>(static_cast<double>(x0[i]) + scale * c0);
    x1[i] = static_cast<S>(static_cast<double>(x1[i]) + scale * c1);
    x2[i] = static_cast<S>(static_cast<double>(x2[i]) + scale * c2);
  }
}

}  // namespace

template <class S>
AggregationMultigrid<S>::AggregationMultigrid(const Model<S>& model, bool stencil)
    : model_(&model),
      n_(model.particleCount()),
      free_(static_cast<size_t>(model.particleCount())),
      fineInverse_(6 * static_cast<size_t>(model.particleCount()), 0.0),
      x_(model.particleCount(), 3),
      t_(model.particleCount(), 3) {
  x_.setZero();
  t_.setZero();
  for (Index i = 0; i < n_; ++i) free_[static_cast<size_t>(i)] = model.isPinned(i) ? 0 : 1;
  const Springs<S>& sp = model.springs();
  std::vector<Link> links(static_cast<size_t>(sp.count()));
  for (Index s = 0; s < sp.count(); ++s)
    links[static_cast<size_t>(s)] = {sp.a[s], sp.b[s], static_cast<double>(sp.stiffness[s])};
  Index gridWidth = 0;
  std::vector<Index> row, column;
  if (const auto& grid = model.grid(); grid && grid->width > 0 && grid->width * grid->height == n_) {
    gridWidth = grid->width;
    row.resize(static_cast<size_t>(n_));
    column.resize(static_cast<size_t>(n_));
    for (Index i = 0; i < n_; ++i) {
      row[static_cast<size_t>(i)] = i / gridWidth;
      column[static_cast<size_t>(i)] = i % gridWidth;
    }
  }
  Index n = n_;
  std::vector<char> free = free_;
  for (;;) {
    std::vector<Link> coarseLinks;
    Level level = buildLevel(n, free, links, gridWidth, row, column, stencil);
    if (level.active == 0) break;
    // Coarse edges link this level to the next; their strengths are the summed springs'.
    coarseLinks.reserve(level.edgeU.size());
    for (size_t e = 0; e < level.edgeU.size(); ++e) {
      double strength = 0;
      for (Index p = level.linkOffset[e]; p < level.linkOffset[e + 1]; ++p)
        strength += links[static_cast<size_t>(level.links[static_cast<size_t>(p)])].strength;
      coarseLinks.push_back({level.edgeU[e], level.edgeV[e], strength});
    }
    const Index coarse = level.active;
    Index freeNodes = 0;
    for (const char f : free) freeNodes += f ? 1 : 0;
    levels_.push_back(std::move(level));
    // A level that does not at least halve its nodes ends the hierarchy: the W-cycle visits
    // level k 2^k times, so its cost stays linear only while every level halves.
    if (coarse <= kCoarsestNodes || 2 * coarse > freeNodes || levels_.size() >= 24) break;
    n = levels_.back().n;
    free.assign(static_cast<size_t>(n), 0);
    for (Index a = 0; a < n; ++a)
      free[static_cast<size_t>(a)] =
          levels_.back().memberOffset[static_cast<size_t>(a) + 1] > levels_.back().memberOffset[static_cast<size_t>(a)]
              ? 1
              : 0;
    links = std::move(coarseLinks);
    gridWidth = levels_.back().gridWidth;
    row = levels_.back().row;
    column = levels_.back().column;
  }
  for (Level& l : levels_) {
    const auto nodes = static_cast<size_t>(l.n);
    l.ground.assign(nodes, SymmetricBlock{});
    l.diagonal.assign(nodes, SymmetricBlock{});
    l.inverse.assign(6 * nodes, 0.0);
    l.edge.assign(l.edgeU.size(), SymmetricBlock{});
    l.b.assign(3 * nodes, 0.0);
    l.x.assign(3 * nodes, 0.0);
    l.t.assign(3 * nodes, 0.0);
    l.saved.assign(3 * nodes, 0.0);
    l.next.assign(3 * nodes, 0.0);
    l.g.assign(3 * l.edgeU.size(), 0.0);
    if (l.stencil) {
      l.stencilBlocks.assign(4 * 6 * nodes, 0.0);
      l.groundBlocks.assign(6 * nodes, 0.0);
    }
  }
  if (!levels_.empty() && levels_.back().active <= kDenseNodes) {
    denseCoarsest_ = true;
    const Level& last = levels_.back();
    for (Index a = 0; a < last.n; ++a)
      if (last.memberOffset[static_cast<size_t>(a) + 1] > last.memberOffset[static_cast<size_t>(a)])
        denseNode_.push_back(a);
    const size_t m = 3 * denseNode_.size();
    dense_.assign(m * m + m, 0.0);
    denseRhs_.assign(m, 0.0);
  }
}

template <class S>
typename AggregationMultigrid<S>::Level AggregationMultigrid<S>::buildLevel(
    Index n, const std::vector<char>& free, const std::vector<Link>& links, Index gridWidth,
    const std::vector<Index>& row, const std::vector<Index>& column, bool stencil) const {
  Level level;
  level.aggregateOf.assign(static_cast<size_t>(n), -1);
  if (gridWidth > 0) {  // 2 x 2 blocks of the grid, in slots of a padded rectangle
    const Index width = (gridWidth + 1) / 2, stride = width + 2;
    Index rows = 0;
    for (Index i = 0; i < n; ++i)
      if (free[static_cast<size_t>(i)]) rows = std::max(rows, row[static_cast<size_t>(i)] / 2 + 1);
    level.n = (rows + 2) * stride;
    level.row.assign(static_cast<size_t>(level.n), -1);
    level.column.assign(static_cast<size_t>(level.n), -1);
    for (Index r = 0; r < rows; ++r)
      for (Index c = 0; c < width; ++c) {
        level.row[static_cast<size_t>((r + 1) * stride + c + 1)] = r;
        level.column[static_cast<size_t>((r + 1) * stride + c + 1)] = c;
      }
    for (Index i = 0; i < n; ++i) {
      if (!free[static_cast<size_t>(i)]) continue;
      const Index r = row[static_cast<size_t>(i)] / 2, c = column[static_cast<size_t>(i)] / 2;
      level.aggregateOf[static_cast<size_t>(i)] = (r + 1) * stride + c + 1;
    }
    level.gridWidth = width;
    level.stride = stride;
  } else {  // two rounds of pairwise matching
    std::vector<Index> first, second;
    const Index pairs = matchPairs(n, free, links, first);
    std::vector<Link> pairLinks;
    pairLinks.reserve(links.size());
    for (const Link& l : links) {
      if (!free[static_cast<size_t>(l.u)] || !free[static_cast<size_t>(l.v)]) continue;
      const Index a = first[static_cast<size_t>(l.u)], b = first[static_cast<size_t>(l.v)];
      if (a != b) pairLinks.push_back({a, b, l.strength});
    }
    matchPairs(pairs, std::vector<char>(static_cast<size_t>(pairs), 1), pairLinks, second);
    // Number the groups in order of their first node.
    std::vector<Index> nodeOfGroup(static_cast<size_t>(pairs), -1);
    for (Index i = 0; i < n; ++i) {
      if (!free[static_cast<size_t>(i)]) continue;
      Index& node = nodeOfGroup[static_cast<size_t>(second[static_cast<size_t>(first[static_cast<size_t>(i)])])];
      if (node < 0) node = level.n++;
      level.aggregateOf[static_cast<size_t>(i)] = node;
    }
  }
  // Members, in index order.
  level.memberOffset.assign(static_cast<size_t>(level.n) + 1, 0);
  for (Index i = 0; i < n; ++i)
    if (const Index a = level.aggregateOf[static_cast<size_t>(i)]; a >= 0)
      ++level.memberOffset[static_cast<size_t>(a) + 1];
  for (Index a = 0; a < level.n; ++a)
    level.memberOffset[static_cast<size_t>(a) + 1] += level.memberOffset[static_cast<size_t>(a)];
  level.members.resize(static_cast<size_t>(level.memberOffset.back()));
  for (Index a = 0; a < level.n; ++a)
    if (level.memberOffset[static_cast<size_t>(a) + 1] > level.memberOffset[static_cast<size_t>(a)]) ++level.active;
  {
    std::vector<Index> fill(level.memberOffset.begin(), level.memberOffset.end() - 1);
    for (Index i = 0; i < n; ++i)
      if (const Index a = level.aggregateOf[static_cast<size_t>(i)]; a >= 0)
        level.members[static_cast<size_t>(fill[static_cast<size_t>(a)]++)] = i;
  }
  // Links between groups become edges (several links may share one); links with one end
  // pinned ground the other end's group; links inside a group drop out.
  std::vector<std::tuple<Index, Index, Index>> between;
  std::vector<std::pair<Index, Index>> grounding;
  for (size_t k = 0; k < links.size(); ++k) {
    const Link& l = links[k];
    const bool fu = free[static_cast<size_t>(l.u)] != 0, fv = free[static_cast<size_t>(l.v)] != 0;
    if (fu && fv) {
      const Index a = level.aggregateOf[static_cast<size_t>(l.u)], b = level.aggregateOf[static_cast<size_t>(l.v)];
      if (a != b) between.emplace_back(std::min(a, b), std::max(a, b), static_cast<Index>(k));
    } else if (fu || fv) {
      grounding.emplace_back(level.aggregateOf[static_cast<size_t>(fu ? l.u : l.v)], static_cast<Index>(k));
    }
  }
  std::sort(between.begin(), between.end());
  level.linkOffset.push_back(0);
  for (size_t p = 0; p < between.size(); ++p) {
    const auto [a, b, k] = between[p];
    if (p == 0 || std::get<0>(between[p - 1]) != a || std::get<1>(between[p - 1]) != b) {
      if (p > 0) level.linkOffset.push_back(static_cast<Index>(p));
      level.edgeU.push_back(a);
      level.edgeV.push_back(b);
    }
    level.links.push_back(k);
  }
  if (!between.empty()) level.linkOffset.push_back(static_cast<Index>(between.size()));
  std::sort(grounding.begin(), grounding.end());
  level.groundOffset.assign(static_cast<size_t>(level.n) + 1, 0);
  for (const auto& [a, k] : grounding) ++level.groundOffset[static_cast<size_t>(a) + 1];
  for (Index a = 0; a < level.n; ++a)
    level.groundOffset[static_cast<size_t>(a) + 1] += level.groundOffset[static_cast<size_t>(a)];
  for (const auto& g : grounding) level.groundLinks.push_back(g.second);
  // Each node's edges, in edge order.
  level.incidenceOffset.assign(static_cast<size_t>(level.n) + 1, 0);
  for (size_t e = 0; e < level.edgeU.size(); ++e) {
    ++level.incidenceOffset[static_cast<size_t>(level.edgeU[e]) + 1];
    ++level.incidenceOffset[static_cast<size_t>(level.edgeV[e]) + 1];
  }
  for (Index a = 0; a < level.n; ++a)
    level.incidenceOffset[static_cast<size_t>(a) + 1] += level.incidenceOffset[static_cast<size_t>(a)];
  level.incident.resize(static_cast<size_t>(level.incidenceOffset.back()));
  {
    std::vector<Index> fill(level.incidenceOffset.begin(), level.incidenceOffset.end() - 1);
    for (size_t e = 0; e < level.edgeU.size(); ++e) {
      level.incident[static_cast<size_t>(fill[static_cast<size_t>(level.edgeU[e])]++)] = static_cast<Index>(e);
      level.incident[static_cast<size_t>(fill[static_cast<size_t>(level.edgeV[e])]++)] = ~static_cast<Index>(e);
    }
  }
  // A grid level whose edges all join a slot to a stencil neighbour (fine springs reach at
  // most two particles: on every coarse level then) takes the stencil product.
  if (stencil && level.gridWidth > 0) {
    const Index s = level.stride;
    const Index offsets[4] = {1, s - 1, s, s + 1};  // east, south-west, south, south-east
    std::copy(offsets, offsets + 4, level.offset);
    level.stencil = true;
    for (size_t e = 0; e < level.edgeU.size() && level.stencil; ++e) {
      const Index o = level.edgeV[e] - level.edgeU[e];
      const Index* d = std::find(offsets, offsets + 4, o);
      if (d == offsets + 4) {
        level.stencil = false;
      } else {
        level.stencilSlot.push_back((d - offsets) * level.n + level.edgeU[e]);
      }
    }
    if (!level.stencil) level.stencilSlot.clear();
  }
  return level;
}

template <class S>
std::vector<Index> AggregationMultigrid<S>::coarseSizes() const {
  std::vector<Index> sizes;
  for (const Level& l : levels_) sizes.push_back(l.active);
  return sizes;
}

template <class S>
void AggregationMultigrid<S>::prepare(const SpringJacobian<S>& jacobian, const Executor& exec) {
  constexpr Index kBlock = ForceField<S>::kSinkBlock;
  const Vec3Array<S>& d = jacobian.diagonal();
  const Vec3Array<S>& o = jacobian.offDiagonal();
  exec.parallelFor(n_, kBlock, [&](Index b, Index e) {
    for (Index i = b; i < e; ++i)
      storeBlock(fineInverse_.data(), n_, i,
                 free_[static_cast<size_t>(i)]
                     ? inverse(SymmetricBlock{static_cast<double>(d(i, 0)), static_cast<double>(d(i, 1)),
                                              static_cast<double>(d(i, 2)), static_cast<double>(o(i, 0)),
                                              static_cast<double>(o(i, 1)), static_cast<double>(o(i, 2))})
                     : SymmetricBlock{});
  });
  for (size_t k = 0; k < levels_.size(); ++k)
    assemble(levels_[k], k == 0 ? nullptr : &levels_[k - 1], k == 0 ? &jacobian : nullptr, exec);
  if (denseCoarsest_) factorCoarsest();
}

template <class S>
void AggregationMultigrid<S>::assemble(Level& level, const Level* finer, const SpringJacobian<S>* jacobian,
                                       const Executor& exec) {
  // The finer level's link k as a block: a spring's linearisation, or a coarse edge.
  const S* blocks = jacobian ? jacobian->blocks() : nullptr;
  auto link = [&](Index k) -> SymmetricBlock {
    if (finer) return finer->edge[static_cast<size_t>(k)];
    const S* b = blocks + 6 * static_cast<size_t>(k);
    return {static_cast<double>(b[0]), static_cast<double>(b[1]), static_cast<double>(b[2]),
            static_cast<double>(b[3]), static_cast<double>(b[4]), static_cast<double>(b[5])};
  };
  const auto edges = static_cast<Index>(level.edgeU.size());
  const Index edgeGrain = grainOf(edges, 1024);
  exec.parallelFor(edges, edgeGrain, [&](Index b, Index e) {
    for (Index k = b; k < e; ++k) {
      SymmetricBlock sum;
      for (Index p = level.linkOffset[static_cast<size_t>(k)]; p < level.linkOffset[static_cast<size_t>(k) + 1]; ++p)
        add(sum, link(level.links[static_cast<size_t>(p)]));
      level.edge[static_cast<size_t>(k)] = sum;
      if (level.stencil) {
        const Index slot = level.stencilSlot[static_cast<size_t>(k)];
        storeBlock(level.stencilBlocks.data() + (slot / level.n) * 6 * level.n, level.n, slot % level.n, sum);
      }
    }
  });
  const ScalarArray<S>& mass = model_->mass();
  const double drag = jacobian ? static_cast<double>(jacobian->dragTerm()) : 0.0;
  const Index grain = grainOf(level.n, 256);
  exec.parallelFor(level.n, grain, [&](Index b, Index e) {
    for (Index a = b; a < e; ++a) {
      const auto ua = static_cast<size_t>(a);
      SymmetricBlock g;
      for (Index p = level.memberOffset[ua]; p < level.memberOffset[ua + 1]; ++p) {
        const Index i = level.members[static_cast<size_t>(p)];
        if (finer) {
          add(g, finer->ground[static_cast<size_t>(i)]);
        } else {
          const double m = static_cast<double>(mass[i]) + drag;
          g.xx += m;
          g.yy += m;
          g.zz += m;
        }
      }
      for (Index p = level.groundOffset[ua]; p < level.groundOffset[ua + 1]; ++p)
        add(g, link(level.groundLinks[static_cast<size_t>(p)]));
      level.ground[ua] = g;
      if (level.stencil) storeBlock(level.groundBlocks.data(), level.n, a, g);
      SymmetricBlock diagonal = g;
      for (Index p = level.incidenceOffset[ua]; p < level.incidenceOffset[ua + 1]; ++p) {
        const Index code = level.incident[static_cast<size_t>(p)];
        add(diagonal, level.edge[static_cast<size_t>(code >= 0 ? code : ~code)]);
      }
      level.diagonal[ua] = diagonal;
      storeBlock(level.inverse.data(), level.n, a, inverse(diagonal));
    }
  });
}

template <class S>
void AggregationMultigrid<S>::residual(Level& level, const std::vector<double>& x, const std::vector<double>& rhs,
                                       std::vector<double>& t, std::vector<double>* smoothed, bool fromZero,
                                       const Executor& exec) {
  const Index n = level.n;
  const double* X = x.data();
  const double* B = rhs.data();
  double* T = t.data();
  double* Z = smoothed ? smoothed->data() : nullptr;
  const Index grain = grainOf(n, 256);
  // Slots [from, to): t = b - out (out = A x there, 3 rows `stride` apart), and if asked
  // the smoothed iterate x + w D^-1 t (or w D^-1 t from zero). t may be b: each slot reads
  // its own b before writing t.
  auto finish = [&](Index from, Index to, const double* out, Index stride) {
    for (int c = 0; c < 3; ++c)
      for (Index a = from; a < to; ++a) T[c * n + a] = B[c * n + a] - out[c * stride + a - from];
    if (!Z) return;
    const double* inv = level.inverse.data() + from;
    const Index m = to - from;
    if (fromZero)
      smoothSlots<true, double, double>(m, inv, n, kSmoothing, T + from, T + n + from, T + 2 * n + from, nullptr,
                                        nullptr, nullptr, Z + from, Z + n + from, Z + 2 * n + from);
    else
      smoothSlots<false, double, double>(m, inv, n, kSmoothing, T + from, T + n + from, T + 2 * n + from, X + from,
                                         X + n + from, X + 2 * n + from, Z + from, Z + n + from, Z + 2 * n + from);
  };
  if (level.stencil) {
    // Slots outside [first, last) are the ring's first and last rows (and one slot more):
    // no edge reaches them, and their product is 0.
    const Index first = level.stride + 1, last = n - level.stride - 1;
    // Each block sums into local rows and writes every output once, rather than five
    // passes over output lines it shares with the neighbouring blocks.
    exec.parallelFor(n, grain, [&](Index b, Index e) {
      constexpr Index kChunk = 256;
      alignas(64) double out[3 * kChunk];
      for (Index c0 = b; c0 < e; c0 += kChunk) {
        const Index c1 = std::min(e, c0 + kChunk);
        const Index lo = std::clamp(c0, first, last), hi = std::clamp(c1, first, last);
        std::fill_n(out, 3 * kChunk, 0.0);
        if (hi > lo) {
          const Index m = hi - lo, at = lo - c0;
          stencilGround(m, n, level.groundBlocks.data() + lo, X + lo, X + n + lo, X + 2 * n + lo, out + at,
                        out + kChunk + at, out + 2 * kChunk + at);
          for (int d = 0; d < 4; ++d)
            stencilDirection(m, n, level.offset[d], level.stencilBlocks.data() + d * 6 * n + lo, X + lo, X + n + lo,
                             X + 2 * n + lo, out + at, out + kChunk + at, out + 2 * kChunk + at);
        }
        finish(c0, c1, out, kChunk);
      }
    });
    return;
  }
  // g_e = B_e (x_u - x_v) once per edge; then (A x)_a = G_a x_a + sum of +-g over a's edges
  // (+ on the edge's u side).
  const auto edges = static_cast<Index>(level.edgeU.size());
  const Index edgeGrain = grainOf(edges, 1024);
  exec.parallelFor(edges, edgeGrain, [&](Index b, Index e) {
    for (Index k = b; k < e; ++k) {
      const Index u = level.edgeU[static_cast<size_t>(k)], v = level.edgeV[static_cast<size_t>(k)];
      const double d[3] = {X[u] - X[v], X[n + u] - X[n + v], X[2 * n + u] - X[2 * n + v]};
      multiply(level.edge[static_cast<size_t>(k)], d, level.g.data() + 3 * k);
    }
  });
  exec.parallelFor(n, grain, [&](Index b, Index e) {
    constexpr Index kChunk = 256;
    alignas(64) double out[3 * kChunk];
    for (Index c0 = b; c0 < e; c0 += kChunk) {
      const Index c1 = std::min(e, c0 + kChunk);
      for (Index a = c0; a < c1; ++a) {
        const auto ua = static_cast<size_t>(a);
        const double xa[3] = {X[a], X[n + a], X[2 * n + a]};
        double y[3];
        multiply(level.ground[ua], xa, y);
        for (Index p = level.incidenceOffset[ua]; p < level.incidenceOffset[ua + 1]; ++p) {
          const Index code = level.incident[static_cast<size_t>(p)];
          const double* g = level.g.data() + 3 * (code >= 0 ? code : ~code);
          const double sign = code >= 0 ? 1.0 : -1.0;
          y[0] += sign * g[0];
          y[1] += sign * g[1];
          y[2] += sign * g[2];
        }
        for (int c = 0; c < 3; ++c) out[c * kChunk + a - c0] = y[c];
      }
      finish(c0, c1, out, kChunk);
    }
  });
}

template <class S>
void AggregationMultigrid<S>::factorCoarsest() {
  const Level& level = levels_.back();
  const auto nodes = static_cast<Index>(denseNode_.size());
  const Index m = 3 * nodes;
  double* L = dense_.data();
  double* inversePivot = L + m * m;
  std::fill(L, L + m * m, 0.0);
  auto at = [&](Index r, Index c) -> double& { return L[r * m + c]; };  // lower triangle used
  // Slots are in increasing order in denseNode_, so an edge's u < v stays so densely.
  auto denseOf = [&](Index slot) {
    return static_cast<Index>(std::lower_bound(denseNode_.begin(), denseNode_.end(), slot) - denseNode_.begin());
  };
  for (Index k = 0; k < nodes; ++k) {
    const SymmetricBlock& d = level.diagonal[static_cast<size_t>(denseNode_[static_cast<size_t>(k)])];
    const double block[3][3] = {{d.xx, d.xy, d.xz}, {d.xy, d.yy, d.yz}, {d.xz, d.yz, d.zz}};
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c <= r; ++c) at(3 * k + r, 3 * k + c) = block[r][c];
  }
  for (size_t e = 0; e < level.edgeU.size(); ++e) {
    const SymmetricBlock& k = level.edge[e];
    const double block[3][3] = {{k.xx, k.xy, k.xz}, {k.xy, k.yy, k.yz}, {k.xz, k.yz, k.zz}};
    const Index u = denseOf(level.edgeU[e]), v = denseOf(level.edgeV[e]);  // u < v: the block sits in row v
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) at(3 * v + r, 3 * u + c) = -block[r][c];
  }
  // Cholesky, row by row; a pivot that is not positive drops its unknown (solved as 0).
  for (Index j = 0; j < m; ++j) {
    for (Index k = 0; k < j; ++k) {
      double s = at(j, k);
      for (Index p = 0; p < k; ++p) s -= at(j, p) * at(k, p);
      at(j, k) = s * inversePivot[k];
    }
    double s = at(j, j);
    for (Index p = 0; p < j; ++p) s -= at(j, p) * at(j, p);
    const double pivot = s > 0 && std::isfinite(s) ? std::sqrt(s) : 0.0;
    at(j, j) = pivot;
    inversePivot[j] = pivot > 0 ? 1.0 / pivot : 0.0;
  }
}

template <class S>
void AggregationMultigrid<S>::solveCoarsest() {
  Level& level = levels_.back();
  const auto nodes = static_cast<Index>(denseNode_.size());
  const Index m = 3 * nodes, n = level.n;
  const double* L = dense_.data();
  const double* inversePivot = L + m * m;
  double* x = denseRhs_.data();
  for (Index k = 0; k < nodes; ++k)
    for (int c = 0; c < 3; ++c) x[3 * k + c] = level.b[static_cast<size_t>(c * n + denseNode_[static_cast<size_t>(k)])];
  for (Index j = 0; j < m; ++j) {  // L y = b
    double s = x[j];
    for (Index p = 0; p < j; ++p) s -= L[j * m + p] * x[p];
    x[j] = s * inversePivot[j];
  }
  for (Index j = m - 1; j >= 0; --j) {  // L^T x = y
    double s = x[j];
    for (Index p = j + 1; p < m; ++p) s -= L[p * m + j] * x[p];
    x[j] = s * inversePivot[j];
  }
  for (Index k = 0; k < nodes; ++k)
    for (int c = 0; c < 3; ++c) level.x[static_cast<size_t>(c * n + denseNode_[static_cast<size_t>(k)])] = x[3 * k + c];
}

template <class S>
template <class Value>
void AggregationMultigrid<S>::restrictTo(Level& coarse, Value&& value, bool smooth, const Executor& exec) {
  // b_a = the sum of the finer level's residual over a's members, in member order.
  const Index n = coarse.n;
  const Index grain = grainOf(n, 256);
  exec.parallelFor(n, grain, [&](Index b, Index e) {
    for (Index a = b; a < e; ++a) {
      double sum[3] = {0, 0, 0};
      for (Index p = coarse.memberOffset[static_cast<size_t>(a)]; p < coarse.memberOffset[static_cast<size_t>(a) + 1];
           ++p) {
        const Index i = coarse.members[static_cast<size_t>(p)];
        for (int c = 0; c < 3; ++c) sum[c] += value(i, c);
      }
      for (int c = 0; c < 3; ++c) coarse.b[static_cast<size_t>(c * n + a)] = sum[c];
    }
    if (smooth) {  // the coarse cycle's first sweep, from zero: x = w D^-1 b
      const double* B = coarse.b.data();
      double* X = coarse.x.data();
      smoothSlots<true, double, double>(e - b, coarse.inverse.data() + b, n, kSmoothing, B + b, B + n + b,
                                        B + 2 * n + b, nullptr, nullptr, nullptr, X + b, X + n + b, X + 2 * n + b);
    }
  });
}

template <class S>
void AggregationMultigrid<S>::cycle(std::size_t k, const Executor& exec) {
  // On entry b holds the level's right-hand side and, unless it is solved densely, x its
  // first sweep from zero, w D^-1 b (fused into the pass that wrote b).
  Level& level = levels_[k];
  const Index n = level.n;
  const Index grain = grainOf(n, 256);
  // A sweep from x: x += w D^-1 (b - A x), t = b - A x (fused: the new x into `next`).
  auto sweep = [&] {
    residual(level, level.x, level.b, level.t, &level.next, false, exec);
    std::swap(level.x, level.next);
  };
  if (k + 1 == levels_.size()) {
    if (denseCoarsest_) {
      solveCoarsest();
    } else {  // a level that would not coarsen further: a fixed number of sweeps (symmetric)
      for (int s = 0; s < 4; ++s) sweep();
    }
    return;
  }
  for (int s = 1; s < kCoarseSweeps; ++s) sweep();
  residual(level, level.x, level.b, level.t, nullptr, false, exec);
  Level& coarse = levels_[k + 1];
  restrictTo(
      coarse, [&](Index i, int c) { return level.t[static_cast<size_t>(c * n + i)]; }, startsWithSweep(k + 1), exec);
  cycle(k + 1, exec);
  const bool exactBelow = k + 2 == levels_.size() && denseCoarsest_;
  const bool again = kCycles == 2 && !exactBelow;
  if (again) {
    // Another pass on the coarse level for its remaining residual (a W-cycle): b = b - A x
    // in place and the pass's first sweep from zero into `next` (the coarse level is not
    // solved densely here); x is kept in `saved`.
    residual(coarse, coarse.x, coarse.b, coarse.b, &coarse.next, true, exec);
    std::swap(coarse.saved, coarse.x);
    std::swap(coarse.x, coarse.next);
    cycle(k + 1, exec);
  }
  // Prolongation (with the W-cycle's kept solution added back): x += w_c P x_coarse.
  const Index cn = coarse.n;
  exec.parallelFor(n, grain, [&](Index b, Index e) {
    const double* y = coarse.x.data();
    const double* kept = coarse.saved.data();
    double* x = level.x.data();
    const Index* aggregate = coarse.aggregateOf.data() + b;
    if (again)
      prolongate<true>(e - b, aggregate, kOverCorrection, y, y + cn, y + 2 * cn, kept, kept + cn, kept + 2 * cn, x + b,
                       x + n + b, x + 2 * n + b);
    else
      prolongate<false>(e - b, aggregate, kOverCorrection, y, y + cn, y + 2 * cn, kept, kept + cn, kept + 2 * cn, x + b,
                        x + n + b, x + 2 * n + b);
  });
  for (int s = 0; s < kCoarseSweeps; ++s) sweep();
}

template <class S>
void AggregationMultigrid<S>::apply(SpringJacobian<S>& jacobian, const Vec3Array<S>& r, Vec3Array<S>& z,
                                    std::vector<double>& partials, Index block, const Executor& exec) {
  const char* free = free_.data();
  const double* inv = fineInverse_.data();
  auto col = [](auto& m, int c) { return m.data() + c * m.rows(); };
  // Pre-smoothing from zero: x = w D^-1 r.
  exec.parallelFor(n_, block, [&](Index b, Index e) {
    smoothSlots<true, S, S>(e - b, inv + b, n_, kSmoothing, col(r, 0) + b, col(r, 1) + b, col(r, 2) + b, nullptr,
                            nullptr, nullptr, col(x_, 0) + b, col(x_, 1) + b, col(x_, 2) + b);
  });
  if (!levels_.empty()) {
    // t = r - A x (filtered), restricted to the first coarse level.
    auto residual = [&](Index b, Index m, const S* ax, const S* ay, const S* az) {
      const S* y[3] = {ax, ay, az};
      for (int c = 0; c < 3; ++c) freeDifference<S>(m, free + b, col(r, c) + b, y[c], col(t_, c) + b);
    };
    jacobian.systemProduct(x_, makeSink<S>(residual), exec);
    Level& coarse = levels_.front();
    restrictTo(
        coarse, [&](Index i, int c) { return static_cast<double>(t_(i, c)); }, startsWithSweep(0), exec);
    cycle(0, exec);
    const Index cn = coarse.n;
    exec.parallelFor(n_, block, [&](Index b, Index e) {
      const double* y = coarse.x.data();
      prolongate<false>(e - b, coarse.aggregateOf.data() + b, kOverCorrection, y, y + cn, y + 2 * cn, y, y, y,
                        col(x_, 0) + b, col(x_, 1) + b, col(x_, 2) + b);
    });
  }
  // Post-smoothing: z = x + w D^-1 (r - A x), and r . z per block (per axis, vectorised, as
  // the CG's own dot products: the same order for any thread count).
  auto post = [&](Index b, Index m, const S* ax, const S* ay, const S* az) {
    smoothAfter<S>(m, free + b, inv + b, n_, kSmoothing, col(r, 0) + b, col(r, 1) + b, col(r, 2) + b, ax, ay, az,
                   col(x_, 0) + b, col(x_, 1) + b, col(x_, 2) + b, col(z, 0) + b, col(z, 1) + b, col(z, 2) + b);
    double rz = 0;
    for (int c = 0; c < 3; ++c)
      rz += (rows(r, c, b, m).template cast<double>() * rows(z, c, b, m).template cast<double>()).sum();
    partials[static_cast<size_t>(b / block)] = rz;
  };
  jacobian.systemProduct(x_, makeSink<S>(post), exec);
}

template class AggregationMultigrid<float>;
template class AggregationMultigrid<double>;

}  // namespace weft::detail
