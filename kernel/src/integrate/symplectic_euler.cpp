// Semi-implicit (symplectic) Euler: v1 = v0 + h a(x0, v0), x1 = x0 + h v1. First order,
// same cost as explicit Euler, but symplectic for conservative forces: energy stays
// bounded below the stability limit omega h < 2 instead of growing.
#include "row_blocks.hpp"

namespace weft::detail {

namespace {
template <class S>
class SymplecticEuler final : public Integrator<S> {
 public:
  explicit SymplecticEuler(Index n) : a_(n, 3) {}
  IntegratorKind kind() const override { return IntegratorKind::SymplecticEuler; }
  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    forces.accelerations(x0, v0, a_, exec);
    forRowBlocks(exec, static_cast<Index>(x0.rows()), [&](Index b, Index len) {
      v1.middleRows(b, len) = v0.middleRows(b, len) + h * a_.middleRows(b, len);
      x1.middleRows(b, len) = x0.middleRows(b, len) + h * v1.middleRows(b, len);
    });
    return {1};
  }

 private:
  Vec3Array<S> a_;  // (n x 3) accelerations, m/s^2
};
}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeSymplecticEuler(Index n) {
  return std::make_unique<SymplecticEuler<S>>(n);
}
template std::unique_ptr<Integrator<float>> makeSymplecticEuler(Index);
template std::unique_ptr<Integrator<double>> makeSymplecticEuler(Index);

}  // namespace weft::detail
