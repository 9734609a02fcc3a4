// Adaptive Dormand-Prince 5(4) on (x, v), after Hairer, Norsett & Wanner, "Solving
// Ordinary Differential Equations I", section II.4 and II.5 (the DOPRI5 tableau, the
// first-same-as-last property, the PI step-size controller).
//
// Stage j (1..7) is (X_j, V_j) = (x0, v0) + h sum_{l<j} a_jl (V_l, A_l) with
// A_l = a(X_l, V_l); the fifth-order solution is stage 7 itself (its row of a is b), so
// A_7 is the next substep's A_1: six force evaluations per accepted substep. The error
// estimate is h sum_l e_l (V_l, A_l) with e = b - b_hat (the embedded fourth-order
// weights); its size is the largest |error| / (atol + rtol max(|y0|, |y1|)) over every
// coordinate of every particle (a max norm: stricter than the usual RMS, and independent
// of the reduction order, so the accept/reject decisions and hence the result are the
// same for any thread count).
//
// As elsewhere, each stage's combination runs in the sink of the force evaluation that
// produced it: stage j's sink stores A_j and forms stage j + 1. Stage positions
// alternate between two buffers (a sink may not write the state being evaluated);
// stage velocities are kept (they are the position slopes V_l). Accepted substeps
// ping-pong between (x1, v1) and an internal buffer; x0, v0 are never written.
//
// Adaptive mode covers the step h with substeps: the proposal after an accepted substep
// is h_s * clamp(0.9 err^-0.17 err_prev^0.04, 0.2, 10) (the PI controller of DOPRI5);
// after a rejection h_s * max(0.2, 0.9 err^-0.2), with no growth on the next proposal.
// The last substep is clipped to end exactly at h (the proposal survives the clipping),
// and the proposal is carried to the next step (reset() forgets it, and the FSAL slope).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <utility>

#include "core/text.hpp"
#include "row_blocks.hpp"

