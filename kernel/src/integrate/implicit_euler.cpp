// Backward Euler linearised once per step (Baraff & Witkin 1998, section 4):
//
//     (M - h df/dv - h^2 df/dx) dv = h (f0 + h df/dx v0),   v1 = v0 + dv,  x1 = x0 + h v1
//
// solved by the modified preconditioned conjugate gradient of their section 5.3:
// constraint filtering keeps dv = 0 on pinned particles (the filter zeroes their rows of
// b, of every residual and search direction), a preconditioner, and a warm start from the
// previous step's dv. The matrix products come from SpringJacobian (matrix-free,
// deterministic; through the grid stencil on grid models).
//
// Preconditioners (IntegratorOptions::preconditioner): Jacobi (1 / diag(A)); block-Jacobi
// (each particle's 3x3 diagonal block of A inverted once per step, applied in the pass that
// updates r); projective (SpringLaplacianSolver: one prefactored solve with
// projective dynamics' matrix per iteration, after that pass). Measured on the 128^2 flag
// (docs/integrators.md): block-Jacobi takes 30 % fewer iterations than Jacobi at 1/60 s
// for the same cost each; the projective one 53 % fewer, but its solve (two tasks over a
// dissection) costs several iterations, so it is slower per step; multigrid (AggregationMultigrid:
// one W-cycle per iteration) takes 20x fewer than block-Jacobi at 1/60 s, but costs about
// 4.7 of its iterations each, so it pays only where block-Jacobi needs tens of iterations;
// auto (the default) takes block-Jacobi, and the multigrid for steps at least as long as the
// shortest whose block-Jacobi solve took more than kAutoMultigridIterations (or stopped at
// the cap), back to block-Jacobi (with a higher threshold) if a multigrid solve then costs
// more than that block-Jacobi solve did. The force f0 includes everything the ForceField
// computes (springs, gravity); only the springs enter the Jacobian.
//
// Dot products are reduced deterministically: one partial per block of
// ForceField::kSinkBlock particles (the blocks of every pass here), accumulated in double
// and summed in block order after the pass, so the iterates are bitwise the same for any
// thread count. Products fuse the per-particle work that follows them: q = A p is
// filtered and dotted with p in the pass that forms it; dv, r and the new (r, z) dot
// product share one pass (block-Jacobi forms z there too). Per iteration: one Jacobian
// product (one pass on a grid model, two on others) and two more passes (plus the
// projective or multigrid preconditioner's).
//
// Stopping: |r| <= linearTolerance |b| (2-norms of the filtered vectors), or
// maxLinearIterations. A solve that stops at the cap is still used (the step is a
// linearisation anyway; the stability check guards the result) and is reported in
// StepWork.linearUnconverged with its residual.
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "aggregation_multigrid.hpp"
#include "core/text.hpp"
#include "row_blocks.hpp"
#include "spring_laplacian_solver.hpp"
#include "symmetric_block.hpp"
#include "weft/effects/spring_jacobian.hpp"

