#include "weft/effects/force_field.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include "core/text.hpp"
#include "incidence.hpp"
#include "repulsion.hpp"
#include "stencil_gather.hpp"
#include "weft/effects/spring_force.hpp"
#include "wind.hpp"

namespace weft {

const char* forceStrategyName(ForceStrategy s) {
  switch (s) {
    case ForceStrategy::Auto:
      return "auto";
    case ForceStrategy::Gather:
      return "gather";
    case ForceStrategy::Coloured:
      return "coloured";
    case ForceStrategy::GridStencil:
      return "grid-stencil";
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
[[gnu::noinline]] void springsIndexed(Index b, Index e, const Index* __restrict A, const Index* __restrict B,
                                      const S* __restrict x, const S* __restrict y, const S* __restrict z,
                                      const S* __restrict vx, const S* __restrict vy, const S* __restrict vz,
                                      const S* __restrict rest, const S* __restrict ks, const S* __restrict kd,
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
[[gnu::noinline]] void springsStrided(Index count, Index offset, const S* __restrict x, const S* __restrict y,
                                      const S* __restrict z, const S* __restrict vx, const S* __restrict vy,
                                      const S* __restrict vz, S rest, S ks, S kd, S* __restrict fx, S* __restrict fy,
                                      S* __restrict fz) {
  for (Index t = 0; t < count; ++t) {
    const Index j = t + offset;
    dampedSpringForce(x[t] - x[j], y[t] - y[j], z[t] - z[j], vx[t] - vx[j], vy[t] - vy[j], vz[t] - vz[j], rest, ks, kd,
                      fx[t], fy[t], fz[t]);
  }
}

// a_i = w_i f_i + [w_i > 0] g over [0, count): exactly 0 for a pinned particle whenever its
// force is finite. (A select on the whole result would be NaN-proof too, but GCC 12 then
// sinks the family sums into a branch and stops vectorising the gather; a NaN force only
// occurs in a step the stability check rejects, and its report skips pinned particles.)
// Pointers offset to the first particle.
template <class S>
[[gnu::noinline]] void finishAccelerations(Index count, const S* __restrict w, const S* __restrict fx,
                                           const S* __restrict fy, const S* __restrict fz, S gx, S gy, S gz,
                                           S* __restrict ax, S* __restrict ay, S* __restrict az) {
  for (Index i = 0; i < count; ++i) {
    const S wi = w[i];
    const bool free = wi > S(0);
    ax[i] = wi * fx[i] + (free ? gx : S(0));
    ay[i] = wi * fy[i] + (free ? gy : S(0));
    az[i] = wi * fz[i] + (free ? gz : S(0));
  }
}

// a_i = w_i sum_k (f_k[i] - f_k[i - offset_k]) + [w_i > 0] g over [0, count), K families
// in one loop (K a compile-time constant so the family loop unrolls and the particle
// loop vectorises); f pointers already offset to the first particle's window slot.
template <class S, int K>
[[gnu::noinline]] void gatherFamilies(Index count, const S* const* f, const Index* offsets, const S* __restrict w, S gx,
                                      S gy, S gz, S* __restrict ax, S* __restrict ay, S* __restrict az) {
  const S* __restrict fx[K];
  const S* __restrict fy[K];
  const S* __restrict fz[K];
  Index o[K];
  for (int k = 0; k < K; ++k) {
    fx[k] = f[3 * k];
    fy[k] = f[3 * k + 1];
    fz[k] = f[3 * k + 2];
    o[k] = offsets[k];
  }
  for (Index i = 0; i < count; ++i) {
    S sx = 0, sy = 0, sz = 0;
    for (int k = 0; k < K; ++k) {
      sx += fx[k][i] - fx[k][i - o[k]];
      sy += fy[k][i] - fy[k][i - o[k]];
      sz += fz[k][i] - fz[k][i - o[k]];
    }
    const S wi = w[i];
    const bool free = wi > S(0);
    ax[i] = wi * sx + (free ? gx : S(0));
    ay[i] = wi * sy + (free ? gy : S(0));
    az[i] = wi * sz + (free ? gz : S(0));
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
ForceField<S>::ForceField(const Model<S>& model, ForceStrategy strategy, const Vec3d& gravity,
                          const ParticleEffects& effects)
    : model_(&model),
      strategy_(strategy),
      gx_(static_cast<S>(gravity.x)),
      gy_(static_cast<S>(gravity.y)),
      gz_(static_cast<S>(gravity.z)),
      effects_(effects),
      anyEffect_(effects.any()),
      drag_(static_cast<S>(effects.drag)) {
  validateEffects(effects);
  if (!(effects.drag <= std::numeric_limits<S>::max()))
    detail::rejectField("effects.drag", effects.drag, "within the range of the model's precision");
  if (effects.wind.enabled) wind_ = std::make_unique<detail::WindForce<S>>(model, effects.wind);
  if (effects.repulsion.enabled()) repulsion_ = std::make_unique<detail::Repulsion<S>>(model, effects.repulsion);
  const Index n = model.particleCount();
  const Index m = model.springCount();
  if (strategy_ == ForceStrategy::Auto) strategy_ = model.grid() ? ForceStrategy::GridStencil : ForceStrategy::Gather;
  if (strategy_ == ForceStrategy::GridStencil && !model.grid())
    throw std::invalid_argument("force strategy 'grid-stencil' needs a model built as a cloth grid");

  switch (strategy_) {
    case ForceStrategy::Gather: {
      springForce_.setZero(m, 3);
      incidence_ = &model.springIncidence();  // built once per Model
      break;
    }
    case ForceStrategy::Coloured: {
      colouring_ = &model.springColouring();  // built once per Model
      force_.setZero(n, 3);
      break;
    }
    case ForceStrategy::GridStencil: {
      const GridLayout<S>& g = *model.grid();
      for (const GridFamily<S>& f : g.families) {
        familyOffset_.push_back(f.rowOffset * g.width + f.columnOffset);
        maxRowOffset_ = std::max<Index>(maxRowOffset_, f.rowOffset);
      }
      // Rows per chunk: the chunk's window of family forces, (rows + halo) x width x
      // families x 3 scalars, stays within L2 (about 300 KB in double at 2048 particles).
      chunkRows_ = std::max<Index>(2, kStencilChunkParticles / g.width);
      // Pad each array so consecutive ones start 5 cache lines apart modulo 4 KiB: the gather
      // streams 36 of them at once, and at power-of-two strides they would all compete
      // for the same L1 set (measured 2.3x slower at 256^2 in double).
      const Index perLine = static_cast<Index>(64 / sizeof(S));
      // One slot more than a chunk's rows: a family reaching the halo's full depth and a
      // column right (the shear spring (1, 1) on a grid without bend springs) reads one slot
      // before its array for a chunk's first particle, which must then be this never-written
      // (zero) padding slot of the array before, not a force.
      windowSize_ = (chunkRows_ + maxRowOffset_) * g.width + 1;
      windowSize_ = (windowSize_ + perLine - 1) / perLine * perLine;
      const Index perPage = static_cast<Index>(4096 / sizeof(S));
      windowSize_ += ((5 * perLine - windowSize_ % perPage) % perPage + perPage) % perPage;
      // The windows themselves, one per thread, are made by reserve() or the first pass (which
      // know the executor's thread count).
      break;
    }
    case ForceStrategy::Auto:
      break;
  }
}

template <class S>
ForceField<S>::~ForceField() = default;

template <class S>
size_t ForceField<S>::stencilWindowCount(const Executor& exec) const {
  return detail::stencilWindowCount(exec, Executor::blockCount(model_->grid()->height, chunkRows_));
}

template <class S>
void ForceField<S>::reserve(const Executor& exec) {
  if (strategy_ != ForceStrategy::GridStencil) return;
  const size_t perWindow = model_->grid()->families.size() * 3 * static_cast<size_t>(windowSize_);
  detail::reserveStencilWindows(stencilWindows_, stencilWindowCount(exec), perWindow);
}

template <class S>
void ForceField<S>::accelerations(const Vec3Array<S>& x, const Vec3Array<S>& v, const AccelerationSink<S>& sink,
                                  const Executor& exec) {
  if (wind_ || repulsion_) prepareEffects(x, v, exec);
  switch (strategy_) {
    case ForceStrategy::Gather:
      gatherForces(x, v, sink, exec);
      break;
    case ForceStrategy::Coloured:
      colouredForces(x, v, sink, exec);
      break;
    case ForceStrategy::GridStencil:
      stencilForces(x, v, sink, exec);
      break;
    case ForceStrategy::Auto:
      break;
  }
}

template <class S>
void ForceField<S>::accelerations(const Vec3Array<S>& x, const Vec3Array<S>& v, Vec3Array<S>& a, const Executor& exec) {
  auto store = [&](Index b, Index count, const S* ax, const S* ay, const S* az) {
    std::copy_n(ax, count, col(a, 0) + b);
    std::copy_n(ay, count, col(a, 1) + b);
    std::copy_n(az, count, col(a, 2) + b);
  };
  accelerations(x, v, makeSink<S>(store), exec);
}

template <class S>
void ForceField<S>::gatherForces(const Vec3Array<S>& x, const Vec3Array<S>& v, const AccelerationSink<S>& sink,
                                 const Executor& exec) {
  const Springs<S>& sp = model_->springs();
  exec.parallelFor(sp.count(), kSpringGrain, [&](Index b, Index e) {
    springsIndexed(b, e, sp.a.data(), sp.b.data(), col(x, 0), col(x, 1), col(x, 2), col(v, 0), col(v, 1), col(v, 2),
                   sp.restLength.data(), sp.stiffness.data(), sp.damping.data(), col(springForce_, 0),
                   col(springForce_, 1), col(springForce_, 2));
  });
  exec.parallelFor(model_->particleCount(), kSinkBlock, [&](Index b, Index e) {
    const Index* __restrict off = incidence_->offsets.data();
    const Index* __restrict inc = incidence_->entries.data();
    const S* __restrict w = model_->inverseMass().data();
    const S* __restrict Fx = col(springForce_, 0);
    const S* __restrict Fy = col(springForce_, 1);
    const S* __restrict Fz = col(springForce_, 2);
    alignas(64) S ax[kSinkBlock], ay[kSinkBlock], az[kSinkBlock];
    const S gx = gx_, gy = gy_, gz = gz_;
    for (Index i = b; i < e; ++i) {
      S fx, fy, fz;
      detail::sumIncident(off, inc, i, Fx, Fy, Fz, fx, fy, fz);
      const S wi = w[i];
      const bool free = wi > S(0);
      ax[i - b] = wi * fx + (free ? gx : S(0));
      ay[i - b] = wi * fy + (free ? gy : S(0));
      az[i - b] = wi * fz + (free ? gz : S(0));
    }
    if (anyEffect_) applyEffects(b, e - b, x, v, ax, ay, az);
    sink(b, e - b, ax, ay, az);
  });
}

template <class S>
void ForceField<S>::colouredForces(const Vec3Array<S>& x, const Vec3Array<S>& v, const AccelerationSink<S>& sink,
                                   const Executor& exec) {
  const Index n = model_->particleCount();
  exec.parallelFor(n, kParticleGrain, [&](Index b, Index e) { force_.middleRows(b, e - b).setZero(); });
  const SpringColouring<S>& colours = *colouring_;
  for (Index c = 0; c < colours.colourCount(); ++c) {
    const Index first = colours.offsets[c];
    exec.parallelFor(colours.offsets[c + 1] - first, kSpringGrain, [&](Index b, Index e) {
      const Index* __restrict A = colours.a.data();
      const Index* __restrict B = colours.b.data();
      const S* __restrict rest = colours.restLength.data();
      const S* __restrict ks = colours.stiffness.data();
      const S* __restrict kd = colours.damping.data();
      const S* __restrict X = col(x, 0), * __restrict Y = col(x, 1), * __restrict Z = col(x, 2);
      const S* __restrict VX = col(v, 0), * __restrict VY = col(v, 1), * __restrict VZ = col(v, 2);
      S* __restrict FX = col(force_, 0), * __restrict FY = col(force_, 1), * __restrict FZ = col(force_, 2);
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
  exec.parallelFor(n, kSinkBlock, [&](Index b, Index e) {
    alignas(64) S ax[kSinkBlock], ay[kSinkBlock], az[kSinkBlock];
    finishAccelerations(e - b, w + b, col(force_, 0) + b, col(force_, 1) + b, col(force_, 2) + b, gx_, gy_, gz_, ax, ay,
                        az);
    if (anyEffect_) applyEffects(b, e - b, x, v, ax, ay, az);
    sink(b, e - b, ax, ay, az);
  });
}

template <class S>
void ForceField<S>::stencilForces(const Vec3Array<S>& x, const Vec3Array<S>& v, const AccelerationSink<S>& sink,
                                  const Executor& exec) {
  const GridLayout<S>& g = *model_->grid();
  const Index W = g.width, H = g.height;
  const Index familyCount = static_cast<Index>(g.families.size());
  const Index halo = maxRowOffset_;
  const S* w = model_->inverseMass().data();

  // One task per chunk of rows [r0, r1). Its window holds, per family and axis, the force
  // of the spring starting at each particle of rows [r0 - halo, r1) (window row 0 is row
  // r0 - halo). Springs starting in the halo rows are recomputed by this chunk rather than
  // shared with the chunk above: the values are bitwise the same either way, so results do
  // not depend on how chunks are scheduled, and the window never leaves this core's cache.
  // A window per thread, not per chunk: a thread runs one chunk at a time, and each chunk
  // writes every slot its gather reads (the family forces, and zero where there is no
  // spring), so what a window held before does not matter. Made by reserve() (a Simulation
  // calls it when built) or else by the first pass, and again only for more threads.
  const size_t perWindow = static_cast<size_t>(familyCount) * 3 * static_cast<size_t>(windowSize_);
  const size_t slots = stencilWindowCount(exec);
  reserve(exec);
  exec.parallelFor(H, chunkRows_, [&](Index r0, Index r1) {
    S* window = detail::stencilWindow(stencilWindows_, slots, perWindow, "ForceField");
    const Index span = (r1 - r0 + halo) * W;  // the slots the gather below reads
    for (Index k = 0; k < familyCount; ++k) {
      const GridFamily<S>& f = g.families[k];
      const Index c0 = std::max<Index>(0, -f.columnOffset), c1 = std::min<Index>(W, W - f.columnOffset);
      // Halo rows r0 - j only matter to families reaching j rows down (dr >= j).
      const Index first = std::max<Index>(0, r0 - f.rowOffset);
      const Index last = std::min<Index>(r1, H - f.rowOffset);
      S* fc[3];
      for (int c = 0; c < 3; ++c)
        fc[c] = window + (k * 3 + c) * windowSize_ + (halo - r0) * W;  // slot of particle i: fc + i
      if (first >= last) {  // no spring of this family starts in the chunk's rows
        for (int c = 0; c < 3; ++c) std::fill_n(window + (k * 3 + c) * windowSize_, span, S(0));
        continue;
      }
      // Zero before and after the run below: halo rows the family does not reach, the rows
      // above the grid, the boundary columns, the bottom rows without a spring.
      const Index runBegin = first * W + c0 - (r0 - halo) * W, runEnd = (last - 1) * W + c1 - (r0 - halo) * W;
      for (int c = 0; c < 3; ++c) {
        S* slot = window + (k * 3 + c) * windowSize_;
        std::fill_n(slot, runBegin, S(0));
        std::fill_n(slot + runEnd, span - runEnd, S(0));
      }
      // One flat run from (first, c0) to (last - 1, c1 - 1): a single vector loop instead
      // of one short loop (and a scalar tail of square roots) per row. The run also
      // evaluates the wrap-around pairs between rows; their slots are zeroed below.
      const Index b = first * W + c0, e = (last - 1) * W + c1;
      springsStrided(e - b, familyOffset_[k], col(x, 0) + b, col(x, 1) + b, col(x, 2) + b, col(v, 0) + b, col(v, 1) + b,
                     col(v, 2) + b, f.restLength, f.stiffness, f.damping, fc[0] + b, fc[1] + b, fc[2] + b);
      for (Index r = first + 1; r < last; ++r)
        for (Index i = (r - 1) * W + c1; i < r * W + c0; ++i) fc[0][i] = fc[1][i] = fc[2][i] = S(0);
    }
    // Gather: particle i (window slot p) takes +f_k[p] - f_k[p - offset_k], family by
    // family (a fixed order); slots without a spring hold zero, including the ones a
    // boundary column's p - offset_k wraps into. Then a = w f + g.
    const Index i0 = r0 * W, p0 = halo * W;
    alignas(64) S ax[kSinkBlock], ay[kSinkBlock], az[kSinkBlock];
    for (Index j0 = i0; j0 < r1 * W; j0 += kSinkBlock) {
      const Index len = std::min<Index>(kSinkBlock, r1 * W - j0);
      const Index p = j0 - i0 + p0;
      if (familyCount == 6) {
        const S* f[18];
        for (Index c = 0; c < 18; ++c) f[c] = window + c * windowSize_ + p;
        gatherFamilies<S, 6>(len, f, familyOffset_.data(), w + j0, gx_, gy_, gz_, ax, ay, az);
      } else {  // grids without shear or bend springs
        alignas(64) S tx[kSinkBlock], ty[kSinkBlock], tz[kSinkBlock];
        std::fill_n(tx, len, S(0));
        std::fill_n(ty, len, S(0));
        std::fill_n(tz, len, S(0));
        for (Index k = 0; k < familyCount; ++k)
          detail::addStencilFamily(len, familyOffset_[k], window + (k * 3 + 0) * windowSize_ + p,
                                   window + (k * 3 + 1) * windowSize_ + p, window + (k * 3 + 2) * windowSize_ + p, tx,
                                   ty, tz);
        finishAccelerations(len, w + j0, tx, ty, tz, gx_, gy_, gz_, ax, ay, az);
      }
      if (anyEffect_) applyEffects(j0, len, x, v, ax, ay, az);
      sink(j0, len, ax, ay, az);
    }
  });
}

namespace {
// a_i -= c w_i v_i over [0, count) (zero for pinned particles, w = 0). Pointers offset to
// the first particle.
template <class S>
[[gnu::noinline]] void addDrag(Index count, S c, const S* __restrict w, const S* __restrict vx, const S* __restrict vy,
                               const S* __restrict vz, S* __restrict ax, S* __restrict ay, S* __restrict az) {
  for (Index i = 0; i < count; ++i) {
    const S k = c * w[i];
    ax[i] -= k * vx[i];
    ay[i] -= k * vy[i];
    az[i] -= k * vz[i];
  }
}
}  // namespace

namespace {
using Clock = std::chrono::steady_clock;
std::int64_t elapsedNs(Clock::time_point since) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - since).count();
}
}  // namespace

template <class S>
void ForceField<S>::prepareEffects(const Vec3Array<S>& x, const Vec3Array<S>& v, const Executor& exec) {
  if (wind_) {
    const auto start = profiling_ ? Clock::now() : Clock::time_point{};
    wind_->prepare(x, v, time_, exec);
    if (profiling_) windNs_.fetch_add(elapsedNs(start) * exec.threadCount(), std::memory_order_relaxed);
  }
  if (repulsion_) {
    const auto start = profiling_ ? Clock::now() : Clock::time_point{};
    repulsion_->prepare(x, exec);
    if (profiling_) repulsionNs_.fetch_add(elapsedNs(start) * exec.threadCount(), std::memory_order_relaxed);
  }
}

template <class S>
void ForceField<S>::applyEffects(Index begin, Index count, const Vec3Array<S>& x, const Vec3Array<S>& v, S* ax, S* ay,
                                 S* az) const {
  auto timed = [&](std::atomic<std::int64_t>& ns, auto&& body) {
    if (!profiling_) return body();
    const auto start = Clock::now();
    body();
    ns.fetch_add(elapsedNs(start), std::memory_order_relaxed);
  };
  if (effects_.drag != 0)
    timed(dragNs_, [&] {
      addDrag(count, drag_, model_->inverseMass().data() + begin, col(v, 0) + begin, col(v, 1) + begin,
              col(v, 2) + begin, ax, ay, az);
    });
  if (wind_) timed(windNs_, [&] { wind_->add(begin, count, ax, ay, az); });
  if (repulsion_) timed(repulsionNs_, [&] { repulsion_->add(begin, count, x, ax, ay, az); });
}

template <class S>
EffectTimes ForceField<S>::effectTimes() const {
  EffectTimes t;
  t.drag = 1e-9 * static_cast<double>(dragNs_.load(std::memory_order_relaxed));
  t.wind = 1e-9 * static_cast<double>(windNs_.load(std::memory_order_relaxed));
  t.repulsion = 1e-9 * static_cast<double>(repulsionNs_.load(std::memory_order_relaxed));
  return t;
}

template <class S>
Vec3d ForceField<S>::airVelocity(const Vec3d& x, double time) const {
  return wind_ ? wind_->airVelocity(x, time) : effects_.wind.velocity;
}

using detail::requireField;  // core/text.hpp: the kernel's one message form

void validateEffects(const ParticleEffects& e, const char* where) {
  const std::string w = std::string(where) + ".";
  requireField(std::isfinite(e.drag) && e.drag >= 0, w + "drag", e.drag, "finite and >= 0 (N s/m)");
  const WindEffect& wind = e.wind;
  requireField(std::isfinite(wind.velocity.x), w + "wind.velocity.x", wind.velocity.x, "finite (m/s)");
  requireField(std::isfinite(wind.velocity.y), w + "wind.velocity.y", wind.velocity.y, "finite (m/s)");
  requireField(std::isfinite(wind.velocity.z), w + "wind.velocity.z", wind.velocity.z, "finite (m/s)");
  requireField(std::isfinite(wind.airDensity) && wind.airDensity > 0, w + "wind.airDensity", wind.airDensity,
               "finite and > 0 (kg/m^3)");
  requireField(std::isfinite(wind.dragCoefficient) && wind.dragCoefficient >= 0, w + "wind.dragCoefficient",
               wind.dragCoefficient, "finite and >= 0");
  requireField(std::isfinite(wind.liftCoefficient) && wind.liftCoefficient >= 0, w + "wind.liftCoefficient",
               wind.liftCoefficient, "finite and >= 0");
  requireField(std::isfinite(wind.particleArea) && wind.particleArea >= 0, w + "wind.particleArea", wind.particleArea,
               "finite and >= 0 (m^2)");
  requireField(std::isfinite(wind.gustStrength) && wind.gustStrength >= 0, w + "wind.gustStrength", wind.gustStrength,
               "finite and >= 0 (m/s)");
  // (Wavelengths far below a micrometre put sines of 1e30 and more into the gusts, where
  // they are no longer numbers: NaN at the first step.)
  requireField(std::isfinite(wind.gustScale) && wind.gustScale >= 1e-6, w + "wind.gustScale", wind.gustScale,
               "finite and >= 1e-6 (m)");
  requireField(std::isfinite(wind.gustPeriod) && wind.gustPeriod > 0, w + "wind.gustPeriod", wind.gustPeriod,
               "finite and > 0 (s)");
  requireField(wind.gustModes >= 1 && wind.gustModes <= 64, w + "wind.gustModes", wind.gustModes, "in [1, 64]");
  const RepulsionEffect& r = e.repulsion;
  requireField(std::isfinite(r.radius) && r.radius >= 0, w + "repulsion.radius", r.radius, "finite and >= 0 (m)");
  requireField(std::isfinite(r.stiffness) && r.stiffness >= 0, w + "repulsion.stiffness", r.stiffness,
               "finite and >= 0 (N/m)");
  requireField(!(r.radius > 0) || r.radius >= 1e-9, w + "repulsion.radius", r.radius, "0 (off) or >= 1e-9 m");
}

template class ForceField<float>;
template class ForceField<double>;

}  // namespace weft
