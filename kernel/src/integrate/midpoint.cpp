// Explicit midpoint (RK2): a half Euler step to (xm, vm) = (x0 + h/2 v0, v0 + h/2 a0),
// then the full step with the derivative there: x1 = x0 + h vm, v1 = v0 + h a(xm, vm).
// Second order, two force evaluations per step.
#include "row_blocks.hpp"

namespace weft::detail {

namespace {
template <class S>
class Midpoint final : public Integrator<S> {
 public:
  explicit Midpoint(Index n) : a_(n, 3), xm_(n, 3), vm_(n, 3) {}
  IntegratorKind kind() const override { return IntegratorKind::Midpoint; }
  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    const Index n = static_cast<Index>(x0.rows());
    const S half = h / S(2);
    forces.accelerations(x0, v0, a_, exec);
    forRowBlocks(exec, n, [&](Index b, Index len) {
      xm_.middleRows(b, len) = x0.middleRows(b, len) + half * v0.middleRows(b, len);
      vm_.middleRows(b, len) = v0.middleRows(b, len) + half * a_.middleRows(b, len);
    });
    forces.accelerations(xm_, vm_, a_, exec);
    forRowBlocks(exec, n, [&](Index b, Index len) {
      x1.middleRows(b, len) = x0.middleRows(b, len) + h * vm_.middleRows(b, len);
      v1.middleRows(b, len) = v0.middleRows(b, len) + h * a_.middleRows(b, len);
    });
    return {2};
  }

 private:
  Vec3Array<S> a_;   // (n x 3) accelerations, m/s^2
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
