// Classic fourth-order Runge-Kutta on (x, v):
//   k1 = (v0,      a(x0, v0))
//   k2 = (v2,      a(x2, v2)),  (x2, v2) = (x0, v0) + h/2 k1
//   k3 = (v3,      a(x3, v3)),  (x3, v3) = (x0, v0) + h/2 k2
//   k4 = (v4,      a(x4, v4)),  (x4, v4) = (x0, v0) + h   k3
//   (x1, v1) = (x0, v0) + h/6 (k1 + 2 k2 + 2 k3 + k4)
// The weighted sums are accumulated as the stages go, fused with forming the next stage
// state, so a step is 4 force evaluations plus 4 streaming passes and 6 stage buffers.
#include "row_blocks.hpp"

namespace weft::detail {

namespace {
template <class S>
class Rk4 final : public Integrator<S> {
 public:
  explicit Rk4(Index n) : a_(n, 3), xs_(n, 3), vs_(n, 3), sumV_(n, 3), sumA_(n, 3) {}
  IntegratorKind kind() const override { return IntegratorKind::Rk4; }
  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    const Index n = static_cast<Index>(x0.rows());
    const S half = h / S(2);
    const S sixth = h / S(6);
    // Stage 1.
    forces.accelerations(x0, v0, a_, exec);
    forRowBlocks(exec, n, [&](Index b, Index len) {
      sumV_.middleRows(b, len) = v0.middleRows(b, len);
      sumA_.middleRows(b, len) = a_.middleRows(b, len);
      xs_.middleRows(b, len) = x0.middleRows(b, len) + half * v0.middleRows(b, len);
      vs_.middleRows(b, len) = v0.middleRows(b, len) + half * a_.middleRows(b, len);
    });
    // Stages 2 and 3: k = (vs, a(xs, vs)); next stage at h/2, then at h.
    for (int stage = 2; stage <= 3; ++stage) {
      const S reach = stage == 2 ? half : h;
      forces.accelerations(xs_, vs_, a_, exec);
      forRowBlocks(exec, n, [&](Index b, Index len) {
        sumV_.middleRows(b, len) += S(2) * vs_.middleRows(b, len);
        sumA_.middleRows(b, len) += S(2) * a_.middleRows(b, len);
        xs_.middleRows(b, len) = x0.middleRows(b, len) + reach * vs_.middleRows(b, len);
        vs_.middleRows(b, len) = v0.middleRows(b, len) + reach * a_.middleRows(b, len);
      });
    }
    // Stage 4 and the weighted combination.
    forces.accelerations(xs_, vs_, a_, exec);
    forRowBlocks(exec, n, [&](Index b, Index len) {
      x1.middleRows(b, len) = x0.middleRows(b, len) + sixth * (sumV_.middleRows(b, len) + vs_.middleRows(b, len));
      v1.middleRows(b, len) = v0.middleRows(b, len) + sixth * (sumA_.middleRows(b, len) + a_.middleRows(b, len));
    });
    return {4};
  }

 private:
  Vec3Array<S> a_;     // (n x 3) stage accelerations, m/s^2
  Vec3Array<S> xs_;    // (n x 3) stage positions, m
  Vec3Array<S> vs_;    // (n x 3) stage velocities, m/s
  Vec3Array<S> sumV_;  // (n x 3) k1x + 2 k2x + 2 k3x, m/s
  Vec3Array<S> sumA_;  // (n x 3) k1v + 2 k2v + 2 k3v, m/s^2
};
}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeRk4(Index n) {
  return std::make_unique<Rk4<S>>(n);
}
template std::unique_ptr<Integrator<float>> makeRk4(Index);
template std::unique_ptr<Integrator<double>> makeRk4(Index);

}  // namespace weft::detail