namespace weft::detail {

namespace {

constexpr int kStages = 7;
// Nodes c_j: stage j is evaluated at t + c_j h.
constexpr double kC[kStages] = {0, 1.0 / 5, 3.0 / 10, 4.0 / 5, 8.0 / 9, 1, 1};
// a[j][l]: stage j + 1 from the slopes of stages 1 .. j (row j, 0-based; row 0 unused).
constexpr double kA[kStages][kStages - 1] = {
    {0, 0, 0, 0, 0, 0},
    {1.0 / 5, 0, 0, 0, 0, 0},
    {3.0 / 40, 9.0 / 40, 0, 0, 0, 0},
    {44.0 / 45, -56.0 / 15, 32.0 / 9, 0, 0, 0},
    {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729, 0, 0},
    {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656, 0},
    {35.0 / 384, 0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84},  // = b
};
// e = b - b_hat, b_hat = (5179/57600, 0, 7571/16695, 393/640, -92097/339200, 187/2100, 1/40).
constexpr double kE[kStages] = {71.0 / 57600, 0, -71.0 / 16695, 71.0 / 1920, -17253.0 / 339200, 22.0 / 525, -1.0 / 40};

void atomicMax(std::atomic<double>& target, double value) {
  double current = target.load(std::memory_order_relaxed);
  while (value > current && !target.compare_exchange_weak(current, value, std::memory_order_relaxed)) {
  }
}

template <class S>
class Rk45 final : public Integrator<S> {
 public:
  /// `omegaMax`: the model's largest angular frequency bound (maxAngularFrequency), rad/s,
  /// for the rounding floor of the velocity error (see blockError).
  Rk45(Index n, const IntegratorOptions& o, double omegaMax) : options_(o), xn_(n, 3), vn_(n, 3) {
    double sumE = 0;
    for (const double e : kE) sumE += std::abs(e);
    noiseRate_ = static_cast<double>(std::numeric_limits<S>::epsilon()) * omegaMax * omegaMax * sumE;
    for (auto& a : a_) a.setZero(n, 3);  // (no garbage in a checkpoint)
    for (auto& v : vs_) v.resize(n, 3);
    for (auto& x : xs_) x.resize(n, 3);
  }
  IntegratorKind kind() const override { return IntegratorKind::Rk45; }
  void reset() override {
    primed_ = false;
    proposal_ = 0;
    errorPrevious_ = 1e-4;
  }
  void saveCarry(ArchiveWriter& out) const override {
    out.value(primed_);
    out.value(proposal_);
    out.value(errorPrevious_);
    out.array(a_[0]);
  }
  void loadCarry(ArchiveReader& in) override {
    in.flag(primed_, "rk45's flag");
    in.value(proposal_);
    in.value(errorPrevious_);
    in.array(a_[0], a_[0].rows(), 3, "rk45's first slope", primed_);  // (read only when primed)
    if (!(std::isfinite(proposal_) && proposal_ >= 0 && std::isfinite(errorPrevious_) && errorPrevious_ > 0))
      in.fail("rk45's proposed substep " + detail::number(proposal_) + " or error " + detail::number(errorPrevious_) +
              " is out of range");
  }

  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    StepWork work;
    const double H = static_cast<double>(h);
    if (!options_.adaptive) {
      substep(forces, x0, v0, h, 0, x1, v1, exec, work);
      work.substeps = 1;
      primed_ = true;
      std::swap(a_[0], a_[kStages - 1]);  // FSAL: A_7 at y1 is the next step's A_1
      return work;
    }
    const Vec3Array<S>* xc = &x0;
    const Vec3Array<S>* vc = &v0;
    double t = 0;
    double hs = proposal_ > 0 ? std::min(proposal_, H) : H;
    bool grew = true;  // growth allowed (false right after a rejection)
    // A step shorter than minSubstep is tried whole once: the floor is on substeps the error
    // control shrank, not on the step the caller chose.
    const double floor = std::min(options_.minSubstep, H);
    for (;;) {
      if (work.substeps + work.rejectedSubsteps >= options_.maxSubsteps || !(hs >= floor)) {
        work.failed = true;
        return work;
      }
      const double remaining = H - t;
      const bool last = hs >= remaining * (1 - 1e-9);  // also swallows a remainder below 1e-9 h_s
      const double used = last ? remaining : hs;
      Vec3Array<S>& xt = xc == &x1 ? xn_ : x1;  // target: whichever of (x1, xn) is not current
      Vec3Array<S>& vt = xc == &x1 ? vn_ : v1;
      const double err = substep(forces, *xc, *vc, static_cast<S>(used), t, xt, vt, exec, work);
      if (err <= 1) {
        ++work.substeps;
        work.errorEstimate = std::max(work.errorEstimate, err);
        std::swap(a_[0], a_[kStages - 1]);
        primed_ = true;
        xc = &xt;
        vc = &vt;
        const double e = std::max(err, 1e-10);
        double factor = std::clamp(0.9 * std::pow(e, -0.17) * std::pow(errorPrevious_, 0.04), 0.2, 10.0);
        if (!grew) factor = std::min(factor, 1.0);
        errorPrevious_ = std::max(err, 1e-4);
        grew = true;
        // A clipped last substep says little about the natural size: keep the larger of
        // the old proposal and the one from the clipped step.
        const double next = used * factor;
        hs = last ? std::max(hs, next) : next;
        if (last) break;
        t += used;
      } else {
        ++work.rejectedSubsteps;
        const double factor = std::isfinite(err) ? std::max(0.2, 0.9 * std::pow(err, -0.2)) : 0.2;
        hs = used * factor;
        grew = false;
      }
    }
    proposal_ = hs;
    if (xc != &x1) {
      exec.parallelFor(static_cast<Index>(x1.rows()), ForceField<S>::kSinkBlock, [&](Index b, Index e) {
        for (int c = 0; c < 3; ++c) {
          rows(x1, c, b, e - b) = rows(xn_, c, b, e - b);
          rows(v1, c, b, e - b) = rows(vn_, c, b, e - b);
        }
      });
    }
    return work;
  }

