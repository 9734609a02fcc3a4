// Projective dynamics for mass-spring systems (Liu, Bargteil, O'Brien & Kavan 2013, "Fast
// Simulation of Mass-Spring Systems"): backward Euler on positions, solved by alternating
//
//   local step   per spring s = (a, b), the direction it would have at rest length,
//                r_s e^_s with e^_s the unit vector of x_a - x_b   (parallel over springs), and
//   global step  one solve with a matrix that depends only on the model and h:
//
//     (M + h c I + (h^2 ks + h kd) L) dx = M (h v0 + h^2 a_ext)
//                                          + sum_s J_s [h^2 ks (r_s e^_s - e0_s) + h kd u_perp_s]
//
// for the step's displacement dx = x1 - x0 (the unknown is the small displacement, not the
// positions: in float, x0 + h v0 would lose most of h v0 to the rounding of x0). e0_s is
// the spring vector at the start of the step, u_s = dx_a - dx_b its change over the step.
// L is the springs' graph Laplacian (per coordinate: the same matrix for x, y and z), a_ext
// every acceleration the ForceField computes other than the springs' and the drag's
// (gravity, wind, repulsion), evaluated once at the start of the step, and J_s adds a
// spring's vector to a and subtracts it from b. x1 = x0 + dx, v1 = dx / h.
//
// Damping. The spring dashpot kd acts along the spring (f = -kd (dv . e^) e^, as in the
// ForceField). Along the spring only, its matrix would change every step, so the constant
// matrix holds an isotropic dashpot h kd L (and the drag h c I), and the part that must not
// be damped, the relative displacement across the spring u_perp = u - (e^ . u) e^, is
// given back on the right at the current iterate. The lagged part is smaller than the
// matrix's (a projection of it), so it converges with the local steps, to backward Euler
// with the ForceField's damping (tests/test_integrate.cpp measures the residual).
// Explicit drag at h c / m >= 2 would diverge; it is implicit here for that reason.
//
// Pinned particles keep their velocity (kinematic pins move on), dx = h v0: their rows of
// the matrix are the identity, and their springs to free particles move to the right.
//
// Correction form. Each iteration solves for a correction, P delta = b(dx) - P dx, and
// adds it: dx += delta (P the matrix above, b the right-hand side at the current iterate).
// With P applied to dx folded in, a spring's share of the residual is
//   h^2 ks (r_s e^_s - e_s) - h kd (e^_s . u_s) e^_s   (e_s = e0_s + u_s, the current vector)
// and a free particle's row adds M (h v0 + h^2 a_ext) - (m + h c) dx; pinned rows are 0.
// In exact arithmetic it is the same iteration. Its fixed point does not depend on the
// factor's rounding, so the factor's entries are stored in float (spring_laplacian_solver.hpp):
// a solve with them leaves a residual with P of ~1e-6 of its right-hand side, which changes
// how fast the iteration converges by about as little, not where it converges to.
//
// The solve. The matrix is symmetric positive definite; it is factorised once per time
// step h (Eigen's SimplicialLDLT, in double for both precisions, on an ordering found once:
// one level of nested dissection, each part in approximate-minimum-degree order) and kept;
// the factors of the two most recently used steps are cached, so the collision pipeline's
// halved chunks do not refactorise at every change. A factorisation allocates and is counted
// in StepWork::factorizations; a step with a cached h allocates nothing. The triangular
// solves are weft's own, in gather form with the three coordinates interleaved, so that the
// factor is read once per solve (2.3x faster than Eigen's solve with three right-hand sides
// at 128^2 even before the gather form); the dissection's two parts are two tasks that never
// read each other's unknowns, and each unknown is summed in one fixed order, so the result
// is the same for any thread count. The factor cache and the solves are
// SpringLaplacianSolver's (spring_laplacian_solver.hpp, with theta = 1), which implicit
// Euler's projective preconditioner shares.
//
// Grids. On a model with a grid layout the local step runs over each spring family's rows
// (a spring's endpoints i and i + offset for consecutive i: contiguous loads, where the
// general per-spring endpoints need gathers, which on the AMD EPYC took about as long as a
// triangular solve) and the right-hand side is gathered by the same stencil (per particle:
// each family's spring from it, minus the one to it) instead of the incidence lists, both
// in one pass per chunk of particles through a window per thread (gridResidual);
// tests/test_integrate.cpp checks both paths agree.
//
// Convergence. Each iteration (a local step, a gather, a solve) is a fixed-point step
// towards backward Euler (without damping it lowers the backward-Euler energy: Liu et
// al.); it converges linearly, and a fixed count is run (IntegratorOptions::projectiveIterations). StepWork reports
// the global solves in linearIterations and, in linearResidual, the largest coordinate
// change of the last iteration relative to the largest displacement of the step: how far
// the iteration count leaves the step from converged.
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