namespace weft::detail {

namespace {

template <class S>
class ImplicitEuler final : public Integrator<S> {
 public:
  ImplicitEuler(const Model<S>& model, const IntegratorOptions& o)
      : options_(o),
        jacobian_(model),
        free_(model.particleCount()),
        b_(model.particleCount(), 3),
        dv_(model.particleCount(), 3),
        r_(model.particleCount(), 3),
        p_(model.particleCount(), 3),
        q_(model.particleCount(), 3),
        z_(o.preconditioner == Preconditioner::Jacobi ? 0 : model.particleCount(), 3),
        inverseDiagonal_(model.particleCount(), 3),
        inverseBlock_(o.preconditioner == Preconditioner::BlockJacobi || o.preconditioner == Preconditioner::Auto
                          ? model.particleCount()
                          : 0,
                      6),
        partialA_(static_cast<size_t>(Executor::blockCount(model.particleCount(), kBlock)), 0.0),
        partialB_(partialA_.size(), 0.0),
        active_(o.preconditioner == Preconditioner::Auto ? Preconditioner::BlockJacobi : o.preconditioner) {
    for (Index i = 0; i < model.particleCount(); ++i) free_[i] = model.isPinned(i) ? S(0) : S(1);
    dv_.setZero();
    if (o.preconditioner == Preconditioner::Projective)
      laplacian_ = std::make_unique<SpringLaplacianSolver<S>>(model, kProjectiveTheta,
                                                              "implicit Euler: the preconditioner's matrix");
    if (o.preconditioner == Preconditioner::Multigrid || o.preconditioner == Preconditioner::Auto)
      multigrid_ = std::make_unique<AggregationMultigrid<S>>(model);
  }
  IntegratorKind kind() const override { return IntegratorKind::ImplicitEuler; }
  // (Auto's lengths, threshold and trigger are kept: they belong to the model and the step
  // size, not the state.)
  void reset() override { warm_ = false; }
  void reserve(const Executor& exec) override { jacobian_.reserve(exec); }
  void saveCarry(ArchiveWriter& out) const override {
    out.value(warm_);
    out.array(dv_);
    out.value(multigridStep_);
    out.value(acceptedStep_);
    out.value(threshold_);
    out.value(trigger_);
  }
  void loadCarry(ArchiveReader& in) override {
    in.flag(warm_, "implicit Euler's flag");
    in.array(dv_, dv_.rows(), 3, "implicit Euler's warm start", warm_);  // (read only when warm)
    in.value(multigridStep_);
    in.value(acceptedStep_);
    in.value(threshold_);
    in.value(trigger_);
    // (What a run can reach: lengths > 0 or +infinity, the one in use no longer than the
    // kept one; a finite threshold from 40 up; a trigger above 40 iterations, or +infinity.)
    if (!(multigridStep_ > 0 && acceptedStep_ >= multigridStep_ && std::isfinite(threshold_) &&
          threshold_ >= static_cast<double>(kAutoMultigridIterations) &&
          (std::isinf(trigger_) ||
           (trigger_ > static_cast<double>(kAutoMultigridIterations) && trigger_ == std::floor(trigger_)))))
      in.fail("implicit Euler's auto preconditioner: step " + detail::number(multigridStep_) + " s (kept " +
              detail::number(acceptedStep_) + " s), threshold " + detail::number(threshold_) + ", trigger " +
              detail::number(trigger_) + " iterations: not a state a run reaches");
  }

  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    StepWork work;
    work.substeps = 1;
    const Index n = static_cast<Index>(x0.rows());
    if (options_.preconditioner == Preconditioner::Auto)
      active_ = static_cast<double>(h) >= multigridStep_ ? Preconditioner::Multigrid : Preconditioner::BlockJacobi;
    const ScalarArray<S>& mass = jacobian_.model().mass();

    // b = h m a0 (filtered): a0 includes springs and gravity.
    auto rhsForce = [&](Index b, Index m, const S* ax, const S* ay, const S* az) {
      const auto f = free_.segment(b, m).array();
      const auto mh = h * mass.segment(b, m).array();
      for (int c = 0; c < 3; ++c) rows(b_, c, b, m) = f * mh * accel(ax, ay, az, c, m);
    };
    forces.setStageOffset(0);  // forces and their Jacobian at the start of the step
    forces.accelerations(x0, v0, makeSink<S>(rhsForce), exec);
    ++work.forceEvaluations;
    jacobian_.linearize(x0, h, exec, static_cast<S>(forces.effects().drag));
    // b -= (-h^2 df/dx) v0; then |b|^2 per block. Jacobi: 1 / diag(A) on free particles.
    auto rhsStiffness = [&](Index b, Index m, const S* yx, const S* yy, const S* yz) {
      const auto f = free_.segment(b, m).array();
      double bb = 0;
      for (int c = 0; c < 3; ++c) {
        auto bc = rows(b_, c, b, m);
        bc -= f * accel(yx, yy, yz, c, m);
        bb += bc.template cast<double>().square().sum();
        rows(inverseDiagonal_, c, b, m) = f / rows(jacobian_.diagonal(), c, b, m);
      }
      if (active_ == Preconditioner::BlockJacobi) invertBlocks(b, m);
      partialA_[static_cast<size_t>(b / kBlock)] = bb;
    };
    jacobian_.stiffnessProduct(v0, makeSink<S>(rhsStiffness), exec);
    if (laplacian_ && laplacian_->prepare(static_cast<double>(h), static_cast<double>(forces.effects().drag)))
      ++work.factorizations;
    const bool multigrid = active_ == Preconditioner::Multigrid;
    if (multigrid) multigrid_->prepare(jacobian_, exec);
    const double bNorm = std::sqrt(sumPartials(partialA_));