 private:
  /// One Dormand-Prince substep from (x0, v0) to (x1, v1); returns the scaled error (NaN
  /// read as infinite). Uses a_[0] = A_1 if primed_, leaves A_7 in a_[6].
  /// `start` is the substep's offset from the start of the step (for time-dependent forces).
  double substep(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, double start,
                 Vec3Array<S>& x1, Vec3Array<S>& v1, const Executor& exec, StepWork& work) {
    const Index n = static_cast<Index>(x0.rows());
    // Velocity slope of stage l (1-based): v0 for stage 1, vs_[l - 2] for 2..6, v1 for 7.
    auto slopeV = [&](int l) -> const Vec3Array<S>& { return l == 1 ? v0 : l == kStages ? v1 : vs_[l - 2]; };
    // Stage j + 1 from the slopes of stages 1 .. j, for rows [b, b + m).
    auto formStage = [&](int j, Index b, Index m) {
      Vec3Array<S>& xt = j + 1 == kStages ? x1 : xs_[(j + 1) % 2];
      Vec3Array<S>& vt = j + 1 == kStages ? v1 : vs_[j - 1];
      for (int c = 0; c < 3; ++c) {
        auto xo = rows(xt, c, b, m);
        auto vo = rows(vt, c, b, m);
        xo = rows(x0, c, b, m);
        vo = rows(v0, c, b, m);
        for (int l = 1; l <= j; ++l) {
          const S w = static_cast<S>(static_cast<double>(h) * kA[j][l - 1]);
          if (w == S(0)) continue;
          xo += w * rows(slopeV(l), c, b, m);
          vo += w * rows(a_[l - 1], c, b, m);
        }
      }
    };
    // Below a few dozen ulps the estimate measures rounding, not truncation: tighter
    // tolerances then only shrink the substeps (float at 1e-6 took 40x the substeps of
    // 1e-5 on the 128^2 flag). The floor is 64 eps: 7.6e-6 in float, 1.4e-14 in double.
    constexpr double kFloor = 64 * static_cast<double>(std::numeric_limits<S>::epsilon());
    const S atol = static_cast<S>(std::max(options_.absoluteTolerance, kFloor));
    const S rtol = static_cast<S>(std::max(options_.relativeTolerance, kFloor));
    std::atomic<double> errMax{0.0};
    // The rounding floor of the velocity error. A coordinate is stored to eps |x|, a
    // spring's vector x_j - x_i keeps that absolute error however short the spring is, and
    // the stiffness turns it into noise of up to about eps |x| omega_max^2 in every stage's
    // accelerations (measured on the 128^2 flag in float: a quarter to half of that); the
    // velocity error h sum_l E_l A_l then holds up to h sum |E_l| times it, which shrinks
    // only linearly with h. Below it the estimate measures rounding, and a controller
    // chasing it cut float substeps in proportion to the tolerance: 1562 a 1/60 s frame of
    // the 128^2 flag at 1e-6 (double: 80), and 12x more with a cloth moved 10 m from the
    // origin. Per block, with the block's largest |x|. Far below any tolerance in double.
    const S noisePerMetre = static_cast<S>(static_cast<double>(h) * noiseRate_);
    // The error of rows [b, b + m), once A_7 is known.
    auto blockError = [&](Index b, Index m) {
      S worst = 0;
      S largest = 0;  // the block's largest |coordinate| at the start of the substep, m
      for (int c = 0; c < 3; ++c) largest = std::max(largest, rows(x0, c, b, m).abs().maxCoeff());
      for (int c = 0; c < 3; ++c) {
        for (int part = 0; part < 2; ++part) {
          const Vec3Array<S>& y0 = part == 0 ? x0 : v0;
          const Vec3Array<S>& y1 = part == 0 ? x1 : v1;
          // e = h sum_l e_l slope_l, evaluated without a temporary (blocks are <= 256 rows).
          alignas(64) S buffer[ForceField<S>::kSinkBlock];
          Column<S> acc(buffer, m);
          acc.setZero();
          for (int l = 1; l <= kStages; ++l) {
            const S w = static_cast<S>(static_cast<double>(h) * kE[l - 1]);
            if (w == S(0)) continue;
            acc += w * (part == 0 ? rows(slopeV(l), c, b, m) : rows(std::as_const(a_[l - 1]), c, b, m));
          }
          const S floor = part == 0 ? S(0) : noisePerMetre * largest;
          const auto scale = (atol + rtol * rows(y0, c, b, m).abs().max(rows(y1, c, b, m).abs())).max(floor);
          const S blockWorst = (acc.abs() / scale).template maxCoeff<Eigen::PropagateNaN>();
          if (!(blockWorst <= worst)) worst = blockWorst;  // NaN sticks
        }
      }
      atomicMax(errMax, std::isnan(worst) ? std::numeric_limits<double>::infinity() : static_cast<double>(worst));
    };

    if (primed_) {
      exec.parallelFor(n, ForceField<S>::kSinkBlock, [&](Index b, Index e) { formStage(1, b, e - b); });
    } else {
      auto first = [&](Index b, Index m, const S* ax, const S* ay, const S* az) {
        for (int c = 0; c < 3; ++c) rows(a_[0], c, b, m) = accel(ax, ay, az, c, m);
        formStage(1, b, m);
      };
      forces.setStageOffset(start);
      forces.accelerations(x0, v0, makeSink<S>(first), exec);
      ++work.forceEvaluations;
      primed_ = true;  // A_1 stays valid if this substep is rejected: x0 does not change
    }
    for (int j = 2; j <= kStages; ++j) {
      const Vec3Array<S>& xj = j == kStages ? x1 : xs_[j % 2];
      const Vec3Array<S>& vj = slopeV(j);
      auto stage = [&](Index b, Index m, const S* ax, const S* ay, const S* az) {
        for (int c = 0; c < 3; ++c) rows(a_[j - 1], c, b, m) = accel(ax, ay, az, c, m);
        if (j < kStages)
          formStage(j, b, m);
        else if (options_.adaptive)
          blockError(b, m);
      };
      forces.setStageOffset(start + kC[j - 1] * static_cast<double>(h));
      forces.accelerations(xj, vj, makeSink<S>(stage), exec);
      ++work.forceEvaluations;
    }
    return errMax.load(std::memory_order_relaxed);
  }

  IntegratorOptions options_;
  Vec3Array<S> a_[kStages];       // (n x 3) stage accelerations A_1 .. A_7, m/s^2
  Vec3Array<S> vs_[kStages - 2];  // (n x 3) stage velocities V_2 .. V_6, m/s
  Vec3Array<S> xs_[2];            // (n x 3) stage positions, alternating, m
  Vec3Array<S> xn_, vn_;          // (n x 3) the other half of the substep ping-pong
  bool primed_ = false;           // a_[0] holds A_1 at the current state (FSAL)
  double proposal_ = 0;           // next substep size, s (0: none yet)
  double errorPrevious_ = 1e-4;   // last accepted error, for the PI controller
  double noiseRate_ = 0;          // eps omega_max^2 sum |E_l|: the velocity error's rounding floor per (s m)
};

}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeRk45(Index n, const IntegratorOptions& options, double omegaMax) {
  return std::make_unique<Rk45<S>>(n, options, omegaMax);
}
template std::unique_ptr<Integrator<float>> makeRk45(Index, const IntegratorOptions&, double);
template std::unique_ptr<Integrator<double>> makeRk45(Index, const IntegratorOptions&, double);

}  // namespace weft::detail