#include "effects/stencil_gather.hpp"
#include "row_blocks.hpp"
#include "spring_laplacian_solver.hpp"
#include "weft/effects/spring_force.hpp"

namespace weft::detail {

namespace {

template <class S>
class Projective final : public Integrator<S> {
 public:
  Projective(const Model<S>& model, const IntegratorOptions& o)
      : model_(&model),
        iterations_(o.projectiveIterations),
        n_(model.particleCount()),
        free_(model.particleCount()),
        externalAccel_(model.particleCount(), 3),
        springForce_(model.springCount(), 3),
        springTerm_(model.grid() ? 0 : model.springCount(), 3),
        constant_(model.particleCount(), 3),
        displacement_(model.particleCount(), 3),
        blockMax_(static_cast<size_t>(Executor::blockCount(model.particleCount(), kGrain)), 0.0),
        blockMove_(blockMax_.size(), 0.0),
        global_(model, 1.0, "projective dynamics: the global matrix") {
    for (Index i = 0; i < n_; ++i) free_[i] = model.isPinned(i) ? S(0) : S(1);
    incidence_ = model.springCount() > 0 ? &model.springIncidence() : nullptr;
    if (model.grid()) {
      const GridLayout<S>& grid = *model.grid();
      for (const GridFamily<S>& f : grid.families) {
        familyOffset_.push_back(f.rowOffset * grid.width + f.columnOffset);
        pad_ = std::max(pad_, familyOffset_.back());
      }
      // A chunk's window spans its rows and the pad_ / W rows above that its gather reaches,
      // after pad_ slots that stay zero (what i - offset reads before particle 0).
      const StencilChunks chunks =
          stencilChunks<S>(grid.width, pad_, ForceField<S>::kStencilChunkParticles, ForceField<S>::kSinkBlock);
      chunk_ = chunks.chunk;
      window_ = chunks.window;
    }
  }
  void reserve(const Executor& exec) override {
    if (familyOffset_.empty()) return;
    reserveStencilWindows(windows_, windowCount(exec), familyOffset_.size() * 3 * static_cast<size_t>(window_));
  }
  IntegratorKind kind() const override { return IntegratorKind::Projective; }

  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    StepWork work;
    work.substeps = 1;
    // The global matrix's factor for this h and drag: cached, or factorised now (allocates).
    if (global_.prepare(static_cast<double>(h), forces.effects().drag)) ++work.factorizations;
    double* const permuted = global_.buffer();  // right-hand side / solution, factor order (offset(i))
    const ScalarArray<S>& mass = model_->mass();
    const ScalarArray<S>& w = model_->inverseMass();
    const S drag = static_cast<S>(forces.effects().drag);
    const Springs<S>& sp = model_->springs();
    const Index m = sp.count();

