// BM_Patch_*: weft's integrators on the cloth-peer protocol (patch_protocol.hpp): the 128²
// flag from rest, frames of 1/600 s, one span of 0.5 s per repetition, structural stretch
// sampled after every frame. Bullet's soft body runs the same frames in
// BM_Peer_Bullet_Cloth (bench_peer_bullet_cloth.cpp, where Bullet is found), so the ratios
// and the stretch figures come out of one run.
//
//   implicit Euler (block-Jacobi and multigrid preconditioners) and projective dynamics:
//   one step of 1/600 s a frame; their second argument is the solver's setting, the CG
//   tolerance 10^-k (cg_tol_exp:k; 6 is the default, 1e-6) or projective dynamics'
//   iterations per step (pd_iterations, 10 the default). What a looser setting costs in accuracy is the
//   counter error_vs_converged_m: the largest distance of a particle at the end of the span
//   from where the same method puts it with its solve converged (CG to 1e-10, or 100
//   projective iterations), computed once per process outside the timing;
//   every method: error_vs_rk4_m, the same distance from RK4 in double with twice its
//   probed substeps (below), what the method itself costs in accuracy;
//   symplectic Euler and RK4 (explicit, unstable at 1/600 s on this cloth): K equal steps of
//   1/(600 K) s a frame, K the smallest count at which the whole span passes the stability
//   check (probed once per method and precision, on 2 threads, from ceil(frame / the kernel's
//   estimate) down). Counter substeps = K.
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <tuple>

#include "bench_common.hpp"
#include "patch_protocol.hpp"
#include "weft/weft.hpp"

