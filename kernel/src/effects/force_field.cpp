#include "weft/effects/force_field.hpp"

#include <algorithm>
#include <cstdint>
#include <stdexcept>

#include "weft/effects/spring_force.hpp"

namespace weft {

const char* forceStrategyName(ForceStrategy s) {
  switch (s) {
    case ForceStrategy::Auto: return "auto";
    case ForceStrategy::Gather: return "gather";
    case ForceStrategy::Coloured: return "coloured";
    case ForceStrategy::GridStencil: return "grid-stencil";
  }
  return "unknown";
}

ForceStrategy parseForceStrategy(const std::string& name) {
  if (name == "auto") return ForceStrategy::Auto;
  if (name == "gather") return ForceStrategy::Gather;
  if (name == "coloured" || name == "colored") return ForceStrategy::Coloured;
  if (name == "grid" || name == "grid-stencil") return ForceStrategy::GridStencil;
  throw std::invalid_argument("force strategy must be one of auto, gather, coloured, grid-stencil; got '" + name + "'");
}

namespace {

// The hot loops, as out-of-line functions of raw restrict-qualified pointers, so the
// compiler knows no store aliases a load. (Inlined into the parallel lambdas, GCC 12 loses
// that and falls back to scalar code; one call per block costs nothing measurable.)

// Springs [b, e) with endpoint index arrays: force on endpoint a into f[s].
template <class S>
[[gnu::noinline]] void springsIndexed(Index b, Index e, const Index* __restrict A, const Index* __restrict B, const S* __restrict x,
                    const S* __restrict y, const S* __restrict z, const S* __restrict vx, const S* __restrict vy,
                    const S* __restrict vz, const S* __restrict rest, const S* __restrict ks, const S* __restrict kd,
                    S* __restrict fx, S* __restrict fy, S* __restrict fz) {
  for (Index s = b; s < e; ++s) {
    const Index i = A[s], j = B[s];
    dampedSpringForce(x[i] - x[j], y[i] - y[j], z[i] - z[j], vx[i] - vx[j], vy[i] - vy[j], vz[i] - vz[j], rest[s],
                      ks[s], kd[s], fx[s], fy[s], fz[s]);
  }
}

// `count` springs of one grid family between particles i and i + offset, i = first + t,
// written to f[t]; pointers already offset to the first particle.
template <class S>
[[gnu::noinline]] void springsStrided(Index count, Index offset, const S* __restrict x, const S* __restrict y, const S* __restrict z,
                    const S* __restrict vx, const S* __restrict vy, const S* __restrict vz, S rest, S ks, S kd,
                    S* __restrict fx, S* __restrict fy, S* __restrict fz) {
  for (Index t = 0; t < count; ++t) {
    const Index j = t + offset;
    dampedSpringForce(x[t] - x[j], y[t] - y[j], z[t] - z[j], vx[t] - vx[j], vy[t] - vy[j], vz[t] - vz[j], rest, ks,
                      kd, fx[t], fy[t], fz[t]);
  }
}

// a_i = w_i f_i + [w_i > 0] g over [0, count); pointers offset to the first particle.
template <class S>
[[gnu::noinline]] void finishAccelerations(Index count, const S* __restrict w, const S* __restrict fx, const S* __restrict fy,
                         const S* __restrict fz, S gx, S gy, S gz, S* __restrict ax, S* __restrict ay,
                         S* __restrict az) {
  for (Index i = 0; i < count; ++i) {
    const S wi = w[i];
    const bool free = wi > S(0);
    ax[i] = wi * fx[i] + (free ? gx : S(0));
    ay[i] = wi * fy[i] + (free ? gy : S(0));
    az[i] = wi * fz[i] + (free ? gz : S(0));
  }
}

// t[i] += f[i] - f[i - offset] over [0, count), the stencil gather of one family.
template <class S>
[[gnu::noinline]] void addFamily(Index count, Index offset, const S* __restrict fx, const S* __restrict fy, const S* __restrict fz,
               S* __restrict tx, S* __restrict ty, S* __restrict tz) {
  for (Index i = 0; i < count; ++i) {
    tx[i] += fx[i] - fx[i - offset];
    ty[i] += fy[i] - fy[i - offset];
    tz[i] += fz[i] - fz[i - offset];
  }
}

template <class S>
const S* col(const Vec3Array<S>& m, int c) {
  return m.data() + c * m.rows();
}
template <class S>
S* col(Vec3Array<S>& m, int c) {
  return m.data() + c * m.rows();
}

}  // namespace

template <class S>
ForceField<S>::ForceField(const Model<S>& model, ForceStrategy strategy, const Vec3d& gravity)
    : model_(&model),
      strategy_(strategy),
      gx_(static_cast<S>(gravity.x)),
      gy_(static_cast<S>(gravity.y)),
      gz_(static_cast<S>(gravity.z)) {
  const Index n = model.particleCount();
  const Index m = model.springCount();
  const Springs<S>& sp = model.springs();
  if (strategy_ == ForceStrategy::Auto)
    strategy_ = model.grid() ? ForceStrategy::GridStencil : ForceStrategy::Gather;
  if (strategy_ == ForceStrategy::GridStencil && !model.grid())
    throw std::invalid_argument("force strategy 'grid-stencil' needs a model built as a cloth grid");

  switch (strategy_) {
    case ForceStrategy::Gather: {
      springForce_.setZero(m, 3);
      incidenceOffsets_.setZero(n + 1);
      for (Index s = 0; s < m; ++s) {
        ++incidenceOffsets_[sp.a[s] + 1];
        ++incidenceOffsets_[sp.b[s] + 1];
      }
      for (Index i = 0; i < n; ++i) incidenceOffsets_[i + 1] += incidenceOffsets_[i];
      incidence_.resize(2 * m);
      std::vector<Index> fill(incidenceOffsets_.data(), incidenceOffsets_.data() + n);
      // Springs in index order: each particle's list, and so its sum, is in a fixed order.
      for (Index s = 0; s < m; ++s) {
        incidence_[fill[sp.a[s]]++] = 2 * s;
        incidence_[fill[sp.b[s]]++] = 2 * s + 1;
      }
      break;
    }
    case ForceStrategy::Coloured: {
      // Greedy edge colouring: each spring takes the smallest colour used by neither
      // endpoint yet. At most 2 * maxDegree - 1 colours.
      std::vector<Index> degree(n, 0);
      for (Index s = 0; s < m; ++s) {
        ++degree[sp.a[s]];
        ++degree[sp.b[s]];
      }
      const Index maxDegree = n > 0 ? *std::max_element(degree.begin(), degree.end()) : 0;
      const Index words = (2 * maxDegree) / 64 + 1;
      std::vector<std::uint64_t> used(static_cast<size_t>(n) * words, 0);
      std::vector<Index> colour(m);
      Index colours = 0;
      for (Index s = 0; s < m; ++s) {
        const std::uint64_t* ua = &used[static_cast<size_t>(sp.a[s]) * words];
        const std::uint64_t* ub = &used[static_cast<size_t>(sp.b[s]) * words];
        Index c = 0;
        for (Index w = 0; w < words; ++w) {
          const std::uint64_t free = ~(ua[w] | ub[w]);
          if (free) {
            c = w * 64 + static_cast<Index>(__builtin_ctzll(free));
            break;
          }
        }
        colour[s] = c;
        used[static_cast<size_t>(sp.a[s]) * words + c / 64] |= std::uint64_t(1) << (c % 64);
        used[static_cast<size_t>(sp.b[s]) * words + c / 64] |= std::uint64_t(1) << (c % 64);
        colours = std::max(colours, c + 1);
      }
      colourOffsets_.assign(colours + 1, 0);
      for (Index s = 0; s < m; ++s) ++colourOffsets_[colour[s] + 1];
      for (Index c = 0; c < colours; ++c) colourOffsets_[c + 1] += colourOffsets_[c];
      std::vector<Index> fill(colourOffsets_.begin(), colourOffsets_.end() - 1);
      colA_.resize(m);
      colB_.resize(m);
      colRest_.resize(m);
      colKs_.resize(m);
      colKd_.resize(m);
      for (Index s = 0; s < m; ++s) {
        const Index t = fill[colour[s]]++;
        colA_[t] = sp.a[s];
        colB_[t] = sp.b[s];
        colRest_[t] = sp.restLength[s];
        colKs_[t] = sp.stiffness[s];
        colKd_[t] = sp.damping[s];
      }
      force_.setZero(n, 3);
      break;
    }
    case ForceStrategy::GridStencil: {
      const GridLayout<S>& g = *model.grid();
      stencilPad_ = 0;
      for (const GridFamily<S>& f : g.families) {
        const Index offset = f.rowOffset * g.width + f.columnOffset;
        familyOffset_.push_back(offset);
        stencilPad_ = std::max(stencilPad_, offset);
      }
      for (size_t k = 0; k < g.families.size(); ++k) familyForce_.push_back(Vec3Array<S>::Zero(stencilPad_ + n, 3));
      break;
    }
    case ForceStrategy::Auto: break;
  }
}

template <class S>
void ForceField<S>::accelerations(const Vec3Array<S>& x, const Vec3Array<S>& v, Vec3Array<S>& a,
                                  const Executor& exec) {
  switch (strategy_) {
    case ForceStrategy::Gather: gatherForces(x, v, a, exec); break;
    case ForceStrategy::Coloured: colouredForces(x, v, a, exec); break;
    case ForceStrategy::GridStencil: stencilForces(x, v, a, exec); break;
    case ForceStrategy::Auto: break;
  }
}

template <class S>
void ForceField<S>::gatherForces(const Vec3Array<S>& x, const Vec3Array<S>& v, Vec3Array<S>& a,
                                 const Executor& exec) {
  const Springs<S>& sp = model_->springs();
  exec.parallelFor(sp.count(), kSpringGrain, [&](Index b, Index e) {
    springsIndexed(b, e, sp.a.data(), sp.b.data(), col(x, 0), col(x, 1), col(x, 2), col(v, 0), col(v, 1), col(v, 2),
                   sp.restLength.data(), sp.stiffness.data(), sp.damping.data(), col(springForce_, 0),
                   col(springForce_, 1), col(springForce_, 2));
  });
  exec.parallelFor(model_->particleCount(), kParticleGrain, [&](Index b, Index e) {
    const Index* __restrict off = incidenceOffsets_.data();
    const Index* __restrict inc = incidence_.data();
    const S* __restrict w = model_->inverseMass().data();
    const S* __restrict Fx = col(springForce_, 0);
    const S* __restrict Fy = col(springForce_, 1);
    const S* __restrict Fz = col(springForce_, 2);
    S* __restrict ax = col(a, 0);
    S* __restrict ay = col(a, 1);
    S* __restrict az = col(a, 2);
    const S gx = gx_, gy = gy_, gz = gz_;
    for (Index i = b; i < e; ++i) {
      S fx = 0, fy = 0, fz = 0;
      for (Index k = off[i]; k < off[i + 1]; ++k) {
        const Index s = inc[k] >> 1;
        const S sign = (inc[k] & 1) ? S(-1) : S(1);
        fx += sign * Fx[s];
        fy += sign * Fy[s];
        fz += sign * Fz[s];
      }
      const S wi = w[i];
      const bool free = wi > S(0);
      ax[i] = wi * fx + (free ? gx : S(0));
      ay[i] = wi * fy + (free ? gy : S(0));
      az[i] = wi * fz + (free ? gz : S(0));
    }
  });
}

template <class S>
void ForceField<S>::colouredForces(const Vec3Array<S>& x, const Vec3Array<S>& v, Vec3Array<S>& a,
                                   const Executor& exec) {
  const Index n = model_->particleCount();
  exec.parallelFor(n, kParticleGrain, [&](Index b, Index e) { force_.middleRows(b, e - b).setZero(); });
  for (Index c = 0; c + 1 < static_cast<Index>(colourOffsets_.size()); ++c) {
    const Index first = colourOffsets_[c];
    exec.parallelFor(colourOffsets_[c + 1] - first, kSpringGrain, [&](Index b, Index e) {
      const Index* __restrict A = colA_.data();
      const Index* __restrict B = colB_.data();
      const S* __restrict rest = colRest_.data();
      const S* __restrict ks = colKs_.data();
      const S* __restrict kd = colKd_.data();
      const S *__restrict X = col(x, 0), *__restrict Y = col(x, 1), *__restrict Z = col(x, 2);
      const S *__restrict VX = col(v, 0), *__restrict VY = col(v, 1), *__restrict VZ = col(v, 2);
      S *__restrict FX = col(force_, 0), *__restrict FY = col(force_, 1), *__restrict FZ = col(force_, 2);
      // Within a colour no two springs share a particle, so these scatters never collide.
      for (Index s = first + b; s < first + e; ++s) {
        const Index i = A[s], j = B[s];
        S fx, fy, fz;
        dampedSpringForce(X[i] - X[j], Y[i] - Y[j], Z[i] - Z[j], VX[i] - VX[j], VY[i] - VY[j], VZ[i] - VZ[j], rest[s],
                          ks[s], kd[s], fx, fy, fz);
        FX[i] += fx;
        FY[i] += fy;
        FZ[i] += fz;
        FX[j] -= fx;
        FY[j] -= fy;
        FZ[j] -= fz;
      }
    });
  }
  const S* w = model_->inverseMass().data();
  exec.parallelFor(n, kParticleGrain, [&](Index b, Index e) {
    finishAccelerations(e - b, w + b, col(force_, 0) + b, col(force_, 1) + b, col(force_, 2) + b, gx_, gy_, gz_,
                        col(a, 0) + b, col(a, 1) + b, col(a, 2) + b);
  });
}

template <class S>
void ForceField<S>::stencilForces(const Vec3Array<S>& x, const Vec3Array<S>& v, Vec3Array<S>& a,
                                  const Executor& exec) {
  const GridLayout<S>& g = *model_->grid();
  const Index W = g.width, H = g.height, n = model_->particleCount();
  const Index familyCount = static_cast<Index>(g.families.size());
  const Index pad = stencilPad_;

  // Pass 1: per family, the force of the spring whose first endpoint is particle i, into
  // slot pad + i. Row blocks of about kSpringGrain springs (all families together).
  const Index rowsPerBlock = std::max<Index>(1, kSpringGrain / std::max<Index>(1, W * familyCount));
  exec.parallelFor(H, rowsPerBlock, [&](Index r0, Index r1) {
    for (Index k = 0; k < familyCount; ++k) {
      const GridFamily<S>& f = g.families[k];
      const Index c0 = std::max<Index>(0, -f.columnOffset), c1 = std::min<Index>(W, W - f.columnOffset);
      Vec3Array<S>& Fk = familyForce_[k];
      for (Index r = r0; r < std::min<Index>(r1, H - f.rowOffset); ++r) {
        const Index i = r * W + c0;
        springsStrided(c1 - c0, familyOffset_[k], col(x, 0) + i, col(x, 1) + i, col(x, 2) + i, col(v, 0) + i,
                       col(v, 1) + i, col(v, 2) + i, f.restLength, f.stiffness, f.damping, col(Fk, 0) + pad + i,
                       col(Fk, 1) + pad + i, col(Fk, 2) + pad + i);
      }
    }
  });

  // Pass 2: each particle sums +f over the springs it starts and -f over those it ends,
  // family by family (a fixed order), in chunks that stay in L1; then a = w f + g.
  const S* w = model_->inverseMass().data();
  exec.parallelFor(n, kParticleGrain, [&](Index b, Index e) {
    constexpr Index kChunk = 256;
    alignas(64) S tx[kChunk], ty[kChunk], tz[kChunk];
    for (Index c0 = b; c0 < e; c0 += kChunk) {
      const Index len = std::min<Index>(kChunk, e - c0);
      std::fill_n(tx, len, S(0));
      std::fill_n(ty, len, S(0));
      std::fill_n(tz, len, S(0));
      for (Index k = 0; k < familyCount; ++k) {
        const Vec3Array<S>& Fk = familyForce_[k];
        addFamily(len, familyOffset_[k], col(Fk, 0) + pad + c0, col(Fk, 1) + pad + c0, col(Fk, 2) + pad + c0, tx, ty,
                  tz);
      }
      finishAccelerations(len, w + c0, tx, ty, tz, gx_, gy_, gz_, col(a, 0) + c0, col(a, 1) + c0, col(a, 2) + c0);
    }
  });
}

template class ForceField<float>;
template class ForceField<double>;

}  // namespace weft