    // a = every acceleration at the start of the step; then the springs' and the drag's
    // share is taken out again (they are in the matrix and the local step).
    forces.setStageOffset(0);
    forces.accelerations(x0, v0, externalAccel_, exec);
    ++work.forceEvaluations;
    exec.parallelFor(m, kSpringGrain, [&](Index b, Index e) {
      for (Index s = b; s < e; ++s) {
        const Index pa = sp.a[s], pb = sp.b[s];
        S f[3];
        dampedSpringForce(x0(pa, 0) - x0(pb, 0), x0(pa, 1) - x0(pb, 1), x0(pa, 2) - x0(pb, 2), v0(pa, 0) - v0(pb, 0),
                          v0(pa, 1) - v0(pb, 1), v0(pa, 2) - v0(pb, 2), sp.restLength[s], sp.stiffness[s],
                          sp.damping[s], f[0], f[1], f[2]);
        for (int c = 0; c < 3; ++c) springForce_(s, c) = f[c];
      }
    });
    // The unknown is the displacement of the step, dx = x1 - x0 (small: rounding relative to
    // it, not to the positions, which in float would lose h v0 to the rounding of x0).
    // constant = M (h v0 + h^2 a_ext) on free particles; h v0 on pinned ones (their rows are
    // the identity). The first iterate is the inertial prediction.
    const S h2 = h * h;
    exec.parallelFor(n_, kGrain, [&](Index b, Index e) {
      alignas(64) S sum[3][kGrain];
      const bool grid = gatherBlock(springForce_, b, e, sum);
      for (Index i = b; i < e; ++i) {
        S f[3] = {0, 0, 0};
        if (grid)
          for (int c = 0; c < 3; ++c) f[c] = sum[c][i - b];
        else if (incidence_ != nullptr)
          gatherSprings(springForce_, i, f);
        const bool isFree = free_[i] != S(0);
        for (int c = 0; c < 3; ++c) {
          if (isFree) {
            const S aExt = externalAccel_(i, c) - w[i] * f[c] + w[i] * drag * v0(i, c);
            const S inertial = h * v0(i, c) + h2 * aExt;
            constant_(i, c) = mass[i] * inertial;
            displacement_(i, c) = inertial;
          } else {
            constant_(i, c) = h * v0(i, c);
            displacement_(i, c) = h * v0(i, c);
          }
        }
      }
    });

    for (int k = 0; k < iterations_; ++k) {
      if (!familyOffset_.empty()) {
        gridResidual(x0, h, drag, permuted, exec);
      } else {
        localStep(x0, h, exec);
        // The residual r = b(dx) - P dx, gathered per particle in its incidence order, into
        // the factor's ordering with the coordinates interleaved.
        exec.parallelFor(n_, kGrain, [&](Index b, Index e) {
          for (Index i = b; i < e; ++i) {
            double* out = permuted + global_.offset(i);
            if (free_[i] == S(0)) {  // dx = h v0 already: no correction
              for (int c = 0; c < 3; ++c) out[c] = 0.0;
              continue;
            }
            S f[3] = {0, 0, 0};
            if (incidence_ != nullptr) gatherSprings(springTerm_, i, f);
            const double diagonal = static_cast<double>(mass[i]) + static_cast<double>(h) * static_cast<double>(drag);
            for (int c = 0; c < 3; ++c)
              out[c] = (static_cast<double>(constant_(i, c)) + static_cast<double>(f[c])) -
                       diagonal * static_cast<double>(displacement_(i, c));
          }
        });
      }
      global_.solveBuffer(exec);
      const bool last = k + 1 == iterations_;
      exec.parallelForBlocks(n_, kGrain, [&](Index block, Index b, Index e) {
        if (last)
          finish(x0, v0, h, x1, v1, block, b, e);
        else
          for (Index i = b; i < e; ++i) {
            const double* in = permuted + global_.offset(i);
            for (int c = 0; c < 3; ++c) displacement_(i, c) += static_cast<S>(in[c]);
          }
      });
      ++work.linearIterations;
    }
    double move = 0, moved = 0;
    for (size_t k = 0; k < blockMove_.size(); ++k) {
      move = std::max(move, blockMove_[k]);
      moved = std::max(moved, blockMax_[k]);
    }
    work.linearResidual = moved > 0 ? move / moved : 0.0;
    return work;
  }

 private:
  static constexpr Index kGrain = ForceField<S>::kParticleGrain;
  static constexpr Index kSpringGrain = ForceField<S>::kSpringGrain;

  /// sum over particle i's springs of +t_s (endpoint a) or -t_s (endpoint b), in the
  /// incidence order.
  void gatherSprings(const Vec3Array<S>& t, Index i, S f[3]) const {
    for (Index k = incidence_->begin(i); k < incidence_->end(i); ++k) {
      const Index entry = incidence_->entries[k];
      const Index s = entry >> 1;
      const S sign = (entry & 1) != 0 ? S(-1) : S(1);
      for (int c = 0; c < 3; ++c) f[c] += sign * t(s, c);
    }
  }