namespace {

using weftbench::kPatchFrame;
using weftbench::kPatchSize;
using weftbench::kSpanFrames;

/// The solver setting of an implicit method: the CG tolerance 10^-setting (implicit Euler)
/// or the iterations per step (projective dynamics); 0 = the default.
weft::SimulationOptions patchOptions(weft::IntegratorKind kind, int substeps, int threads,
                                     weft::Preconditioner preconditioner = weft::Preconditioner::BlockJacobi,
                                     int setting = 0, double frame = kPatchFrame) {
  weft::SimulationOptions options;
  options.integrator = kind;
  options.integration.preconditioner = preconditioner;
  options.threads = threads;
  options.dt = frame / substeps;
  options.integration.adaptive = false;
  if (setting > 0 && kind == weft::IntegratorKind::ImplicitEuler)
    options.integration.linearTolerance = std::pow(10.0, -setting);
  if (setting > 0 && kind == weft::IntegratorKind::Projective) options.integration.projectiveIterations = setting;
  return options;
}

/// The settings of the converged reference: CG to 1e-10, 100 projective iterations.
constexpr int kConvergedCg = 10, kConvergedProjective = 100;

/// Frames in the span (0.5 s) at fps frames a second.
constexpr int spanFrames(int fps) { return fps / 2; }
static_assert(spanFrames(600) == kSpanFrames, "the protocol's span");

/// The patch after the span (0.5 s in frames of 1 / fps s) with the method's solve
/// converged (computed once per method and frame length); no rows if that run failed or a
/// solve stopped at the CG's iteration cap.
template <class S>
const weft::Vec3Array<S>& convergedEnd(weft::IntegratorKind kind, weft::Preconditioner preconditioner, int fps) {
  static std::map<std::tuple<int, int, int>, weft::Vec3Array<S>> cache;
  const std::tuple<int, int, int> key{static_cast<int>(kind), static_cast<int>(preconditioner), fps};
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  const int setting = kind == weft::IntegratorKind::Projective ? kConvergedProjective : kConvergedCg;
  weft::Simulation<S> sim(weft::makeFlag<S>(kPatchSize), patchOptions(kind, 1, 2, preconditioner, setting, 1.0 / fps));
  const weft::State<S> rest = sim.state();  // the protocol of BM_Patch: one step, back to rest
  sim.step();
  sim.setState(rest);
  const bool ok = sim.run(spanFrames(fps)).ok() && sim.totalWork().linearUnconverged == 0;
  return cache[key] = ok ? sim.state().x : weft::Vec3Array<S>();
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

/// The patch after the span under RK4 in double with twice its probed substeps: the
/// reference for every method's error.
const weft::Vec3Array<double>& rk4End() {
  static const weft::Vec3Array<double> end = [] {
    const int substeps = 2 * substepsPerFrame<double>(weft::IntegratorKind::Rk4);
    weft::Simulation<double> sim(weft::makeFlag<double>(kPatchSize),
                                 patchOptions(weft::IntegratorKind::Rk4, substeps, 2));
    sim.run(static_cast<std::int64_t>(substeps) * kSpanFrames);
    return sim.state().x;
  }();
  return end;
}

/// The largest distance between a particle's positions in a and b, m.
template <class A, class B>
double largestDistance(const A& a, const B& b) {
  double worst = 0;
  for (weft::Index i = 0; i < a.rows(); ++i)
    worst = std::max(worst, (a.row(i).template cast<double>() - b.row(i).template cast<double>()).norm());
  return worst;
}

/// Fps: frames per second (600, the protocol's; 60 for the implicit methods' large step,
/// BM_Patch60_*: the same 0.5 s in 30 frames of one step each).
template <class S, weft::IntegratorKind Kind, weft::Preconditioner Preconditioner = weft::Preconditioner::BlockJacobi,
          int Fps = 600>
void BM_Patch(benchmark::State& st) {
  if (Fps != 600 && weft::integratorIsExplicit(Kind)) {
    st.SkipWithError("the explicit methods run the 1/600 s protocol");
    return;
  }
  const double frame = 1.0 / Fps;
  const int threads = static_cast<int>(st.range(0));
  const int setting = weft::integratorIsExplicit(Kind) ? 0 : static_cast<int>(st.range(1));
  const int substeps = substepsPerFrame<S>(Kind);
  weft::Simulation<S> sim(weft::makeFlag<S>(kPatchSize),
                          patchOptions(Kind, substeps, threads, Preconditioner, setting, frame));
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
  series.report(st, frame);
  st.counters["substeps"] = substeps;
  st.counters["dt"] = frame / substeps;
  const double steps = static_cast<double>(std::max<std::int64_t>(sim.stepCount() - stepsBefore, 1));
  // Implicit Euler: CG iterations; projective dynamics: solves (its iteration count).
  st.counters["cg_iterations_per_step"] =
      static_cast<double>(sim.totalWork().linearIterations - iterationsBefore) / steps;
  // After the timed loop: the references run once per process, untimed.
  if (!weft::integratorIsExplicit(Kind)) {
    const weft::Vec3Array<S>& converged = convergedEnd<S>(Kind, Preconditioner, Fps);
    if (converged.rows() == 0) {
      st.SkipWithError("the converged reference did not run to the end or did not converge");
      return;
    }
    st.counters["error_vs_converged_m"] = largestDistance(sim.state().x, converged);
  }
  st.counters["error_vs_rk4_m"] = largestDistance(sim.state().x, rk4End());
}

// The explicit methods on 1 and 2 threads; the implicit ones (a frame costs 100x more) on
// 2 only, to keep the run short.
void explicitArgs(benchmark::internal::Benchmark* b) {
  b->ArgName("threads")->Arg(1)->Arg(2)->Iterations(kSpanFrames)->UseRealTime()->Unit(benchmark::kMillisecond);
}
// Implicit Euler: CG tolerances 10^-k; the default, 1e-6, first.
void implicitArgs(benchmark::internal::Benchmark* b) {
  b->ArgNames({"threads", "cg_tol_exp"})->Iterations(kSpanFrames)->UseRealTime()->Unit(benchmark::kMillisecond);
  for (const int k : {6, 4, 3, 2}) b->Args({2, k});
}
// Projective dynamics: iterations per step (Bullet's soft body runs 1, 4 and 10); the default, 10, first.
void projectiveArgs(benchmark::internal::Benchmark* b) {
  b->ArgNames({"threads", "pd_iterations"})->Iterations(kSpanFrames)->UseRealTime()->Unit(benchmark::kMillisecond);
  for (const int k : {10, 4, 1}) b->Args({2, k});
}
// The same settings in frames of 1/60 s (30 a span).
void implicit60Args(benchmark::internal::Benchmark* b) {
  b->ArgNames({"threads", "cg_tol_exp"})->Iterations(spanFrames(60))->UseRealTime()->Unit(benchmark::kMillisecond);
  for (const int k : {6, 4, 3, 2}) b->Args({2, k});
}
void projective60Args(benchmark::internal::Benchmark* b) {
  b->ArgNames({"threads", "pd_iterations"})->Iterations(spanFrames(60))->UseRealTime()->Unit(benchmark::kMillisecond);
  for (const int k : {10, 4, 1}) b->Args({2, k});
}

using weft::IntegratorKind;
#define WEFT_PATCH(NAME, ARGS, S, KIND) WEFT_BENCHMARK_AS(NAME, ARGS, BM_Patch<S, KIND>)

WEFT_PATCH(BM_Patch_Symplectic_float, explicitArgs, float, IntegratorKind::SymplecticEuler);
WEFT_PATCH(BM_Patch_Symplectic_double, explicitArgs, double, IntegratorKind::SymplecticEuler);
WEFT_PATCH(BM_Patch_Rk4_float, explicitArgs, float, IntegratorKind::Rk4);
WEFT_PATCH(BM_Patch_Rk4_double, explicitArgs, double, IntegratorKind::Rk4);
WEFT_PATCH(BM_Patch_Implicit_double, implicitArgs, double, IntegratorKind::ImplicitEuler);
// Implicit Euler with the multigrid preconditioner (the one above uses block-Jacobi).
WEFT_BENCHMARK_AS(BM_Patch_ImplicitMultigrid_double, implicitArgs,
                  BM_Patch<double, IntegratorKind::ImplicitEuler, weft::Preconditioner::Multigrid>);
WEFT_PATCH(BM_Patch_Projective_double, projectiveArgs, double, IntegratorKind::Projective);
// The implicit methods at their large step: the same span in 30 steps of 1/60 s (no peer:
// Bullet's soft body is not run at 1/60 s here).
WEFT_BENCHMARK_AS(BM_Patch60_ImplicitMultigrid_double, implicit60Args,
                  BM_Patch<double, IntegratorKind::ImplicitEuler, weft::Preconditioner::Multigrid, 60>);
WEFT_BENCHMARK_AS(BM_Patch60_Projective_double, projective60Args,
                  BM_Patch<double, IntegratorKind::Projective, weft::Preconditioner::BlockJacobi, 60>);

}  // namespace