    // r = b - A dv (warm start) or r = b (cold); then rz = r . M^-1 r and |r|^2.
    if (warm_) {
      auto residual = [&](Index b, Index m, const S* yx, const S* yy, const S* yz) {
        const auto f = free_.segment(b, m).array();
        for (int c = 0; c < 3; ++c) rows(r_, c, b, m) = rows(b_, c, b, m) - f * accel(yx, yy, yz, c, m);
        reduceResidual(b, m);
      };
      jacobian_.systemProduct(dv_, makeSink<S>(residual), exec);  // one product more than the iterations
    } else {
      exec.parallelFor(n, kBlock, [&](Index b, Index e) {
        for (int c = 0; c < 3; ++c) {
          rows(dv_, c, b, e - b).setZero();
          rows(r_, c, b, e - b) = rows(b_, c, b, e - b);
        }
        reduceResidual(b, e - b);
      });
    }
    precondition(exec);
    double rz = sumPartials(partialA_);
    double rNorm = std::sqrt(sumPartials(partialB_));
    const double target = options_.linearTolerance * bNorm;

    Index iterations = 0;
    double beta = 0;
    // A right-hand side, residual or product that is not a number (forces or a Jacobian past
    // the precision's range) would stop the loop below at once and leave dv as it was: a
    // step that looks fine and is not. Such a solve gives dv = NaN, which the step's
    // stability check reports as non-finite, as it does for the explicit methods.
    bool finite = std::isfinite(bNorm) && std::isfinite(rNorm);
    while (finite && rNorm > target && bNorm > 0) {
      if (iterations == options_.maxLinearIterations) {
        ++work.linearUnconverged;
        break;
      }
      // p = z + beta p, z = M^-1 r.
      const S betaS = static_cast<S>(beta);
      const bool first = iterations == 0;
      exec.parallelFor(n, kBlock, [&](Index b, Index e) {
        for (int c = 0; c < 3; ++c) {
          auto pc = rows(p_, c, b, e - b);
          if (active_ == Preconditioner::Jacobi) {
            const auto z = rows(inverseDiagonal_, c, b, e - b) * rows(r_, c, b, e - b);
            if (first)
              pc = z;
            else
              pc = z + betaS * pc;
          } else {
            const auto z = rows(z_, c, b, e - b);
            if (first)
              pc = z;
            else
              pc = z + betaS * pc;
          }
        }
      });
      // q = A p (filtered); p . q per block.
      auto applied = [&](Index b, Index m, const S* yx, const S* yy, const S* yz) {
        const auto f = free_.segment(b, m).array();
        double pq = 0;
        for (int c = 0; c < 3; ++c) {
          auto qc = rows(q_, c, b, m);
          qc = f * accel(yx, yy, yz, c, m);
          pq += (qc.template cast<double>() * rows(p_, c, b, m).template cast<double>()).sum();
        }
        partialA_[static_cast<size_t>(b / kBlock)] = pq;
      };
      jacobian_.systemProduct(p_, makeSink<S>(applied), exec);
      const double pq = sumPartials(partialA_);
      if (!(pq > 0)) {  // A is SPD on the free subspace: only exhaustion or NaN gets here
        finite = !std::isnan(pq);
        break;
      }
      const S alpha = static_cast<S>(rz / pq);
      // dv += alpha p, r -= alpha q; new rz and |r|^2.
      exec.parallelFor(n, kBlock, [&](Index b, Index e) {
        for (int c = 0; c < 3; ++c) {
          rows(dv_, c, b, e - b) += alpha * rows(p_, c, b, e - b);
          rows(r_, c, b, e - b) -= alpha * rows(q_, c, b, e - b);
        }
        reduceResidual(b, e - b);
      });
      precondition(exec);
      const double rzNew = sumPartials(partialA_);
      rNorm = std::sqrt(sumPartials(partialB_));
      beta = rzNew / rz;
      rz = rzNew;
      ++iterations;
      finite = std::isfinite(rNorm);
    }
    if (!finite)
      exec.parallelFor(n, kBlock, [&](Index b, Index e) {
        for (int c = 0; c < 3; ++c) rows(dv_, c, b, e - b).setConstant(std::numeric_limits<S>::quiet_NaN());
      });
    work.linearIterations += iterations;
    work.linearResidual = bNorm > 0 ? rNorm / bNorm : 0.0;
    work.multigridSolves += multigrid ? 1 : 0;
    // Auto: a block-Jacobi solve of more iterations than the threshold (at first
    // kAutoMultigridIterations, where the multigrid starts to pay on the flag at CG 1e-6), or
    // one stopped at the cap, hands steps of this length and longer to the multigrid. The
    // next multigrid solve at that length is judged against it: if it costs more than that
    // block-Jacobi solve did (an iteration counted as kMultigridIterationCost block-Jacobi
    // iterations, its levels as kMultigridStepCost), the length goes back to block-Jacobi
    // (the longer ones judged before stay with the multigrid) and the threshold rises above
    // that cost; the measured iterations of both, not the constant, decide where they differ
    // (a tighter tolerance favours block-Jacobi). A capped block-Jacobi solve is not judged
    // against: no multigrid solve costs more than an unfinished one.
    if (options_.preconditioner == Preconditioner::Auto) {
      const double length = static_cast<double>(h);
      if (active_ == Preconditioner::BlockJacobi &&
          (static_cast<double>(iterations) > threshold_ || work.linearUnconverged > 0)) {
        multigridStep_ = length;  // (< multigridStep_: block-Jacobi ran)
        trigger_ = static_cast<double>(iterations);
        if (work.linearUnconverged > 0) {
          acceptedStep_ = std::min(acceptedStep_, length);
          trigger_ = std::numeric_limits<double>::infinity();
        }
      } else if (active_ == Preconditioner::Multigrid && length == multigridStep_ && std::isfinite(trigger_)) {
        const double cost = kMultigridIterationCost * static_cast<double>(iterations) + kMultigridStepCost;
        if (cost >= trigger_) {
          multigridStep_ = acceptedStep_;
          threshold_ = std::max(threshold_, kHysteresis * cost);
        } else {
          acceptedStep_ = length;
        }
        trigger_ = std::numeric_limits<double>::infinity();  // judged
      }
    }

