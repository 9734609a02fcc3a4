// Velocity Verlet, with a velocity predictor for velocity-dependent (damping) forces:
//   x1 = x0 + h v0 + h^2/2 a0
//   a1 = a(x1, v0 + h a0)
//   v1 = v0 + h/2 (a0 + a1)
// For conservative forces this is the classic symplectic, time-reversible, second-order
// method (stable for omega h < 2, energy bounded). With damping, evaluating a1 at the
// predicted velocity v0 + h a0 (error O(h^2)) keeps it second order; the textbook choice
// of the half-step velocity would make it first order.
//
// a1 is kept and used as the next step's a0, so a step costs one force evaluation. The
// cache is valid only while the state evolves by this integrator's accepted steps: the
// Simulation calls reset() on setState() and after a rejected step, and the next step
// then evaluates a0 itself (two evaluations, reported in StepWork).
#include "row_blocks.hpp"

namespace weft::detail {

namespace {
template <class S>
class VelocityVerlet final : public Integrator<S> {
 public:
  explicit VelocityVerlet(Index n) : a_(Vec3Array<S>::Zero(n, 3)), vp_(n, 3) {}  // (a_: no garbage in a checkpoint)
  IntegratorKind kind() const override { return IntegratorKind::VelocityVerlet; }
  void reset() override { primed_ = false; }
  void saveCarry(ArchiveWriter& out) const override {
    out.value(primed_);
    out.array(a_);
  }
  void loadCarry(ArchiveReader& in) override {
    in.flag(primed_, "verlet's flag");
    in.array(a_, a_.rows(), 3, "verlet's acceleration", primed_);  // (read only when primed)
  }

  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    StepWork work;
    work.substeps = 1;
    if (!primed_) {
      forces.setStageOffset(0);
      forces.accelerations(x0, v0, a_, exec);  // a0
      ++work.forceEvaluations;
    }
    const S halfH2 = h * h / S(2);
    const S half = h / S(2);
    // Drift: x1 and the predicted velocity, from x0, v0, a0.
    exec.parallelFor(static_cast<Index>(x0.rows()), ForceField<S>::kSinkBlock, [&](Index b, Index e) {
      const Index n = e - b;
      for (int c = 0; c < 3; ++c) {
        rows(x1, c, b, n) = rows(x0, c, b, n) + h * rows(v0, c, b, n) + halfH2 * rows(a_, c, b, n);
        rows(vp_, c, b, n) = rows(v0, c, b, n) + h * rows(a_, c, b, n);
      }
    });
    // Kick: a1 at (x1, predicted v); v1 from the average acceleration; a1 becomes a0.
    auto kick = [&](Index b, Index n, const S* ax, const S* ay, const S* az) {
      for (int c = 0; c < 3; ++c) {
        const auto a1 = accel(ax, ay, az, c, n);
        rows(v1, c, b, n) = rows(v0, c, b, n) + half * (rows(a_, c, b, n) + a1);
        rows(a_, c, b, n) = a1;
      }
    };
    forces.setStageOffset(static_cast<double>(h));
    forces.accelerations(x1, vp_, makeSink<S>(kick), exec);
    ++work.forceEvaluations;
    primed_ = true;
    return work;
  }

 private:
  Vec3Array<S> a_;   // (n x 3) a0 on entry, a1 on exit, m/s^2
  Vec3Array<S> vp_;  // (n x 3) predicted velocity v0 + h a0, m/s
  bool primed_ = false;
};
}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeVelocityVerlet(Index n) {
  return std::make_unique<VelocityVerlet<S>>(n);
}
template std::unique_ptr<Integrator<float>> makeVelocityVerlet(Index);
template std::unique_ptr<Integrator<double>> makeVelocityVerlet(Index);

}  // namespace weft::detail
