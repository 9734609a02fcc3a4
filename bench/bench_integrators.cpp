// BM_Integrator_*: one full Simulation::step (all stages, stability check) on the flag,
// each integrator, float and double, 1 and 2 threads, at 128^2 (and 256^2 for the
// thread-scaling target). BM_Textbook_Rk4: the array-of-structs baseline, 1 thread,
// double, same scene and dt. Each reports allocations per step (expected 0 for weft).
#include <benchmark/benchmark.h>

#include "bench_common.hpp"
#include "textbook.hpp"
#include "weft/weft.hpp"

namespace {

template <class S, weft::IntegratorKind Kind>
void BM_Integrator(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  weft::SimulationOptions options;
  options.integrator = Kind;
  options.threads = static_cast<int>(st.range(1));
  options.dt = weft::defaultTimeStep(weft::BuiltinScene::Flag, size);
  // Explicit Euler is unstable on this scene; its cost per step is what is measured, so
  // the stability check must not stop it.
  options.stability.enabled = Kind != weft::IntegratorKind::ExplicitEuler;
  weft::Simulation<S> sim(weft::makeFlag<S>(size), options);
  const weft::State<S> initial = sim.state();
  sim.run(5);  // warm up
  std::int64_t steps = 0;
  const std::int64_t allocationsBefore = weftbench::allocationCount();
  for (auto _ : st) {
    if (!sim.step().ok() || (Kind == weft::IntegratorKind::ExplicitEuler && steps % 50 == 49)) {
      st.PauseTiming();
      sim.setState(initial);
      st.ResumeTiming();
    }
    ++steps;
  }
  const double allocations = static_cast<double>(weftbench::allocationCount() - allocationsBefore);
  const double springs = static_cast<double>(sim.model().springCount());
  const double evals = static_cast<double>(sim.lastWork().forceEvaluations);
  st.counters["allocs_per_step"] = steps ? allocations / static_cast<double>(steps) : 0;
  st.counters["steps_per_second"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate);
  st.counters["spring_evals_per_second"] =
      benchmark::Counter(springs * evals, benchmark::Counter::kIsIterationInvariantRate);
}

void integratorArgs(benchmark::internal::Benchmark* b) {
  for (int size : {128, 256})
    for (int threads : {1, 2}) b->Args({size, threads});
  b->ArgNames({"size", "threads"})->UseRealTime()->Unit(benchmark::kMicrosecond);
}

using weft::IntegratorKind;
#define WEFT_INTEGRATOR(NAME, S, KIND)                            \
  void NAME(benchmark::State& st) { BM_Integrator<S, KIND>(st); } \
  BENCHMARK(NAME)->Apply(integratorArgs)

WEFT_INTEGRATOR(BM_Integrator_Euler_float, float, IntegratorKind::ExplicitEuler);
WEFT_INTEGRATOR(BM_Integrator_Euler_double, double, IntegratorKind::ExplicitEuler);
WEFT_INTEGRATOR(BM_Integrator_Symplectic_float, float, IntegratorKind::SymplecticEuler);
WEFT_INTEGRATOR(BM_Integrator_Symplectic_double, double, IntegratorKind::SymplecticEuler);
WEFT_INTEGRATOR(BM_Integrator_Midpoint_float, float, IntegratorKind::Midpoint);
WEFT_INTEGRATOR(BM_Integrator_Midpoint_double, double, IntegratorKind::Midpoint);
WEFT_INTEGRATOR(BM_Integrator_Rk4_float, float, IntegratorKind::Rk4);
WEFT_INTEGRATOR(BM_Integrator_Rk4_double, double, IntegratorKind::Rk4);
WEFT_INTEGRATOR(BM_Integrator_Verlet_float, float, IntegratorKind::VelocityVerlet);
WEFT_INTEGRATOR(BM_Integrator_Verlet_double, double, IntegratorKind::VelocityVerlet);

void BM_Textbook_Rk4_double(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  const weft::ModelAndState<double> built = weft::makeFlag<double>(size);
  textbook::Cloth cloth(built.model, built.state, {0, -9.81, 0});
  const double dt = weft::defaultTimeStep(weft::BuiltinScene::Flag, size);
  std::int64_t steps = 0;
  const std::int64_t allocationsBefore = weftbench::allocationCount();
  for (auto _ : st) {
    cloth.stepRk4(dt);
    ++steps;
  }
  const double springs = static_cast<double>(built.model.springCount());
  st.counters["allocs_per_step"] =
      steps ? static_cast<double>(weftbench::allocationCount() - allocationsBefore) / static_cast<double>(steps) : 0;
  st.counters["steps_per_second"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate);
  st.counters["spring_evals_per_second"] =
      benchmark::Counter(4 * springs, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Textbook_Rk4_double)->Arg(128)->ArgName("size")->UseRealTime()->Unit(benchmark::kMicrosecond);

}  // namespace
