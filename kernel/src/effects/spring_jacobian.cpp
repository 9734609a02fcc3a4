#include "weft/effects/spring_jacobian.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "incidence.hpp"
#include "stencil_gather.hpp"

namespace weft {

namespace {

template <class S>
const S* col(const Vec3Array<S>& m, int c) {
  return m.data() + c * m.rows();
}
template <class S>
S* col(Vec3Array<S>& m, int c) {
  return m.data() + c * m.rows();
}

template <class S>
bool usesGridStencil(const Model<S>& model) {
  return model.grid() && !model.grid()->families.empty();
}

// One spring's linearisation from its extent l = x_a - x_b: direction, alpha, beta,
// v = sqrt(beta + gamma) d and its block alpha I + (beta + gamma) d d^T, written at slot s
// of the per-spring arrays (see the header).
template <class S>
inline void linearizeSpring(std::size_t s, S lx, S ly, S lz, S rest, S ks, S kd, S h, S h2, S* __restrict dx,
                            S* __restrict dy, S* __restrict dz, S* __restrict alpha, S* __restrict beta,
                            S* __restrict vx, S* __restrict vy, S* __restrict vz, S* __restrict blocks) {
  const S len2 = lx * lx + ly * ly + lz * lz;
  const bool hasDirection = len2 > std::numeric_limits<S>::min();
  const S len = std::sqrt(len2);
  const S invLen = (hasDirection ? S(1) : S(0)) / (hasDirection ? len : S(1));
  // c = 1 - r / L clamped to [0, 1]; a spring of rest length 0 is linear (c = 1), even
  // at length 0; any other spring without a direction contributes nothing.
  const S c0 = S(1) - rest * invLen;
  const S c = rest == S(0) ? S(1) : hasDirection ? (c0 > S(0) ? c0 : S(0)) : S(0);
  const S ux = lx * invLen, uy = ly * invLen, uz = lz * invLen;
  const S a = h2 * ks * c, b = h2 * ks * (S(1) - c), w = b + h * kd;  // alpha, beta, beta + gamma
  dx[s] = ux;
  dy[s] = uy;
  dz[s] = uz;
  alpha[s] = a;
  beta[s] = b;
  const S root = std::sqrt(w);  // beta, gamma >= 0
  vx[s] = root * ux;
  vy[s] = root * uy;
  vz[s] = root * uz;
  S* k = blocks + 6 * s;  // xx yy zz xy xz yz
  k[0] = a + w * ux * ux;
  k[1] = a + w * uy * uy;
  k[2] = a + w * uz * uz;
  k[3] = w * ux * uy;
  k[4] = w * ux * uz;
  k[5] = w * uy * uz;
}

// Springs [b, e). (A grid variant with contiguous loads, as for the products, had the same
// minimum time on the 128^2 flag: the loop writes fourteen streams a spring.)
template <class S>
[[gnu::noinline]] void linearizeSprings(Index b, Index e, const Index* __restrict A, const Index* __restrict B,
                                        const S* __restrict x, const S* __restrict y, const S* __restrict z,
                                        const S* __restrict rest, const S* __restrict ks, const S* __restrict kd, S h,
                                        S* __restrict dx, S* __restrict dy, S* __restrict dz, S* __restrict alpha,
                                        S* __restrict beta, S* __restrict vx, S* __restrict vy, S* __restrict vz,
                                        S* __restrict blocks) {
  const S h2 = h * h;
  for (Index s = b; s < e; ++s) {
    const Index i = A[s], j = B[s];
    linearizeSpring(static_cast<std::size_t>(s), x[i] - x[j], y[i] - y[j], z[i] - z[j], rest[s], ks[s], kd[s], h, h2,
                    dx, dy, dz, alpha, beta, vx, vy, vz, blocks);
  }
}

// The stiffness product's spring block (no damping): g = alpha u + beta d (d . u).
template <class S>
inline void stiffnessBlock(S ux, S uy, S uz, S dx, S dy, S dz, S alpha, S beta, S& gx, S& gy, S& gz) {
  const S along = beta * (dx * ux + dy * uy + dz * uz);
  gx = alpha * ux + along * dx;
  gy = alpha * uy + along * dy;
  gz = alpha * uz + along * dz;
}

// Springs [b, e) of the stiffness product (stiffnessBlock), u = p_a - p_b.
template <class S>
[[gnu::noinline]] void springProducts(Index b, Index e, const Index* __restrict A, const Index* __restrict B,
                                      const S* __restrict px, const S* __restrict py, const S* __restrict pz,
                                      const S* __restrict dx, const S* __restrict dy, const S* __restrict dz,
                                      const S* __restrict alpha, const S* __restrict beta, S* __restrict gx,
                                      S* __restrict gy, S* __restrict gz) {
  for (Index s = b; s < e; ++s) {
    const Index i = A[s], j = B[s];
    stiffnessBlock(px[i] - px[j], py[i] - py[j], pz[i] - pz[j], dx[s], dy[s], dz[s], alpha[s], beta[s], gx[s], gy[s],
                   gz[s]);
  }
}

// The system product's spring block with v = sqrt(beta + gamma) d: g = alpha u + v (v . u),
// the same block alpha I + (beta + gamma) d d^T from four numbers a spring instead of six.
template <class S>
inline void scaledBlock(S ux, S uy, S uz, S vx, S vy, S vz, S alpha, S& gx, S& gy, S& gz) {
  const S along = vx * ux + vy * uy + vz * uz;
  gx = alpha * ux + along * vx;
  gy = alpha * uy + along * vy;
  gz = alpha * uz + along * vz;
}

// Springs [b, e) of the system product (scaledBlock).
template <class S>
[[gnu::noinline]] void scaledSpringProducts(Index b, Index e, const Index* __restrict A, const Index* __restrict B,
                                            const S* __restrict px, const S* __restrict py, const S* __restrict pz,
                                            const S* __restrict vx, const S* __restrict vy, const S* __restrict vz,
                                            const S* __restrict alpha, S* __restrict gx, S* __restrict gy,
                                            S* __restrict gz) {
  for (Index s = b; s < e; ++s) {
    const Index i = A[s], j = B[s];
    scaledBlock(px[i] - px[j], py[i] - py[j], pz[i] - pz[j], vx[s], vy[s], vz[s], alpha[s], gx[s], gy[s], gz[s]);
  }
}

// The same for count springs of one grid family starting at consecutive particles.
template <class S>
[[gnu::noinline]] void scaledStridedProducts(Index count, Index offset, const S* __restrict px, const S* __restrict py,
                                             const S* __restrict pz, const S* __restrict vx, const S* __restrict vy,
                                             const S* __restrict vz, const S* __restrict alpha, S* __restrict gx,
                                             S* __restrict gy, S* __restrict gz) {
  for (Index t = 0; t < count; ++t) {
    const Index j = t + offset;
    scaledBlock(px[t] - px[j], py[t] - py[j], pz[t] - pz[j], vx[t], vy[t], vz[t], alpha[t], gx[t], gy[t], gz[t]);
  }
}

// The same for count springs of one grid family starting at consecutive particles:
// u = p[t] - p[t + offset], coefficients of springs [s0, s0 + count) (pointers offset).
template <class S>
[[gnu::noinline]] void stridedProducts(Index count, Index offset, const S* __restrict px, const S* __restrict py,
                                       const S* __restrict pz, const S* __restrict dx, const S* __restrict dy,
                                       const S* __restrict dz, const S* __restrict alpha, const S* __restrict beta,
                                       S* __restrict gx, S* __restrict gy, S* __restrict gz) {
  for (Index t = 0; t < count; ++t) {
    const Index j = t + offset;
    stiffnessBlock(px[t] - px[j], py[t] - py[j], pz[t] - pz[j], dx[t], dy[t], dz[t], alpha[t], beta[t], gx[t], gy[t],
                   gz[t]);
  }
}

// y[t] += (m[t] + drag) p[t] over [0, count).
template <class S>
[[gnu::noinline]] void addMassTerm(Index count, const S* __restrict mass, S drag, const S* __restrict px,
                                   const S* __restrict py, const S* __restrict pz, S* __restrict yx, S* __restrict yy,
                                   S* __restrict yz) {
  for (Index t = 0; t < count; ++t) {
    const S mi = mass[t] + drag;
    yx[t] += mi * px[t];
    yy[t] += mi * py[t];
    yz[t] += mi * pz[t];
  }
}

// y = sum_k (g_k[i] - g_k[i - offset_k]) over K families in order (+ (m_i + drag) p_i when
// kMass) over [0, count): the same additions, in the same order, as K calls of
// addStencilFamily then addMassTerm, in one pass (g pointers at the block's first slot).
template <class S, int K, bool kMass>
[[gnu::noinline]] void gatherProducts(Index count, const S* const* g, const Index* offsets, const S* __restrict mass,
                                      S drag, const S* __restrict px, const S* __restrict py, const S* __restrict pz,
                                      S* __restrict yx, S* __restrict yy, S* __restrict yz) {
  const S* __restrict gx[K];
  const S* __restrict gy[K];
  const S* __restrict gz[K];
  Index o[K];
  for (int k = 0; k < K; ++k) {
    gx[k] = g[3 * k];
    gy[k] = g[3 * k + 1];
    gz[k] = g[3 * k + 2];
    o[k] = offsets[k];
  }
  for (Index i = 0; i < count; ++i) {
    S sx = 0, sy = 0, sz = 0;
    for (int k = 0; k < K; ++k) {
      sx += gx[k][i] - gx[k][i - o[k]];
      sy += gy[k][i] - gy[k][i - o[k]];
      sz += gz[k][i] - gz[k][i - o[k]];
    }
    if constexpr (kMass) {
      const S mi = mass[i] + drag;
      yx[i] = sx + mi * px[i];
      yy[i] = sy + mi * py[i];
      yz[i] = sz + mi * pz[i];
    } else {
      yx[i] = sx;
      yy[i] = sy;
      yz[i] = sz;
    }
  }
}

}  // namespace

template <class S>
SpringJacobian<S>::SpringJacobian(const Model<S>& model)
    : model_(&model),
      direction_(model.springCount(), 3),
      scaled_(model.springCount(), 3),
      alpha_(model.springCount()),
      beta_(model.springCount()),
      blocks_(6 * static_cast<size_t>(model.springCount()), S(0)),
      g_(usesGridStencil(model) ? 0 : model.springCount(), 3),
      diagonal_(model.particleCount(), 3),
      offDiagonal_(model.particleCount(), 3) {
  incidence_ = &model.springIncidence();  // built once per Model
  direction_.setZero();
  scaled_.setZero();
  alpha_.setZero();
  beta_.setZero();
  g_.setZero();
  diagonal_.setZero();
  offDiagonal_.setZero();
  if (usesGridStencil(model)) {
    const auto& grid = model.grid();
    for (const GridFamily<S>& f : grid->families) {
      gridOffset_.push_back(static_cast<Index>(f.rowOffset) * grid->width + f.columnOffset);
      gridPad_ = std::max(gridPad_, gridOffset_.back());
    }
    // Chunks of whole sink blocks (the rows above a chunk that its gather reaches are
    // recomputed, gridPad_ / W of them: 2 of 16 at 128^2 in double).
    const detail::StencilChunks chunks = detail::stencilChunks<S>(
        grid->width, gridPad_, ForceField<S>::kStencilChunkParticles, ForceField<S>::kSinkBlock);
    gridChunk_ = chunks.chunk;
    gridWindow_ = chunks.window;
  }
}

template <class S>
void SpringJacobian<S>::linearize(const Vec3Array<S>& x, S h, const Executor& exec, S drag) {
  dragTerm_ = h * drag;
  const Springs<S>& sp = model_->springs();
  exec.parallelFor(sp.count(), ForceField<S>::kSpringGrain, [&](Index b, Index e) {
    linearizeSprings(b, e, sp.a.data(), sp.b.data(), col(x, 0), col(x, 1), col(x, 2), sp.restLength.data(),
                     sp.stiffness.data(), sp.damping.data(), h, col(direction_, 0), col(direction_, 1),
                     col(direction_, 2), alpha_.data(), beta_.data(), col(scaled_, 0), col(scaled_, 1), col(scaled_, 2),
                     blocks_.data());
  });
  // A's diagonal block of particle i: (m_i + h c) I plus the blocks of i's springs, summed
  // in incidence order (one contiguous block of six a spring).
  exec.parallelFor(model_->particleCount(), ForceField<S>::kSinkBlock, [&](Index b, Index e) {
    const Index* __restrict off = incidence_->offsets.data();
    const Index* __restrict inc = incidence_->entries.data();
    const S* __restrict blocks = blocks_.data();
    for (Index i = b; i < e; ++i) {
      S sum[6] = {0, 0, 0, 0, 0, 0};
      for (Index k = off[i]; k < off[i + 1]; ++k) {
        const S* block = blocks + 6 * static_cast<size_t>(inc[k] >> 1);
        for (int c = 0; c < 6; ++c) sum[c] += block[c];
      }
      for (int c = 0; c < 3; ++c) {
        diagonal_(i, c) = model_->mass()[i] + dragTerm_ + sum[c];
        offDiagonal_(i, c) = sum[3 + c];
      }
    }
  });
}

template <class S>
size_t SpringJacobian<S>::windowCount(const Executor& exec) const {
  return detail::stencilWindowCount(exec, Executor::blockCount(model_->particleCount(), gridChunk_));
}

template <class S>
void SpringJacobian<S>::reserve(const Executor& exec) {
  if (gridOffset_.empty()) return;
  detail::reserveStencilWindows(gridWindows_, windowCount(exec),
                                gridOffset_.size() * 3 * static_cast<size_t>(gridWindow_));
}

template <class S>
template <bool kSystem>
void SpringJacobian<S>::gridProduct(const Vec3Array<S>& p, const AccelerationSink<S>& sink, const Executor& exec) {
  const GridLayout<S>& grid = *model_->grid();
  const Index W = grid.width, H = grid.height;
  const Index families = static_cast<Index>(grid.families.size());
  constexpr Index kBlock = ForceField<S>::kSinkBlock;
  const size_t perWindow = static_cast<size_t>(families) * 3 * static_cast<size_t>(gridWindow_);
  const size_t slots = windowCount(exec);
  reserve(exec);
  // One task per chunk of particles [b, e) (a whole number of sink blocks, so the sink sees
  // the same blocks for any chunking). Its window holds, per family and axis, the product of
  // the spring starting at each particle of the rows from that of b - gridPad_ to that of
  // e - 1 (every slot the gather below reads), after gridPad_ zeros (never written: what
  // i - offset_k reads before the grid's first particle). Springs starting in the rows above
  // the chunk are recomputed here rather than shared with the chunk above: the values are
  // bitwise the same either way, and the window stays in this core's cache (a buffer of the
  // whole grid, 144 bytes a particle in double, streamed out and back through memory: the
  // product took 1.3-1.9x this time at 256^2, docs/benchmarks.md). A window per thread, as
  // the force field's stencil has: each chunk writes every slot its gather reads.
  exec.parallelFor(model_->particleCount(), gridChunk_, [&](Index b, Index e) {
    S* window = detail::stencilWindow(gridWindows_, slots, perWindow, "SpringJacobian");
    const Index rowFirst = b > gridPad_ ? (b - gridPad_) / W : 0, rowEnd = (e - 1) / W + 1;
    // Window slot of particle i: gridPad_ + i - rowFirst W (>= 0 for every i the gather reads).
    const Index shift = gridPad_ - rowFirst * W;
    for (Index k = 0; k < families; ++k) {
      const GridFamily<S>& f = grid.families[static_cast<size_t>(k)];
      const Index c0 = std::max<Index>(0, -f.columnOffset), c1 = std::min<Index>(W, W - f.columnOffset);
      const Index count = c1 - c0, last = H - f.rowOffset;  // rows [0, last) start a spring
      S* g[3];
      for (int c = 0; c < 3; ++c) g[c] = window + (3 * k + c) * gridWindow_ + gridPad_;
      for (Index r = rowFirst; r < rowEnd; ++r) {
        const Index at = (r - rowFirst) * W;  // the row's first slot after the padding
        if (r >= last || count <= 0) {
          for (int c = 0; c < 3; ++c) std::fill_n(g[c] + at, W, S(0));
          continue;
        }
        for (int c = 0; c < 3; ++c) {
          std::fill_n(g[c] + at, c0, S(0));
          std::fill_n(g[c] + at + c1, W - c1, S(0));
        }
        const Index i = r * W + c0, s = f.firstSpring + r * count;
        if constexpr (kSystem)
          scaledStridedProducts<S>(count, gridOffset_[static_cast<size_t>(k)], col(p, 0) + i, col(p, 1) + i,
                                   col(p, 2) + i, col(scaled_, 0) + s, col(scaled_, 1) + s, col(scaled_, 2) + s,
                                   alpha_.data() + s, g[0] + at + c0, g[1] + at + c0, g[2] + at + c0);
        else
          stridedProducts<S>(count, gridOffset_[static_cast<size_t>(k)], col(p, 0) + i, col(p, 1) + i, col(p, 2) + i,
                             col(direction_, 0) + s, col(direction_, 1) + s, col(direction_, 2) + s, alpha_.data() + s,
                             beta_.data() + s, g[0] + at + c0, g[1] + at + c0, g[2] + at + c0);
      }
    }
    // Particles: +g_k[i] - g_k[i - offset_k], families in order, then the mass term.
    alignas(64) S yx[kBlock], yy[kBlock], yz[kBlock];
    for (Index j0 = b; j0 < e; j0 += kBlock) {
      const Index m = std::min<Index>(kBlock, e - j0);
      const Index slot = j0 + shift;
      const S* mass = kSystem ? model_->mass().data() + j0 : nullptr;
      if (families == 6) {
        const S* g[18];
        for (Index c = 0; c < 18; ++c) g[c] = window + c * gridWindow_ + slot;
        gatherProducts<S, 6, kSystem>(m, g, gridOffset_.data(), mass, dragTerm_, col(p, 0) + j0, col(p, 1) + j0,
                                      col(p, 2) + j0, yx, yy, yz);
      } else {  // grids without shear or bend springs
        std::fill_n(yx, m, S(0));
        std::fill_n(yy, m, S(0));
        std::fill_n(yz, m, S(0));
        for (Index k = 0; k < families; ++k)
          detail::addStencilFamily(m, gridOffset_[static_cast<size_t>(k)], window + (3 * k) * gridWindow_ + slot,
                                   window + (3 * k + 1) * gridWindow_ + slot, window + (3 * k + 2) * gridWindow_ + slot,
                                   yx, yy, yz);
        if constexpr (kSystem)
          addMassTerm(m, mass, dragTerm_, col(p, 0) + j0, col(p, 1) + j0, col(p, 2) + j0, yx, yy, yz);
      }
      sink(j0, m, yx, yy, yz);
    }
  });
}

template <class S>
template <bool kSystem>
void SpringJacobian<S>::product(const Vec3Array<S>& p, const AccelerationSink<S>& sink, const Executor& exec) {
  if (!gridOffset_.empty()) {
    gridProduct<kSystem>(p, sink, exec);
    return;
  }
  const Springs<S>& sp = model_->springs();
  exec.parallelFor(sp.count(), ForceField<S>::kSpringGrain, [&](Index b, Index e) {
    if constexpr (kSystem) {
      scaledSpringProducts<S>(b, e, sp.a.data(), sp.b.data(), col(p, 0), col(p, 1), col(p, 2), col(scaled_, 0),
                              col(scaled_, 1), col(scaled_, 2), alpha_.data(), col(g_, 0), col(g_, 1), col(g_, 2));
      return;
    }
    springProducts<S>(b, e, sp.a.data(), sp.b.data(), col(p, 0), col(p, 1), col(p, 2), col(direction_, 0),
                      col(direction_, 1), col(direction_, 2), alpha_.data(), beta_.data(), col(g_, 0), col(g_, 1),
                      col(g_, 2));
  });
  constexpr Index kBlock = ForceField<S>::kSinkBlock;
  exec.parallelFor(model_->particleCount(), kBlock, [&](Index b, Index e) {
    const Index* __restrict off = incidence_->offsets.data();
    const Index* __restrict inc = incidence_->entries.data();
    const S* __restrict mass = model_->mass().data();
    const S* __restrict Gx = col(g_, 0);
    const S* __restrict Gy = col(g_, 1);
    const S* __restrict Gz = col(g_, 2);
    const S* __restrict Px = col(p, 0);
    const S* __restrict Py = col(p, 1);
    const S* __restrict Pz = col(p, 2);
    const S dragTerm = dragTerm_;
    alignas(64) S yx[kBlock], yy[kBlock], yz[kBlock];
    for (Index i = b; i < e; ++i) {
      S sx, sy, sz;
      detail::sumIncident(off, inc, i, Gx, Gy, Gz, sx, sy, sz);
      if constexpr (kSystem) {
        const S mi = mass[i] + dragTerm;
        sx += mi * Px[i];
        sy += mi * Py[i];
        sz += mi * Pz[i];
      }
      yx[i - b] = sx;
      yy[i - b] = sy;
      yz[i - b] = sz;
    }
    sink(b, e - b, yx, yy, yz);
  });
}

template <class S>
void SpringJacobian<S>::systemProduct(const Vec3Array<S>& p, const AccelerationSink<S>& sink, const Executor& exec) {
  product<true>(p, sink, exec);
}

template <class S>
void SpringJacobian<S>::stiffnessProduct(const Vec3Array<S>& p, const AccelerationSink<S>& sink, const Executor& exec) {
  product<false>(p, sink, exec);
}

template class SpringJacobian<float>;
template class SpringJacobian<double>;

}  // namespace weft
