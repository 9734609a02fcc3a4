// Explicit (forward) Euler: x1 = x0 + h v0, v1 = v0 + h a(x0, v0). First order; with no
// damping its amplification factor exceeds 1 for every h (the original design's
// "stiffness problem"), so it is here as the baseline and for teaching, not for use.
#include "row_blocks.hpp"

namespace weft::detail {

namespace {
template <class S>
class ExplicitEuler final : public Integrator<S> {
 public:
  explicit ExplicitEuler(Index n) : a_(n, 3) {}
  IntegratorKind kind() const override { return IntegratorKind::ExplicitEuler; }
  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    forces.accelerations(x0, v0, a_, exec);
    forRowBlocks(exec, static_cast<Index>(x0.rows()), [&](Index b, Index len) {
      x1.middleRows(b, len) = x0.middleRows(b, len) + h * v0.middleRows(b, len);
      v1.middleRows(b, len) = v0.middleRows(b, len) + h * a_.middleRows(b, len);
    });
    return {1};
  }

 private:
  Vec3Array<S> a_;  // (n x 3) accelerations, m/s^2
};
}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeExplicitEuler(Index n) {
  return std::make_unique<ExplicitEuler<S>>(n);
}
template std::unique_ptr<Integrator<float>> makeExplicitEuler(Index);
template std::unique_ptr<Integrator<double>> makeExplicitEuler(Index);

}  // namespace weft::detail