    // v1 = v0 + dv, x1 = x0 + h v1.
    exec.parallelFor(n, kBlock, [&](Index b, Index e) {
      for (int c = 0; c < 3; ++c) {
        rows(v1, c, b, e - b) = rows(v0, c, b, e - b) + rows(dv_, c, b, e - b);
        rows(x1, c, b, e - b) = rows(x0, c, b, e - b) + h * rows(v1, c, b, e - b);
      }
    });
    warm_ = finite;  // (a NaN warm start would poison the next solve)
    return work;
  }

 private:
  static constexpr Index kBlock = ForceField<S>::kSinkBlock;
  // The projective preconditioner's share of h^2 ks in its Laplacian: 1 (projective
  // dynamics' matrix) took the fewest iterations of 1, 0.5, 0.2 and 0.05 on the 128^2 flag.
  static constexpr double kProjectiveTheta = 1.0;

  /// partialA = r . M^-1 r (Jacobi; block-Jacobi also forms z = M^-1 r; the projective
  /// preconditioner's solve does both after the pass), partialB = |r|^2 for the block
  /// starting at b.
  void reduceResidual(Index b, Index m) {
    double rz = 0, rr = 0;
    if (active_ == Preconditioner::Jacobi) {
      for (int c = 0; c < 3; ++c) {
        const auto r = rows(r_, c, b, m).template cast<double>();
        rz += (r * rows(inverseDiagonal_, c, b, m).template cast<double>() * r).sum();
        rr += r.square().sum();
      }
    } else {
      for (int c = 0; c < 3; ++c) rr += rows(r_, c, b, m).template cast<double>().square().sum();
      if (active_ == Preconditioner::BlockJacobi) {
        const S* __restrict inv = inverseBlock_.data();
        const Index stride = inverseBlock_.rows();
        for (Index i = b; i < b + m; ++i) {
          const S rx = r_(i, 0), ry = r_(i, 1), rz3 = r_(i, 2);
          const S* k = inv + i;  // xx, yy, zz, xy, xz, yz in columns
          const S zx = k[0] * rx + k[3 * stride] * ry + k[4 * stride] * rz3;
          const S zy = k[3 * stride] * rx + k[stride] * ry + k[5 * stride] * rz3;
          const S zz = k[4 * stride] * rx + k[5 * stride] * ry + k[2 * stride] * rz3;
          z_(i, 0) = zx;
          z_(i, 1) = zy;
          z_(i, 2) = zz;
          rz += static_cast<double>(rx) * static_cast<double>(zx) + static_cast<double>(ry) * static_cast<double>(zy) +
                static_cast<double>(rz3) * static_cast<double>(zz);
        }
      }
    }
    partialA_[static_cast<size_t>(b / kBlock)] = rz;
    partialB_[static_cast<size_t>(b / kBlock)] = rr;
  }
  /// The inverses of the 3x3 diagonal blocks of A for particles [b, b + m) (0 on pinned
  /// particles): symmetric positive definite, inverted by cofactors in double.
  void invertBlocks(Index b, Index m) {
    const Vec3Array<S>& d = jacobian_.diagonal();
    const Vec3Array<S>& o = jacobian_.offDiagonal();
    for (Index i = b; i < b + m; ++i) {
      const SymmetricBlock k = free_[i] != S(0)
                                   ? inverse(SymmetricBlock{d(i, 0), d(i, 1), d(i, 2), o(i, 0), o(i, 1), o(i, 2)})
                                   : SymmetricBlock{};
      inverseBlock_(i, 0) = static_cast<S>(k.xx);
      inverseBlock_(i, 1) = static_cast<S>(k.yy);
      inverseBlock_(i, 2) = static_cast<S>(k.zz);
      inverseBlock_(i, 3) = static_cast<S>(k.xy);
      inverseBlock_(i, 4) = static_cast<S>(k.xz);
      inverseBlock_(i, 5) = static_cast<S>(k.yz);
    }
  }
  /// z = M^-1 r and partialA = r . z per block, for the preconditioners applied after the
  /// pass that updates r (Jacobi and block-Jacobi work inside that pass).
  void precondition(const Executor& exec) {
    if (laplacian_) laplacian_->apply(r_, z_, partialA_, kBlock, exec);
    if (active_ == Preconditioner::Multigrid) multigrid_->apply(jacobian_, r_, z_, partialA_, kBlock, exec);
  }
  static double sumPartials(const std::vector<double>& partials) {
    double sum = 0;
    for (const double p : partials) sum += p;  // block order: the same for any thread count
    return sum;
  }

