// Semi-implicit (symplectic) Euler: v1 = v0 + h a(x0, v0), x1 = x0 + h v1. First order,
// same cost as explicit Euler, but symplectic for conservative forces: energy stays
// bounded below the stability limit omega h < 2 instead of growing.
#include "row_blocks.hpp"

namespace weft::detail {

namespace {
template <class S>
class SymplecticEuler final : public Integrator<S> {
 public:
  IntegratorKind kind() const override { return IntegratorKind::SymplecticEuler; }
  StepWork advance(ForceField<S>& forces, const Vec3Array<S>& x0, const Vec3Array<S>& v0, S h, Vec3Array<S>& x1,
                   Vec3Array<S>& v1, const Executor& exec) override {
    auto combine = [&](Index b, Index n, const S* ax, const S* ay, const S* az) {
      for (int c = 0; c < 3; ++c) {
        rows(v1, c, b, n) = rows(v0, c, b, n) + h * accel(ax, ay, az, c, n);
        rows(x1, c, b, n) = rows(x0, c, b, n) + h * rows(v1, c, b, n);
      }
    };
    forces.setStageOffset(0);
    forces.accelerations(x0, v0, makeSink<S>(combine), exec);
    return {1, 1};
  }
};
}  // namespace

template <class S>
std::unique_ptr<Integrator<S>> makeSymplecticEuler(Index) {
  return std::make_unique<SymplecticEuler<S>>();
}
template std::unique_ptr<Integrator<float>> makeSymplecticEuler(Index);
template std::unique_ptr<Integrator<double>> makeSymplecticEuler(Index);

}  // namespace weft::detail
