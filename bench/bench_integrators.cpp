// BM_Integrator_*: one full Simulation::step (all stages, stability check) on the flag,
// each integrator, float and double, 1 and 2 threads, at 128^2 (and 256^2 for the
// thread-scaling target). BM_Textbook_Rk4: the array-of-structs baseline, 1 thread,
// double, same scene and dt. Each reports allocations per step (expected 0 for weft).
// BM_SimulatedSecond_*: cost per simulated second at each method's largest stable step.
// BM_Scaling_*: the step from 32^2 to 1024^2 (bench/run_scaling.sh).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "bench_common.hpp"
#include "integrate/aggregation_multigrid.hpp"
#include "integrate/spring_laplacian_solver.hpp"
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
  weftbench::valuesOnOneAndTwoThreads(b, "size", {128, 256}, benchmark::kMicrosecond);
}

using weft::IntegratorKind;
#define WEFT_INTEGRATOR(NAME, S, KIND) WEFT_BENCHMARK_AS(NAME, integratorArgs, BM_Integrator<S, KIND>)

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
WEFT_INTEGRATOR(BM_Integrator_Rk45_float, float, IntegratorKind::Rk45);
WEFT_INTEGRATOR(BM_Integrator_Rk45_double, double, IntegratorKind::Rk45);
WEFT_INTEGRATOR(BM_Integrator_Implicit_float, float, IntegratorKind::ImplicitEuler);
WEFT_INTEGRATOR(BM_Integrator_Implicit_double, double, IntegratorKind::ImplicitEuler);
WEFT_INTEGRATOR(BM_Integrator_Projective_float, float, IntegratorKind::Projective);
WEFT_INTEGRATOR(BM_Integrator_Projective_double, double, IntegratorKind::Projective);

// BM_Scaling_*: the same step from 32^2 to 1024^2 particles (implicit Euler to 512^2,
// projective dynamics to 256^2: their factorisation and solve grow faster than the rest),
// 1 and 2 threads, for the cost-against-size plot. Not part of the default run
// (bench/run_benchmarks.sh filters them out): bench/run_scaling.sh runs and plots them.
void scalingArgs(benchmark::internal::Benchmark* b) {
  weftbench::valuesOnOneAndTwoThreads(b, "size", {32, 64, 128, 256, 512, 1024}, benchmark::kMicrosecond);
}
void scalingArgsImplicit(benchmark::internal::Benchmark* b) {
  weftbench::valuesOnOneAndTwoThreads(b, "size", {32, 64, 128, 256, 512}, benchmark::kMicrosecond);
}
void scalingArgsProjective(benchmark::internal::Benchmark* b) {
  weftbench::valuesOnOneAndTwoThreads(b, "size", {32, 64, 128, 256}, benchmark::kMicrosecond);
}
#define WEFT_SCALING(NAME, ARGS, S, KIND) WEFT_BENCHMARK_AS(NAME, ARGS, BM_Integrator<S, KIND>)
WEFT_SCALING(BM_Scaling_Euler_float, scalingArgs, float, IntegratorKind::ExplicitEuler);
WEFT_SCALING(BM_Scaling_Euler_double, scalingArgs, double, IntegratorKind::ExplicitEuler);
WEFT_SCALING(BM_Scaling_Symplectic_float, scalingArgs, float, IntegratorKind::SymplecticEuler);
WEFT_SCALING(BM_Scaling_Symplectic_double, scalingArgs, double, IntegratorKind::SymplecticEuler);
WEFT_SCALING(BM_Scaling_Midpoint_float, scalingArgs, float, IntegratorKind::Midpoint);
WEFT_SCALING(BM_Scaling_Midpoint_double, scalingArgs, double, IntegratorKind::Midpoint);
WEFT_SCALING(BM_Scaling_Rk4_float, scalingArgs, float, IntegratorKind::Rk4);
WEFT_SCALING(BM_Scaling_Rk4_double, scalingArgs, double, IntegratorKind::Rk4);
WEFT_SCALING(BM_Scaling_Verlet_float, scalingArgs, float, IntegratorKind::VelocityVerlet);
WEFT_SCALING(BM_Scaling_Verlet_double, scalingArgs, double, IntegratorKind::VelocityVerlet);
WEFT_SCALING(BM_Scaling_Rk45_float, scalingArgs, float, IntegratorKind::Rk45);
WEFT_SCALING(BM_Scaling_Rk45_double, scalingArgs, double, IntegratorKind::Rk45);
WEFT_SCALING(BM_Scaling_Implicit_float, scalingArgsImplicit, float, IntegratorKind::ImplicitEuler);
WEFT_SCALING(BM_Scaling_Implicit_double, scalingArgsImplicit, double, IntegratorKind::ImplicitEuler);
WEFT_SCALING(BM_Scaling_Projective_float, scalingArgsProjective, float, IntegratorKind::Projective);
WEFT_SCALING(BM_Scaling_Projective_double, scalingArgsProjective, double, IntegratorKind::Projective);

