// BM_Patch_*: weft's integrators on the cloth-peer protocol (patch_protocol.hpp): the 128²
// flag from rest, frames of 1/600 s, one span of 0.5 s per repetition, structural stretch
// sampled after every frame. Bullet's soft body runs the same frames in
// BM_Peer_Bullet_Cloth (bench_peer_bullet_cloth.cpp, where Bullet is found), so the ratios
// and the stretch figures come out of one run.
//
//   implicit Euler (block-Jacobi and multigrid preconditioners) and projective dynamics
//   (10 iterations): one step of 1/600 s a frame;
//   symplectic Euler and RK4 (explicit, unstable at 1/600 s on this cloth): K equal steps of
//   1/(600 K) s a frame, K the smallest count at which the whole span passes the stability
//   check (probed once per method and precision, on 2 threads, from ceil(frame / the kernel's
//   estimate) down). Counter substeps = K.
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>

#include "bench_common.hpp"
#include "patch_protocol.hpp"
#include "weft/weft.hpp"

namespace {

using weftbench::kPatchFrame;
using weftbench::kPatchSize;
using weftbench::kSpanFrames;

weft::SimulationOptions patchOptions(weft::IntegratorKind kind, int substeps, int threads,
                                     weft::Preconditioner preconditioner = weft::Preconditioner::BlockJacobi) {
  weft::SimulationOptions options;
  options.integrator = kind;
  options.integration.preconditioner = preconditioner;
  options.threads = threads;
  options.dt = kPatchFrame / substeps;
  options.integration.adaptive = false;
  return options;
}

/// Steps per 1/600 s frame: 1 for the implicit methods; for the explicit ones the fewest
/// equal steps with which a span from rest passes the stability check.
template <class S>
int substepsPerFrame(weft::IntegratorKind kind) {
  if (!weft::integratorIsExplicit(kind)) return 1;
  static std::map<int, int> cache;
  if (auto it = cache.find(static_cast<int>(kind)); it != cache.end()) return it->second;
  const weft::ModelAndState<S> flag = weft::makeFlag<S>(kPatchSize);
  const auto stable = [&](int k) {
    weft::Simulation<S> sim(weft::ModelAndState<S>{flag.model, flag.state}, patchOptions(kind, k, 2));
    return sim.run(static_cast<std::int64_t>(k) * kSpanFrames).ok();
  };
  int k = std::max(1, static_cast<int>(std::ceil(kPatchFrame / weft::estimateStableTimeStep(flag.model, kind))));
  if (stable(k)) {
    while (k > 1 && stable(k - 1)) --k;
  } else {
    do ++k;
    while (!stable(k));
  }
  return cache[static_cast<int>(kind)] = k;
}

template <class S, weft::IntegratorKind Kind, weft::Preconditioner Preconditioner = weft::Preconditioner::BlockJacobi>
void BM_Patch(benchmark::State& st) {
  const int threads = static_cast<int>(st.range(0));
  const int substeps = substepsPerFrame<S>(Kind);
  weft::Simulation<S> sim(weft::makeFlag<S>(kPatchSize), patchOptions(Kind, substeps, threads, Preconditioner));
  // Warm up (projective dynamics factorises its matrix in its first step), then back to rest.
  const weft::State<S> rest = sim.state();
  sim.step();
  sim.setState(rest);
  const std::int64_t stepsBefore = sim.stepCount();
  const std::int64_t iterationsBefore = sim.totalWork().linearIterations;
  weftbench::StretchSeries series;
  for (auto _ : st) {
    for (int k = 0; k < substeps; ++k)
      if (!sim.step().ok()) {
        st.SkipWithError(sim.status().message().c_str());
        return;
      }
    st.PauseTiming();
    series.add(weft::stretch(sim.model(), sim.state()));
    st.ResumeTiming();
  }
  series.report(st);
  st.counters["substeps"] = substeps;
  st.counters["dt"] = kPatchFrame / substeps;
  const double steps = static_cast<double>(std::max<std::int64_t>(sim.stepCount() - stepsBefore, 1));
  // Implicit Euler: CG iterations; projective dynamics: solves (its iteration count).
  st.counters["cg_iterations_per_step"] =
      static_cast<double>(sim.totalWork().linearIterations - iterationsBefore) / steps;
}

// The explicit methods on 1 and 2 threads; the implicit ones (a frame costs 100x more) on
// 2 only, to keep the run short (projective dynamics' solve is serial: 1 thread is within
// noise of 2 in BM_Projective_Frame; implicit Euler's CG is ~1.6x slower on 1).
void explicitArgs(benchmark::internal::Benchmark* b) {
  b->ArgName("threads")->Arg(1)->Arg(2)->Iterations(kSpanFrames)->UseRealTime()->Unit(benchmark::kMillisecond);
}
void implicitArgs(benchmark::internal::Benchmark* b) {
  b->ArgName("threads")->Arg(2)->Iterations(kSpanFrames)->UseRealTime()->Unit(benchmark::kMillisecond);
}

using weft::IntegratorKind;
#define WEFT_PATCH(NAME, ARGS, S, KIND) WEFT_BENCHMARK_AS(NAME, ARGS, BM_Patch<S, KIND>)

WEFT_PATCH(BM_Patch_Symplectic_float, explicitArgs, float, IntegratorKind::SymplecticEuler);
WEFT_PATCH(BM_Patch_Symplectic_double, explicitArgs, double, IntegratorKind::SymplecticEuler);
WEFT_PATCH(BM_Patch_Rk4_float, explicitArgs, float, IntegratorKind::Rk4);
WEFT_PATCH(BM_Patch_Rk4_double, explicitArgs, double, IntegratorKind::Rk4);
WEFT_PATCH(BM_Patch_Implicit_double, implicitArgs, double, IntegratorKind::ImplicitEuler);
// Implicit Euler with the multigrid preconditioner (the one above uses the default, block-Jacobi).
WEFT_BENCHMARK_AS(BM_Patch_ImplicitMultigrid_double, implicitArgs,
                  BM_Patch<double, IntegratorKind::ImplicitEuler, weft::Preconditioner::Multigrid>);
WEFT_PATCH(BM_Patch_Projective_double, implicitArgs, double, IntegratorKind::Projective);

}  // namespace