  /// On a grid: sum[c][i - b] = sum over particle i's springs of +t_s (endpoint a) or -t_s
  /// (endpoint b), for particles [b, e), family by family (the a side, then the b side),
  /// over contiguous runs of springs instead of the incidence lists. Returns false (and
  /// does nothing) on a model without a grid layout.
  bool gatherBlock(const Vec3Array<S>& t, Index b, Index e, S (&sum)[3][kGrain]) const {
    if (!model_->grid()) return false;
    const GridLayout<S>& grid = *model_->grid();
    const Index W = grid.width, H = grid.height, m = t.rows();
    for (int c = 0; c < 3; ++c) std::fill_n(sum[c], e - b, S(0));
    for (Index r = b / W; r * W < e; ++r) {  // the rows the block meets
      const Index cs = std::max<Index>(b - r * W, 0), ce = std::min<Index>(e - r * W, W);
      for (const GridFamily<S>& f : grid.families) {
        const Index c0 = std::max<Index>(0, -f.columnOffset), c1 = std::min<Index>(W, W - f.columnOffset);
        const Index count = c1 - c0;
        if (r + f.rowOffset < H) {  // particle (r, c) is endpoint a of spring (r, c)
          const Index lo = std::max(cs, c0), hi = std::min(ce, c1);
          const Index s = f.firstSpring + r * count + (lo - c0), i = r * W + lo - b;  // at column lo
          for (int c = 0; c < 3 && lo < hi; ++c) {
            const S* __restrict src = t.data() + c * m + s;
            S* __restrict dst = sum[c] + i;
            for (Index k = 0; k < hi - lo; ++k) dst[k] += src[k];
          }
        }
        if (r >= f.rowOffset) {  // endpoint b of spring (r - dr, c - dc)
          const Index lo = std::max(cs, c0 + f.columnOffset), hi = std::min(ce, c1 + f.columnOffset);
          const Index s = f.firstSpring + (r - f.rowOffset) * count + (lo - f.columnOffset - c0), i = r * W + lo - b;
          for (int c = 0; c < 3 && lo < hi; ++c) {
            const S* __restrict src = t.data() + c * m + s;
            S* __restrict dst = sum[c] + i;
            for (Index k = 0; k < hi - lo; ++k) dst[k] -= src[k];
          }
        }
      }
    }
    return true;
  }

  /// The last iteration's displacement into (x1, v1) for particles [b, e): dx = the iterate
  /// plus the last correction, x1 = x0 + dx and v1 = dx / h; pinned particles keep v0
  /// (their dx = h v0 gets no correction). Also the block's largest change of this iteration and largest
  /// displacement.
  void finish(const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1, Vec3Array<S>& v1, Index block,
              Index b, Index e) {
    const double invH = 1.0 / static_cast<double>(h);
    double move = 0, moved = 0;
    for (Index i = b; i < e; ++i) {
      const double* in = global_.buffer() + global_.offset(i);  // the last correction
      const bool isFree = free_[i] != S(0);
      for (int c = 0; c < 3; ++c) {
        const S dx = displacement_(i, c) + static_cast<S>(in[c]);
        move = std::max(move, std::abs(in[c]));
        moved = std::max(moved, std::abs(static_cast<double>(dx)));
        x1(i, c) = x0(i, c) + dx;
        v1(i, c) = isFree ? static_cast<S>(static_cast<double>(dx) * invH) : v0(i, c);
      }
    }
    blockMove_[static_cast<size_t>(block)] = move;
    blockMax_[static_cast<size_t>(block)] = moved;
  }

  static constexpr Index kBlock = ForceField<S>::kSinkBlock;

