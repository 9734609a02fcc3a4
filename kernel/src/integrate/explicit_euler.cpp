// Explicit (forward) Euler: x1 = x0 + h v0, v1 = v0 + h a(x0, v0). First order; with no
// damping its amplification factor exceeds 1 for every h (the original design's
// "stiffness problem"), so it is here as the baseline and for teaching, not for use.
#include "row_blocks.hpp"

namespace weft::detail {

namespace {
template <class S>
class ExplicitEuler final : public Integrator<S> {
 public:
  IntegratorKind kind() const override { return IntegratorKind::ExplicitEuler; }
  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    auto combine = [&](Index b, Index n, const S* ax, const S* ay, const S* az) {
      for (int c = 0; c < 3; ++c) {
        rows(x1, c, b, n) = rows(x0, c, b, n) + h * rows(v0, c, b, n);
        rows(v1, c, b, n) = rows(v0, c, b, n) + h * accel(ax, ay, az, c, n);
      }
    };
    forces.setStageOffset(0);
    forces.accelerations(x0, v0, makeSink<S>(combine), exec);
    return {1, 1};
  }
};
}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeExplicitEuler(Index) {
  return std::make_unique<ExplicitEuler<S>>();
}
template std::unique_ptr<Integrator<float>> makeExplicitEuler(Index);
template std::unique_ptr<Integrator<double>> makeExplicitEuler(Index);

}  // namespace weft::detail
