// Classic fourth-order Runge-Kutta on (x, v):
//   k1 = (v0, a(x0, v0))
//   k2 = (v2, a(x2, v2)),  (x2, v2) = (x0, v0) + h/2 k1
//   k3 = (v3, a(x3, v3)),  (x3, v3) = (x0, v0) + h/2 k2
//   k4 = (v4, a(x4, v4)),  (x4, v4) = (x0, v0) + h   k3
//   (x1, v1) = (x0, v0) + h/6 (k1 + 2 k2 + 2 k3 + k4)
// Each stage's combination runs inside its force evaluation (an AccelerationSink): the
// weighted sums accumulate and the next stage state is formed while the accelerations
// are in L1. A sink may not write the state being evaluated, so stage states alternate
// between two buffers: the stage buffer A and the output (x1, v1), which is free until the
// last stage writes the result: x0 -> A -> (x1, v1) -> A -> (x1, v1). 4 force evaluations,
// 4 passes, and four state-sized buffers of its own (A and the two sums).
#include "row_blocks.hpp"

namespace weft::detail {

namespace {
template <class S>
class Rk4 final : public Integrator<S> {
 public:
  explicit Rk4(Index n) : xa_(n, 3), va_(n, 3), sumV_(n, 3), sumA_(n, 3) {}
  IntegratorKind kind() const override { return IntegratorKind::Rk4; }
  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    const S half = h / S(2);
    const S sixth = h / S(6);
    auto stage1 = [&](Index b, Index n, const S* ax, const S* ay, const S* az) {
      for (int c = 0; c < 3; ++c) {
        const auto a = accel(ax, ay, az, c, n);
        rows(sumV_, c, b, n) = rows(v0, c, b, n);
        rows(sumA_, c, b, n) = a;
        rows(xa_, c, b, n) = rows(x0, c, b, n) + half * rows(v0, c, b, n);
        rows(va_, c, b, n) = rows(v0, c, b, n) + half * a;
      }
    };
    forces.setStageOffset(0);
    forces.accelerations(x0, v0, makeSink<S>(stage1), exec);
    // Stages 2 and 3: k = (vs, a(xs, vs)) from (xs, vs); the next stage state, at h/2 then
    // at h, into (xt, vt).
    auto middle = [&](const Vec3Array<S>& xs, const Vec3Array<S>& vs, Vec3Array<S>& xt, Vec3Array<S>& vt, S reach) {
      auto stage = [&](Index b, Index n, const S* ax, const S* ay, const S* az) {
        for (int c = 0; c < 3; ++c) {
          const auto a = accel(ax, ay, az, c, n);
          rows(sumV_, c, b, n) += S(2) * rows(vs, c, b, n);
          rows(sumA_, c, b, n) += S(2) * a;
          rows(xt, c, b, n) = rows(x0, c, b, n) + reach * rows(vs, c, b, n);
          rows(vt, c, b, n) = rows(v0, c, b, n) + reach * a;
        }
      };
      forces.accelerations(xs, vs, makeSink<S>(stage), exec);
    };
    forces.setStageOffset(static_cast<double>(half));  // stages 2 and 3 are at t + h/2
    // (x1, v1) holds stage 3's state until stage 4 writes the result there.
    middle(xa_, va_, x1, v1, half);
    middle(x1, v1, xa_, va_, h);
    auto stage4 = [&](Index b, Index n, const S* ax, const S* ay, const S* az) {
      for (int c = 0; c < 3; ++c) {
        rows(x1, c, b, n) = rows(x0, c, b, n) + sixth * (rows(sumV_, c, b, n) + rows(va_, c, b, n));
        rows(v1, c, b, n) = rows(v0, c, b, n) + sixth * (rows(sumA_, c, b, n) + accel(ax, ay, az, c, n));
      }
    };
    forces.setStageOffset(static_cast<double>(h));
    forces.accelerations(xa_, va_, makeSink<S>(stage4), exec);
    return {4, 1};
  }

 private:
  Vec3Array<S> xa_, va_;  // (n x 3) stage state A: positions m, velocities m/s
  Vec3Array<S> sumV_;     // (n x 3) k1x + 2 k2x + 2 k3x, m/s
  Vec3Array<S> sumA_;     // (n x 3) k1v + 2 k2v + 2 k3v, m/s^2
};
}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeRk4(Index n) {
  return std::make_unique<Rk4<S>>(n);
}
template std::unique_ptr<Integrator<float>> makeRk4(Index);
template std::unique_ptr<Integrator<double>> makeRk4(Index);

}  // namespace weft::detail