  /// t[i] = sum over K families in order of (+g_k[i], then -g_k[i - offset_k]) over
  /// [0, count): gatherBlock's additions in its order (g pointers at the first slot).
  template <int K>
  [[gnu::noinline]] static void gatherTerms(Index count, const S* const* g, const Index* offsets, S* __restrict tx,
                                            S* __restrict ty, S* __restrict tz) {
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
        sx += gx[k][i];
        sx -= gx[k][i - o[k]];
        sy += gy[k][i];
        sy -= gy[k][i - o[k]];
        sz += gz[k][i];
        sz -= gz[k][i - o[k]];
      }
      tx[i] = sx;
      ty[i] = sy;
      tz[i] = sz;
    }
  }
  /// t[i] += g[i], then -= g[i - offset], over [0, count).
  [[gnu::noinline]] static void addTerms(Index count, const S* __restrict g, Index offset, S* __restrict t) {
    for (Index i = 0; i < count; ++i) {
      t[i] += g[i];
      t[i] -= g[i - offset];
    }
  }

  size_t windowCount(const Executor& exec) const { return stencilWindowCount(exec, Executor::blockCount(n_, chunk_)); }

  /// On a grid, the local step and the gather of the residual in one pass: per chunk of
  /// particles, the springs of its rows and of the rows above that its gather reaches
  /// (computed by both chunks: the same bits either way) into the thread's window, indexed
  /// by the spring's first particle (zero where none starts), then per particle, family by
  /// family, + the spring from it and - the spring to it: the additions of gatherBlock, in
  /// its order, without a buffer of every spring's term streamed out and back.
  void gridResidual(const Vec3Array<S>& x0, S h, S drag, double* permuted, const Executor& exec) {
    const GridLayout<S>& grid = *model_->grid();
    const Index W = grid.width, H = grid.height;
    const Index families = static_cast<Index>(grid.families.size());
    const Springs<S>& sp = model_->springs();
    const ScalarArray<S>& mass = model_->mass();
    const S h2 = h * h;
    const size_t perWindow = static_cast<size_t>(families) * 3 * static_cast<size_t>(window_);
    const size_t slots = windowCount(exec);
    reserve(exec);
    exec.parallelFor(n_, chunk_, [&](Index b, Index e) {
      S* window = stencilWindow(windows_, slots, perWindow, "projective dynamics");
      const Index rowFirst = b > pad_ ? (b - pad_) / W : 0, rowEnd = (e - 1) / W + 1;
      const Index shift = pad_ - rowFirst * W;  // window slot of particle i: i + shift
      for (Index k = 0; k < families; ++k) {
        const GridFamily<S>& f = grid.families[static_cast<size_t>(k)];
        const Index c0 = std::max<Index>(0, -f.columnOffset), c1 = std::min<Index>(W, W - f.columnOffset);
        const Index count = c1 - c0, last = H - f.rowOffset;
        S* family = window + 3 * k * window_;  // coordinate c at family + c window_
        for (Index r = rowFirst; r < rowEnd; ++r) {
          const Index at = pad_ + (r - rowFirst) * W;
          if (r >= last || count <= 0) {
            for (int c = 0; c < 3; ++c) std::fill_n(family + c * window_ + at, W, S(0));
            continue;
          }
          for (int c = 0; c < 3; ++c) {
            std::fill_n(family + c * window_ + at, c0, S(0));
            std::fill_n(family + c * window_ + at + c1, W - c1, S(0));
          }
          localSprings<true>(f.firstSpring + r * count, count, r * W + c0, familyOffset_[static_cast<size_t>(k)], h2, h,
                             nullptr, nullptr, sp.stiffness.data(), sp.restLength.data(), sp.damping.data(), x0.data(),
                             displacement_.data(), n_, family, window_, at + c0);
        }
      }
      const double diagonalDrag = static_cast<double>(h) * static_cast<double>(drag);
      alignas(64) S sum[3][kBlock];
      for (Index j0 = b; j0 < e; j0 += kBlock) {
        const Index len = std::min<Index>(kBlock, e - j0);
        if (families == 6) {
          const S* g[18];
          for (Index c = 0; c < 18; ++c) g[c] = window + c * window_ + j0 + shift;
          gatherTerms<6>(len, g, familyOffset_.data(), sum[0], sum[1], sum[2]);
        } else {
          for (int c = 0; c < 3; ++c) std::fill_n(sum[c], len, S(0));
          for (Index k = 0; k < families; ++k)
            for (int c = 0; c < 3; ++c)
              addTerms(len, window + (3 * k + c) * window_ + j0 + shift, familyOffset_[static_cast<size_t>(k)], sum[c]);
        }
        for (Index i = j0; i < j0 + len; ++i) {
          double* out = permuted + global_.offset(i);
          if (free_[i] == S(0)) {  // dx = h v0 already: no correction
            for (int c = 0; c < 3; ++c) out[c] = 0.0;
            continue;
          }
          const double diagonal = static_cast<double>(mass[i]) + diagonalDrag;
          for (int c = 0; c < 3; ++c)
            out[c] = (static_cast<double>(constant_(i, c)) + static_cast<double>(sum[c][i - j0])) -
                     diagonal * static_cast<double>(displacement_(i, c));
        }
      }
    });
  }

  /// The local step, per spring, with u = dx_a - dx_b the change of the spring vector over
  /// the step, e = x0_a - x0_b + u the vector at the iterate and e^ its direction: the
  /// spring's share of the residual b(dx) - P dx,
  ///   springTerm = h^2 ks (r e^ - e) - h kd (e^ . u) e^
  /// (the right-hand side's h^2 ks (r e^ - e0) + h kd u_perp less P's (h^2 ks + h kd) u;
  /// for a spring to a pinned particle the same, the pinned side's dx being on both).
  void localStep(const Vec3Array<S>& x0, S h, const Executor& exec) {
    const Springs<S>& sp = model_->springs();
    const S h2 = h * h;
    const Index m = sp.count();
    exec.parallelFor(m, kSpringGrain, [&](Index b, Index e) {
      localSprings<false>(b, e - b, 0, 0, h2, h, sp.a.data(), sp.b.data(), sp.stiffness.data(), sp.restLength.data(),
                          sp.damping.data(), x0.data(), displacement_.data(), n_, springTerm_.data(), m, b);
    });
  }

  /// The local step over springs [first, first + count) on raw arrays (coordinate-major:
  /// x(i, c) at x[c n + i]; spring first + j's term to term[c m + out + j]), branch-free so
  /// that it vectorises. kStrided: spring first + j joins particles
  /// i0 + j and i0 + j + offset (a grid family's row); else the endpoints are pa[s], pb[s].
  template <bool kStrided>
  static void localSprings(Index first, Index count, Index i0, Index offset, S h2, S h, const Index* __restrict pa,
                           const Index* __restrict pb, const S* __restrict stiffness, const S* __restrict restLength,
                           const S* __restrict damping, const S* __restrict x0, const S* __restrict dx, Index n,
                           S* __restrict term, Index m, Index out) {
    for (Index j = 0; j < count; ++j) {
      const Index s = first + j;
      Index ia, ib;
      if constexpr (kStrided) {
        ia = i0 + j;
        ib = i0 + j + offset;
      } else {
        ia = pa[s];
        ib = pb[s];
      }
      S d[3], e[3], u[3];
      for (int c = 0; c < 3; ++c) {
        u[c] = dx[c * n + ia] - dx[c * n + ib];
        e[c] = (x0[c * n + ia] - x0[c * n + ib]) + u[c];  // the spring vector at the iterate
      }
      const S len2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
      const bool hasDirection = len2 > std::numeric_limits<S>::min();
      const S invLen = (hasDirection ? S(1) : S(0)) / std::sqrt(hasDirection ? len2 : S(1));
      S along = 0;
      for (int c = 0; c < 3; ++c) {
        d[c] = e[c] * invLen;  // unit direction (zero for a spring of zero length)
        along += d[c] * u[c];
      }
      const S ks = h2 * stiffness[s];
      const S rest = restLength[s];
      const S viscous = h * damping[s];
      for (int c = 0; c < 3; ++c) {
        const S t = ks * (rest * d[c] - e[c]) - viscous * along * d[c];
        term[c * m + out + j] = t;
      }
    }
  }

  const Model<S>* model_;
  int iterations_;
  Index n_;
  const Incidence* incidence_ = nullptr;
  ScalarArray<S> free_;         // (n) 1 for free particles, 0 for pinned
  Vec3Array<S> externalAccel_;  // (n x 3) every acceleration at the start of the step, m/s^2
  Vec3Array<S> springForce_;    // (m x 3) spring forces at the start of the step, N
  Vec3Array<S> springTerm_;     // (m x 3) the local step's per-spring right-hand side, kg m (not on grids)
  Vec3Array<S> constant_;       // (n x 3) the right-hand side's constant part, kg m
  Vec3Array<S> displacement_;   // (n x 3) the iterate: x1 - x0, m
  std::vector<double> blockMax_, blockMove_;
  // Grids: per family rowOffset W + columnOffset, the largest of them, particles per chunk,
  // slots per family and coordinate, and the windows, one per thread (gridResidual).
  std::vector<Index> familyOffset_;
  Index pad_ = 0, chunk_ = 0, window_ = 0;
  std::vector<S> windows_;
  SpringLaplacianSolver<S> global_;  // the global matrix, factorised per (h, drag), and its solves
};

}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeProjective(const Model<S>& model, const IntegratorOptions& options) {
  return std::make_unique<Projective<S>>(model, options);
}
template std::unique_ptr<Integrator<float>> makeProjective(const Model<float>&, const IntegratorOptions&);
template std::unique_ptr<Integrator<double>> makeProjective(const Model<double>&, const IntegratorOptions&);

}  // namespace weft::detail
