// Explicit midpoint (RK2): a half Euler step to (xm, vm) = (x0 + h/2 v0, v0 + h/2 a0),
// then the full step with the derivative there: x1 = x0 + h vm, v1 = v0 + h a(xm, vm).
// Second order, two force evaluations per step.
#include "row_blocks.hpp"

namespace weft::detail {

namespace {
template <class S>
class Midpoint final : public Integrator<S> {
 public:
  explicit Midpoint(Index n) : xm_(n, 3), vm_(n, 3) {}
  IntegratorKind kind() const override { return IntegratorKind::Midpoint; }
  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    const S half = h / S(2);
    auto toMidpoint = [&](Index b, Index n, const S* ax, const S* ay, const S* az) {
      for (int c = 0; c < 3; ++c) {
        rows(xm_, c, b, n) = rows(x0, c, b, n) + half * rows(v0, c, b, n);
        rows(vm_, c, b, n) = rows(v0, c, b, n) + half * accel(ax, ay, az, c, n);
      }
    };
    forces.setStageOffset(0);
    forces.accelerations(x0, v0, makeSink<S>(toMidpoint), exec);
    auto fullStep = [&](Index b, Index n, const S* ax, const S* ay, const S* az) {
      for (int c = 0; c < 3; ++c) {
        rows(x1, c, b, n) = rows(x0, c, b, n) + h * rows(vm_, c, b, n);
        rows(v1, c, b, n) = rows(v0, c, b, n) + h * accel(ax, ay, az, c, n);
      }
    };
    forces.setStageOffset(static_cast<double>(half));
    forces.accelerations(xm_, vm_, makeSink<S>(fullStep), exec);
    return {2, 1};
  }

 private:
  Vec3Array<S> xm_;  // (n x 3) midpoint positions, m
  Vec3Array<S> vm_;  // (n x 3) midpoint velocities, m/s
};
}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeMidpoint(Index n) {
  return std::make_unique<Midpoint<S>>(n);
}
template std::unique_ptr<Integrator<float>> makeMidpoint(Index);
template std::unique_ptr<Integrator<double>> makeMidpoint(Index);

}  // namespace weft::detail
