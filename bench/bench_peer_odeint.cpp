// Peer benchmark (optional, built when Boost's headers are found: Debian's libboost-dev,
// which tools/setup.sh installs for tests/test_odeint.cpp): RK4 on the 128² flag as a user
// would write it with Boost.Odeint instead of weft, timed in the same binary as
// BM_Integrator_Rk4_double/size:128 and BM_Textbook_Rk4_double/size:128.
//
//   BM_Peer_Odeint_Rk4/size:N  one odeint::runge_kutta4 step of the flag at weft's dt for
//                              the flag (weft::defaultTimeStep), single-threaded, double.
//                              Counters as BM_Integrator_*'s (allocs_per_step,
//                              steps_per_second, spring_evals_per_second) and
//                              max_dx_vs_weft: after 20 steps from rest, the largest
//                              difference in any coordinate from weft's RK4 (m), so the two
//                              are seen to compute the same motion.
//
// The user's program: the state is one Eigen::VectorXd (all positions, xyz per particle,
// then all velocities), the stepper runge_kutta4 over it with odeint's vector_space_algebra
// (Eigen's own expressions for the stage sums), and the system a functor that, per call,
// zeroes a force vector, loops over the springs (the Witkin/Baraff damped spring, weft's
// force law, from arrays of endpoints, rest lengths, stiffnesses and dampings copied from
// weft's model), and writes dx/dt = v, dv/dt = f / m + g (0 for the pinned corners).
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <algorithm>
#include <boost/numeric/odeint.hpp>
#include <cmath>
#include <cstdint>
#include <functional>
#include <vector>

#include "bench_common.hpp"
#include "weft/weft.hpp"

// After odeint itself (its Eigen support specialises odeint's templates).
#include <boost/numeric/odeint/external/eigen/eigen.hpp>

namespace {

namespace odeint = boost::numeric::odeint;

using Vector = Eigen::VectorXd;
using Stepper = odeint::runge_kutta4<Vector, double, Vector, double, odeint::vector_space_algebra>;

/// The right-hand side of the flag's ODE, y = (x, v).
class FlagSystem {
 public:
  FlagSystem(const weft::Model<double>& model, const weft::Vec3d& gravity)
      : n_(model.particleCount()), gravity_(gravity.x, gravity.y, gravity.z), force_(3 * n_) {
    const weft::Springs<double>& s = model.springs();
    for (weft::Index k = 0; k < s.count(); ++k)
      springs_.push_back({s.a[k], s.b[k], s.restLength[k], s.stiffness[k], s.damping[k]});
    inverseMass_.resize(n_);
    for (weft::Index i = 0; i < n_; ++i) inverseMass_[i] = model.inverseMass()[i];
  }

  void operator()(const Vector& y, Vector& dydt, double /*t*/) {
    const auto x = y.head(3 * n_);
    const auto v = y.tail(3 * n_);
    force_.setZero();
    for (const Spring& s : springs_) {
      const Eigen::Vector3d d = x.segment<3>(3 * s.a) - x.segment<3>(3 * s.b);
      const Eigen::Vector3d dv = v.segment<3>(3 * s.a) - v.segment<3>(3 * s.b);
      const double length = d.norm();
      if (length == 0) continue;
      const Eigen::Vector3d f = d * (-(s.ks * (length - s.rest) + s.kd * dv.dot(d) / length) / length);
      force_.segment<3>(3 * s.a) += f;
      force_.segment<3>(3 * s.b) -= f;
    }
    dydt.head(3 * n_) = v;
    for (weft::Index i = 0; i < n_; ++i)
      dydt.segment<3>(3 * (n_ + i)) = inverseMass_[i] > 0
                                          ? Eigen::Vector3d(force_.segment<3>(3 * i) * inverseMass_[i] + gravity_)
                                          : Eigen::Vector3d::Zero();
    ++evaluations_;
  }

  std::int64_t evaluations() const { return evaluations_; }

 private:
  struct Spring {
    weft::Index a, b;
    double rest, ks, kd;
  };
  weft::Index n_;
  Eigen::Vector3d gravity_;
  std::vector<Spring> springs_;
  Vector inverseMass_;
  Vector force_;
  std::int64_t evaluations_ = 0;
};

Vector pack(const weft::State<double>& s) {
  const weft::Index n = static_cast<weft::Index>(s.x.rows());
  Vector y(6 * n);
  for (weft::Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      y[3 * i + c] = s.x(i, c);
      y[3 * (n + i) + c] = s.v(i, c);
    }
  return y;
}

/// max |x_odeint - x_weft| after `steps` RK4 steps of both from the flag at rest.
double differenceFromWeft(const weft::ModelAndState<double>& flag, double dt, int steps) {
  weft::SimulationOptions options;
  options.integrator = weft::IntegratorKind::Rk4;
  options.dt = dt;
  options.threads = 1;
  weft::Simulation<double> sim(weft::ModelAndState<double>{flag.model, flag.state}, options);
  if (!sim.run(steps).ok()) return NAN;
  FlagSystem system(flag.model, options.gravity);
  Vector y = pack(flag.state);
  Stepper stepper;
  for (int k = 0; k < steps; ++k) stepper.do_step(std::ref(system), y, k * dt, dt);
  double largest = 0;
  for (weft::Index i = 0; i < flag.model.particleCount(); ++i)
    for (int c = 0; c < 3; ++c) largest = std::max(largest, std::abs(y[3 * i + c] - sim.state().x(i, c)));
  return largest;
}

void BM_Peer_Odeint_Rk4(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  const weft::ModelAndState<double> flag = weft::makeFlag<double>(size);
  const double dt = weft::defaultTimeStep(weft::BuiltinScene::Flag, size);
  FlagSystem system(flag.model, weft::SimulationOptions().gravity);
  Vector y = pack(flag.state);
  Stepper stepper;
  double t = 0;
  for (int k = 0; k < 5; ++k, t += dt)
    stepper.do_step(std::ref(system), y, t, dt);  // warm up (odeint sizes its stages)
  std::int64_t steps = 0;
  const std::int64_t allocationsBefore = weftbench::allocationCount();
  for (auto _ : st) {
    stepper.do_step(std::ref(system), y, t, dt);
    t += dt;
    ++steps;
  }
  const double allocations = static_cast<double>(weftbench::allocationCount() - allocationsBefore);
  const double springs = static_cast<double>(flag.model.springCount());
  st.counters["allocs_per_step"] = steps ? allocations / static_cast<double>(steps) : 0;
  st.counters["steps_per_second"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate);
  st.counters["spring_evals_per_second"] =
      benchmark::Counter(4 * springs, benchmark::Counter::kIsIterationInvariantRate);
  st.counters["max_dx_vs_weft"] = differenceFromWeft(flag, dt, 20);
}

}  // namespace

BENCHMARK(BM_Peer_Odeint_Rk4)->Arg(128)->ArgName("size")->UseRealTime()->Unit(benchmark::kMicrosecond);