// ---------------------------------------------------------------------------------------
// BM_SimulatedSecond_*: what a simulated second costs on the 128^2 flag at each method's
// largest stable step. The step is measured once per (precision, method) by bisection
// (fixed steps; a probe is 400 steps from the initial state that the stability check does
// not stop) and cached; the counter wall_s_per_sim_s = wall time / (steps x dt).
// Adaptive rk45 runs frames of 1/60 s at its default tolerances (its substeps are its
// own choice); implicit Euler and projective dynamics (10 iterations) run 1/60 s steps
// (a real-time frame; they are stable far beyond). Explicit Euler is left out: its stable step on this cloth is ~1e-6
// s.
// ---------------------------------------------------------------------------------------

template <class S>
double largestStableFlagStep(weft::IntegratorKind kind, weft::Index size) {
  static std::map<std::pair<int, weft::Index>, double> cache;
  const auto key = std::make_pair(static_cast<int>(kind), size);
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  const weft::ModelAndState<S> flag = weft::makeFlag<S>(size);
  double estimate = weft::estimateStableTimeStep(flag.model, kind);
  if (!(estimate > 0)) estimate = weft::estimateStableTimeStep(flag.model, weft::IntegratorKind::SymplecticEuler);
  const auto stable = [&](double dt) {
    weft::SimulationOptions options;
    options.integrator = kind;
    options.dt = dt;
    options.threads = 2;
    options.integration.adaptive = false;
    weft::Simulation<S> sim(weft::ModelAndState<S>{flag.model, flag.state}, options);
    return sim.run(400).ok();
  };
  double lo = estimate / 4, hi = estimate * 16;
  while (!stable(lo)) lo /= 2;
  for (int k = 0; k < 8; ++k) {
    const double mid = std::sqrt(lo * hi);
    (stable(mid) ? lo : hi) = mid;
  }
  return cache[key] = lo;
}

template <class S, weft::IntegratorKind Kind>
void BM_SimulatedSecond(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  weft::SimulationOptions options;
  options.integrator = Kind;
  options.threads = static_cast<int>(st.range(1));
  if (Kind == weft::IntegratorKind::Rk45 || !weft::integratorIsExplicit(Kind))
    options.dt = 1.0 / 60;
  else
    options.dt = largestStableFlagStep<S>(Kind, size);
  weft::Simulation<S> sim(weft::makeFlag<S>(size), options);
  const weft::State<S> initial = sim.state();
  std::int64_t steps = 0;
  for (auto _ : st) {
    if (!sim.step().ok()) {
      st.SkipWithError(sim.status().message().c_str());
      break;
    }
    if (++steps % 400 == 0) {  // stay within the probed span of the motion
      st.PauseTiming();
      sim.setState(initial);
      st.ResumeTiming();
    }
  }
  const weft::StepWork& work = sim.totalWork();
  const double n = static_cast<double>(std::max<std::int64_t>(sim.stepCount(), 1));
  st.counters["dt"] = options.dt;
  const double estimate = weft::estimateStableTimeStep(sim.model(), Kind);
  st.counters["dt_over_estimate"] = estimate > 0 && std::isfinite(estimate) ? options.dt / estimate : 0.0;
  st.counters["force_evals_per_step"] = static_cast<double>(work.forceEvaluations) / n;
  st.counters["cg_iterations_per_step"] = static_cast<double>(work.linearIterations) / n;  // projective: solves
  st.counters["substeps_per_step"] = static_cast<double>(work.substeps) / n;
  // (No allocation counter here: with a few iterations of a long rk45 frame the
  // framework's own allocations would dominate it. BM_Integrator_* and the tests count.)
  st.counters["wall_s_per_sim_s"] =
      benchmark::Counter(options.dt, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void simulatedSecondArgs(benchmark::internal::Benchmark* b) {
  weftbench::valuesOnOneAndTwoThreads(b, "size", {128}, benchmark::kMillisecond);
}

#define WEFT_SIMULATED_SECOND(NAME, S, KIND) WEFT_BENCHMARK_AS(NAME, simulatedSecondArgs, BM_SimulatedSecond<S, KIND>)

WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Symplectic_float, float, IntegratorKind::SymplecticEuler);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Symplectic_double, double, IntegratorKind::SymplecticEuler);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Midpoint_float, float, IntegratorKind::Midpoint);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Midpoint_double, double, IntegratorKind::Midpoint);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Rk4_float, float, IntegratorKind::Rk4);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Rk4_double, double, IntegratorKind::Rk4);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Verlet_float, float, IntegratorKind::VelocityVerlet);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Verlet_double, double, IntegratorKind::VelocityVerlet);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Rk45_float, float, IntegratorKind::Rk45);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Rk45_double, double, IntegratorKind::Rk45);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Implicit_float, float, IntegratorKind::ImplicitEuler);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Implicit_double, double, IntegratorKind::ImplicitEuler);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Projective_float, float, IntegratorKind::Projective);
WEFT_SIMULATED_SECOND(BM_SimulatedSecond_Projective_double, double, IntegratorKind::Projective);