  IntegratorOptions options_;
  SpringJacobian<S> jacobian_;
  ScalarArray<S> free_;                                  // (n) 1 for free particles, 0 for pinned (the filter)
  Vec3Array<S> b_;                                       // (n x 3) right-hand side, kg m/s
  Vec3Array<S> dv_;                                      // (n x 3) velocity change (kept as the next warm start), m/s
  Vec3Array<S> r_, p_, q_;                               // (n x 3) CG residual, direction, A p
  Vec3Array<S> z_;                                       // (n x 3) preconditioned residual (not used by Jacobi)
  Vec3Array<S> inverseDiagonal_;                         // (n x 3) Jacobi preconditioner (0 on pinned particles)
  Eigen::Array<S, Eigen::Dynamic, 6> inverseBlock_;      // (n x 6) block-Jacobi: xx yy zz xy xz yz
  std::unique_ptr<SpringLaplacianSolver<S>> laplacian_;  // the projective preconditioner
  std::unique_ptr<AggregationMultigrid<S>> multigrid_;   // the multigrid preconditioner
  std::vector<double> partialA_;                         // per block of kBlock particles
  std::vector<double> partialB_;
  bool warm_ = false;      // dv_ holds the previous step's solution
  Preconditioner active_;  // the one in use: options_.preconditioner, or Auto's choice for this step
  // Auto: steps at least this long (s) take the multigrid (+infinity until a block-Jacobi
  // solve passes the threshold); the shortest length the multigrid has kept (judged cheaper,
  // or block-Jacobi stopped at the cap there; multigridStep_ returns to it on a hand-back);
  // the threshold (block-Jacobi iterations); the iterations of the block-Jacobi solve that
  // sent multigridStep_ to the multigrid, until the multigrid's first solve there is judged
  // against it (+infinity: judged, or nothing to judge).
  double multigridStep_ = std::numeric_limits<double>::infinity();
  double acceptedStep_ = std::numeric_limits<double>::infinity();
  double threshold_ = static_cast<double>(kAutoMultigridIterations);
  double trigger_ = std::numeric_limits<double>::infinity();
  // A multigrid iteration and a multigrid step's levels, in block-Jacobi iterations (1.20
  // against 0.254 ms an iteration and about 0.4 ms of levels a step, 128^2 flag, 1 thread;
  // docs/integrators.md), and the margin by which the threshold then clears the multigrid's
  // cost (so that the two do not alternate where they cost the same).
  static constexpr double kMultigridIterationCost = 4.7, kMultigridStepCost = 2, kHysteresis = 1.25;
};

}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeImplicitEuler(const Model<S>& model, const IntegratorOptions& options) {
  return std::make_unique<ImplicitEuler<S>>(model, options);
}
template std::unique_ptr<Integrator<float>> makeImplicitEuler(const Model<float>&, const IntegratorOptions&);
template std::unique_ptr<Integrator<double>> makeImplicitEuler(const Model<double>&, const IntegratorOptions&);

}  // namespace weft::detail