// ---------------------------------------------------------------------------------------
// BM_Projective_Frame: one 1/60 s step of projective dynamics on the flag, by grid side and
// iteration count (double), against one implicit-Euler step of the same frame in the same
// binary (BM_SimulatedSecond_Implicit_double). Counters: the last iteration's relative
// change (how unconverged the count leaves the step) and the factor's share of the memory.
// ---------------------------------------------------------------------------------------

void BM_Projective_Frame(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  weft::SimulationOptions options;
  options.integrator = weft::IntegratorKind::Projective;
  options.threads = static_cast<int>(st.range(2));
  options.dt = 1.0 / 60;
  options.integration.projectiveIterations = static_cast<int>(st.range(1));
  weft::Simulation<double> sim(weft::makeFlag<double>(size), options);
  const weft::State<double> initial = sim.state();
  sim.run(2);  // warm up: the factorisation
  std::int64_t steps = 0;
  double change = 0;
  const std::int64_t allocationsBefore = weftbench::allocationCount();
  for (auto _ : st) {
    if (!sim.step().ok()) {
      st.SkipWithError(sim.status().message().c_str());
      break;
    }
    change = std::max(change, sim.lastWork().linearResidual);
    if (++steps % 120 == 0) {
      st.PauseTiming();
      sim.setState(initial);
      st.ResumeTiming();
    }
  }
  st.counters["allocs_per_step"] =
      steps ? static_cast<double>(weftbench::allocationCount() - allocationsBefore) / static_cast<double>(steps) : 0;
  st.counters["last_iteration_change"] = change;
  st.counters["particles"] = static_cast<double>(sim.model().particleCount());
}
BENCHMARK(BM_Projective_Frame)
    ->ArgNames({"size", "iterations", "threads"})
    ->ArgsProduct({{64, 128}, {1, 10, 20}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// ---------------------------------------------------------------------------------------
// BM_Projective_Solve: one solve with projective dynamics' prefactored global matrix on the
// size^2 flag at dt = 1/60 (both triangular solves, three coordinates), by thread count,
// without the rest of an iteration. Counters: factor entries per second (each read twice),
// the factor's bytes (both copies).
// ---------------------------------------------------------------------------------------

void BM_Projective_Solve(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  const weft::ModelAndState<double> flag = weft::makeFlag<double>(size);
  const weft::Executor exec(static_cast<int>(st.range(1)));
  weft::detail::SpringLaplacianSolver<double> solver(flag.model, 1.0, "BM_Projective_Solve");
  solver.prepare(1.0 / 60, 0.0);
  const weft::Index n = flag.model.particleCount();
  for (weft::Index i = 0; i < n; ++i)
    for (weft::Index c = 0; c < 3; ++c) solver.buffer()[solver.offset(i) + c] = flag.state.x(i, c);
  const std::vector<double> rhs(solver.buffer(), solver.buffer() + 4 * n);
  const std::int64_t allocationsBefore = weftbench::allocationCount();
  std::int64_t solves = 0;
  for (auto _ : st) {
    std::copy(rhs.begin(), rhs.end(), solver.buffer());  // counted: a 4 n copy, ~2 % at 128^2
    solver.solveBuffer(exec);
    ++solves;
  }
  benchmark::DoNotOptimize(solver.buffer()[0]);
  st.counters["allocs_per_solve"] = static_cast<double>(weftbench::allocationCount() - allocationsBefore) /
                                    static_cast<double>(std::max<std::int64_t>(solves, 1));
  st.counters["factor_entries"] = static_cast<double>(solver.factorEntries());
  st.counters["factor_bytes"] = static_cast<double>(solver.factorBytes());
  st.counters["entries_per_second"] = benchmark::Counter(2.0 * static_cast<double>(solver.factorEntries()),
                                                         benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Projective_Solve)
    ->ArgNames({"size", "threads"})
    ->ArgsProduct({{64, 128}, {1, 2}})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

// ---------------------------------------------------------------------------------------
// BM_Projective_Factor: one factorisation of projective dynamics' global matrix on the
// size^2 flag (SpringLaplacianSolver::prepare with a time step not in its cache: the
// matrix assembled and permuted, Eigen's SimplicialLDLT in double, the factor rounded to
// float and transposed), what a new time step costs; the ordering is found once, outside.
// ---------------------------------------------------------------------------------------

void BM_Projective_Factor(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  const weft::ModelAndState<double> flag = weft::makeFlag<double>(size);
  weft::detail::SpringLaplacianSolver<double> solver(flag.model, 1.0, "BM_Projective_Factor");
  int k = 0;
  for (auto _ : st) {
    // Three steps in turn, so the two-slot cache never holds the one asked for.
    const bool factorised = solver.prepare(1.0 / (60.0 + static_cast<double>(k)), 0.0);
    k = (k + 1) % 3;
    if (!factorised) {
      st.SkipWithError("the factor came from the cache");
      break;
    }
  }
  st.counters["factor_entries"] = static_cast<double>(solver.factorEntries());
}
BENCHMARK(BM_Projective_Factor)->ArgName("size")->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond)->UseRealTime();

// ---------------------------------------------------------------------------------------
// BM_Implicit_Step: one implicit-Euler step of the flag (double) at dt = 1 / steps_per_s,
// by CG preconditioner (0 jacobi, 1 block-jacobi, 2 projective, 3 multigrid, 4 auto, the
// default) and thread count.
// Counters: CG iterations per step, wall seconds per simulated second.
// ---------------------------------------------------------------------------------------

void BM_Implicit_Step(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  weft::SimulationOptions options;
  options.integrator = weft::IntegratorKind::ImplicitEuler;
  options.dt = 1.0 / static_cast<double>(st.range(1));
  options.integration.preconditioner = static_cast<weft::Preconditioner>(st.range(2));
  options.threads = static_cast<int>(st.range(3));
  weft::Simulation<double> sim(weft::makeFlag<double>(size), options);
  const weft::State<double> initial = sim.state();
  sim.run(2);  // warm up: the projective preconditioner's factorisation
  std::int64_t steps = 0, iterations = 0;
  const std::int64_t allocationsBefore = weftbench::allocationCount();
  for (auto _ : st) {
    if (!sim.step().ok()) {
      st.SkipWithError(sim.status().message().c_str());
      break;
    }
    iterations += sim.lastWork().linearIterations;
    if (++steps % 120 == 0) {  // the first two simulated seconds at 1/60 (0.2 s at 1/600)
      st.PauseTiming();
      sim.setState(initial);
      st.ResumeTiming();
    }
  }
  const double n = static_cast<double>(std::max<std::int64_t>(steps, 1));
  st.counters["allocs_per_step"] = static_cast<double>(weftbench::allocationCount() - allocationsBefore) / n;
  st.counters["cg_iterations_per_step"] = static_cast<double>(iterations) / n;
  st.counters["wall_s_per_sim_s"] =
      benchmark::Counter(options.dt, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  st.SetLabel(weft::preconditionerName(options.integration.preconditioner));
}
BENCHMARK(BM_Implicit_Step)
    ->ArgNames({"size", "steps_per_s", "preconditioner", "threads"})
    ->ArgsProduct({{128}, {60, 600}, {0, 1, 2, 3, 4}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// ---------------------------------------------------------------------------------------
// BM_Jacobian_SystemProduct: one product with implicit Euler's matrix A (what every CG
// iteration and each multigrid cycle's fine sweeps cost) on the size^2 flag, linearised at
// its stretched rest state at dt = 1/60, by thread count. Counter: springs per second.
// ---------------------------------------------------------------------------------------

template <class S>
void BM_Jacobian_SystemProduct(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  const weft::ModelAndState<S> flag = weft::makeFlag<S>(size);
  const weft::Executor exec(static_cast<int>(st.range(1)));
  weft::SpringJacobian<S> jacobian(flag.model);
  jacobian.reserve(exec);  // the stencil's windows, as a Simulation makes them when built
  const weft::Vec3Array<S> x = flag.state.x * S(1.02);
  jacobian.linearize(x, S(1.0 / 60), exec, S(0.01));
  weft::Vec3Array<S> p = flag.state.x;
  // One slot per block (blocks may run concurrently), summed after the loop.
  std::vector<S> last(
      static_cast<size_t>(weft::Executor::blockCount(flag.model.particleCount(), weft::ForceField<S>::kSinkBlock)));
  auto sink = [&](weft::Index b, weft::Index m, const S* yx, const S*, const S*) {
    last[static_cast<size_t>(b / weft::ForceField<S>::kSinkBlock)] = yx[m - 1];
  };
  const std::int64_t allocationsBefore = weftbench::allocationCount();
  std::int64_t products = 0;
  for (auto _ : st) {
    jacobian.systemProduct(p, weft::makeSink<S>(sink), exec);
    ++products;
  }
  S checksum = 0;
  for (const S value : last) checksum += value;
  benchmark::DoNotOptimize(checksum);
  st.counters["allocs_per_product"] = static_cast<double>(weftbench::allocationCount() - allocationsBefore) /
                                      static_cast<double>(std::max<std::int64_t>(products, 1));
  st.counters["springs_per_second"] =
      benchmark::Counter(static_cast<double>(flag.model.springCount()), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Jacobian_SystemProduct<double>)
    ->ArgNames({"size", "threads"})
    ->ArgsProduct({{128, 256}, {1, 2}})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();
BENCHMARK(BM_Jacobian_SystemProduct<float>)
    ->ArgNames({"size", "threads"})
    ->ArgsProduct({{128}, {1, 2}})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

// ---------------------------------------------------------------------------------------
// BM_Jacobian_Linearize: what an implicit Euler step pays once before its CG, besides the
// force evaluation: the springs' linearisation and A's diagonal blocks (SpringJacobian::
// linearize), and with multigrid:1 the multigrid preconditioner's levels (every coarse
// operator, the smoothers' inverses, the coarsest factor), on the size^2 flag stretched by
// 2 %, dt = 1/60, by thread count.
// ---------------------------------------------------------------------------------------

void BM_Jacobian_Linearize(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  const weft::ModelAndState<double> flag = weft::makeFlag<double>(size);
  const weft::Executor exec(static_cast<int>(st.range(1)));
  const bool multigrid = st.range(2) != 0;
  weft::SpringJacobian<double> jacobian(flag.model);
  weft::detail::AggregationMultigrid<double> hierarchy(flag.model);
  const weft::Vec3Array<double> x = flag.state.x * 1.02;
  const std::int64_t allocationsBefore = weftbench::allocationCount();
  std::int64_t runs = 0;
  for (auto _ : st) {
    exec.run([&] {
      jacobian.linearize(x, 1.0 / 60, exec, 0.01);
      if (multigrid) hierarchy.prepare(jacobian, exec);
    });
    ++runs;
  }
  benchmark::DoNotOptimize(jacobian.diagonal().data());
  st.counters["allocs_per_run"] = static_cast<double>(weftbench::allocationCount() - allocationsBefore) /
                                  static_cast<double>(std::max<std::int64_t>(runs, 1));
}
BENCHMARK(BM_Jacobian_Linearize)
    ->ArgNames({"size", "threads", "multigrid"})
    ->ArgsProduct({{128}, {1, 2}, {0, 1}})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

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

// BM_Simulation_SetState: Simulation::setState on the flag (what a caller pays to reset a
// run: every value checked, the start recorded), with its allocations (expected 0).
template <class S>
void BM_Simulation_SetState(benchmark::State& st) {
  const auto size = static_cast<weft::Index>(st.range(0));
  weft::SimulationOptions options;
  options.threads = 1;
  weft::Simulation<S> sim(weft::makeFlag<S>(size), options);
  const weft::State<S> initial = sim.state();
  sim.setState(initial);  // (warm: the same sizes from here on)
  std::int64_t resets = 0;
  const std::int64_t allocationsBefore = weftbench::allocationCount();
  for (auto _ : st) {
    sim.setState(initial);
    ++resets;
  }
  st.counters["allocs_per_call"] =
      resets ? static_cast<double>(weftbench::allocationCount() - allocationsBefore) / static_cast<double>(resets) : 0;
  st.counters["springs"] = static_cast<double>(sim.model().springCount());
}
BENCHMARK(BM_Simulation_SetState<float>)->Arg(128)->ArgName("size")->UseRealTime()->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Simulation_SetState<double>)->Arg(128)->ArgName("size")->UseRealTime()->Unit(benchmark::kMicrosecond);

}  // namespace
