// `weft study`: error, stability limit and wall time side by side.
//
// For each scene (oscillator: exact solution; rope released from horizontal and the flag:
// reference = RK4 in double at a small step, checked against half that step), each
// integrator and precision:
//   * the largest stable dt, by bisection on dt (a run over the scene's duration that the
//     stability check does not stop), next to the kernel's estimate;
//   * a sweep of dt below it (rk45: of its tolerance, at frames of ~1/60 s; implicit and
//     projective: of dt up to far beyond the explicit limits), each point run on every
//     thread count:
//     error against the reference at T/2 and T, energy error, wall time per simulated
//     second, work counters, and whether the state is bitwise the same as on 1 thread.
// Output: study.csv (one row per run), study.md (tables), study.png/.svg (plot by
// tools/plot_study.py through /usr/bin/python3).
//
// The work runs in three phases of independent tasks — references, stability limits,
// points — which an MPI job spreads over its ranks, largest first (study_schedule.hpp,
// docs/distributed.md); the files are the same as a single process writes but for the
// timing columns and the host each point ran on.
#include "study_command.hpp"

#include <sched.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string_view>
#include <thread>

#include "output_file.hpp"
#include "ranks.hpp"
#include "study_schedule.hpp"
#include "weft/weft.hpp"

#ifndef WEFT_SOURCE_DIR
#define WEFT_SOURCE_DIR "."
#endif

namespace weftcli {

namespace {

using weft::Index;
using weft::IntegratorKind;

// The damped oscillator of the tests (weft/scene/oscillator.hpp): exact solution known.
using Oscillator = weft::DampedOscillator;

struct SceneDef {
  std::string name;
  double duration = 1;  // s
  Index size = 0;       // rope particles / flag side
  weft::Vec3d gravity{0, -9.81, 0};
  bool analytic = false;
};

template <class S>
weft::ModelAndState<S> build(const SceneDef& scene) {
  if (scene.analytic) return Oscillator().build<S>();
  return scene.name == "rope" ? weft::makeRope<S>(scene.size) : weft::makeFlag<S>(scene.size);
}

struct RunResult {
  weft::StepStatus status;
  double wall = 0;                   // s
  weft::Vec3Array<double> xHalf, x;  // positions at T/2 and T
  weft::Vec3Array<double> v;         // velocities at T
  double energy = 0;                 // J at T
  weft::StepWork work;
  std::uint64_t hash = 0;
  Index steps = 0;
};

template <class S>
RunResult run(const SceneDef& scene, IntegratorKind kind, double dt, const weft::IntegratorOptions& io, int threads) {
  weft::SimulationOptions options;
  options.integrator = kind;
  const Index steps = std::max<Index>(2, 2 * static_cast<Index>(std::llround(scene.duration / dt / 2)));
  options.dt = scene.duration / static_cast<double>(steps);
  options.threads = threads;
  options.gravity = scene.gravity;
  options.integration = io;
  if (scene.analytic) options.stability.maxStretch = 1e6;  // checked against the exact solution instead
  weft::Simulation<S> sim(build<S>(scene), options);
  RunResult r;
  const auto start = std::chrono::steady_clock::now();
  r.status = sim.run(steps / 2);
  r.xHalf = sim.state().x.template cast<double>();
  if (r.status.ok()) r.status = sim.run(steps / 2);
  r.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.x = sim.state().x.template cast<double>();
  r.v = sim.state().v.template cast<double>();
  r.energy = weft::energy(sim.model(), sim.state(), scene.gravity).total();
  r.work = sim.totalWork();
  r.hash = weft::stateHash(sim.state());
  r.steps = sim.stepCount();
  return r;
}

RunResult runAny(bool isFloat, const SceneDef& scene, IntegratorKind kind, double dt, const weft::IntegratorOptions& io,
                 int threads) {
  return isFloat ? run<float>(scene, kind, dt, io, threads) : run<double>(scene, kind, dt, io, threads);
}

struct Reference {
  weft::Vec3Array<double> xHalf, x;
  double energy = 0;
  double selfCheck = 0;  // max |x(dt_ref) - x(dt_ref / 2)| at T, m (0 for the exact solution)
  double dt = 0;
};

Reference reference(const SceneDef& scene, bool quick) {
  Reference ref;
  if (scene.analytic) {
    const Oscillator osc;
    const auto [xh, vh] = osc.exact(scene.duration / 2);
    const auto [x, v] = osc.exact(scene.duration);
    ref.xHalf = weft::Vec3Array<double>::Zero(2, 3);
    ref.x = weft::Vec3Array<double>::Zero(2, 3);
    ref.xHalf(1, 0) = xh;
    ref.x(1, 0) = x;
    ref.energy = 0.5 * osc.mass * v * v + 0.5 * osc.stiffness() * (x - osc.rest) * (x - osc.rest);
    (void)vh;
    return ref;
  }
  const weft::ModelAndState<double> built = build<double>(scene);
  const double dt = (quick ? 0.1 : 0.05) * weft::estimateStableTimeStep(built.model, IntegratorKind::Rk4);
  const RunResult coarse = run<double>(scene, IntegratorKind::Rk4, dt, {}, 2);
  const RunResult fine = run<double>(scene, IntegratorKind::Rk4, dt / 2, {}, 2);
  if (!coarse.status.ok() || !fine.status.ok())
    throw std::runtime_error("study: the reference run of " + scene.name + " failed: " + fine.status.message());
  ref.xHalf = fine.xHalf;
  ref.x = fine.x;
  ref.energy = fine.energy;
  ref.selfCheck = (coarse.x - fine.x).cwiseAbs().maxCoeff();
  ref.dt = dt / 2;
  return ref;
}

/// Error of a run against the reference: for the oscillator the phase-space error
/// relative to the amplitude, |(x - x*, (v - v*) / omega)| / A; for rope and flag the
/// largest position error of any particle, m.
double errorAt(const SceneDef& scene, const weft::Vec3Array<double>& x, const weft::Vec3Array<double>* v,
               const weft::Vec3Array<double>& xRef, double t) {
  if (scene.analytic) {
    const Oscillator osc;
    const auto [xe, ve] = osc.exact(t);
    const double dv = v ? ((*v)(1, 0) - ve) / osc.omega : 0.0;
    return std::hypot(x(1, 0) - xe, dv) / osc.amplitude;
  }
  return (x - xRef).cwiseAbs().maxCoeff();
}

/// Largest dt (within a factor 2^(1/2^iterations) of the octave range) at which the
/// scene runs stably; nullopt if even `lo / 4^k` fails, +infinity if `hi` passes. A probe
/// runs for the scene's duration but at least 1000 steps, and is stable if the stability
/// check does not stop it and its total energy ends below E0 + energyMargin (nothing
/// drives these scenes: physically the energy only falls, so a gain of that size is the
/// growth of an unstable method, caught even where no spring overstretches).
std::optional<double> largestStableStep(bool isFloat, SceneDef scene, IntegratorKind kind, double lo, double hi,
                                        int iterations, int threads, double energy0, double energyMargin) {
  weft::IntegratorOptions io;
  io.adaptive = false;
  io.linearTolerance = isFloat ? 1e-5 : 1e-8;
  const double duration = scene.duration;
  const auto stable = [&](double dt) {
    // (Implicit Euler's probes run for the duration only: 1000 of its long steps would be
    // minutes of CG on the flag, and it has no growth to wait for.)
    scene.duration = !weft::integratorIsExplicit(kind) ? duration : std::max(duration, 1000 * dt);
    const RunResult r = runAny(isFloat, scene, kind, dt, io, threads);
    return r.status.ok() && r.energy <= energy0 + energyMargin;
  };
  if (stable(hi)) return std::numeric_limits<double>::infinity();
  while (!stable(lo)) {
    lo /= 4;
    if (lo < 1e-9) return std::nullopt;
  }
  for (int k = 0; k < iterations; ++k) {
    const double mid = std::sqrt(lo * hi);
    (stable(mid) ? lo : hi) = mid;
  }
  return lo;
}

std::string fmt(double v, int precision = 4) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (std::isnan(v)) return "nan";
  std::ostringstream o;
  o.precision(precision);
  o << v;
  return o.str();
}

struct Row {
  std::string scene, integrator, precision;
  int threads = 1;
  double dt = 0, tolerance = 0;
  Index steps = 0;
  double simulated = 0, error = NAN, errorHalf = NAN, energyError = NAN, wall = 0, wallPerSimulated = 0;
  double forceEvaluations = 0, linearIterations = 0, rejected = 0, substeps = 0;
  double stableMeasured = NAN, stableEstimate = NAN;
  std::string status;
  bool sameAsOneThread = true;
  std::string host;  // the machine the run was timed on
};

void pack(Packer& out, const Row& r) {
  for (const std::string* text : {&r.scene, &r.integrator, &r.precision, &r.status, &r.host}) out.put(*text);
  out.put(r.threads);
  out.put(r.steps);
  for (const double v :
       {r.dt, r.tolerance, r.simulated, r.error, r.errorHalf, r.energyError, r.wall, r.wallPerSimulated,
        r.forceEvaluations, r.linearIterations, r.rejected, r.substeps, r.stableMeasured, r.stableEstimate})
    out.put(v);
  out.put(r.sameAsOneThread);
}

Row unpackRow(Unpacker& in) {
  Row r;
  for (std::string* text : {&r.scene, &r.integrator, &r.precision, &r.status, &r.host}) *text = in.getString();
  r.threads = in.get<int>();
  r.steps = in.get<Index>();
  for (double* v :
       {&r.dt, &r.tolerance, &r.simulated, &r.error, &r.errorHalf, &r.energyError, &r.wall, &r.wallPerSimulated,
        &r.forceEvaluations, &r.linearIterations, &r.rejected, &r.substeps, &r.stableMeasured, &r.stableEstimate})
    *v = in.get<double>();
  r.sameAsOneThread = in.get<bool>();
  return r;
}

void pack(Packer& out, const weft::Vec3Array<double>& x) {
  out.put<Index>(x.rows());
  out.put(
      std::string_view(reinterpret_cast<const char*>(x.data()), sizeof(double) * static_cast<std::size_t>(x.size())));
}

weft::Vec3Array<double> unpackPositions(Unpacker& in) {
  const auto rows = in.get<Index>();
  const std::string bytes = in.getString();
  if (rows < 0 || bytes.size() != sizeof(double) * 3 * static_cast<std::size_t>(rows))
    throw std::runtime_error("study: a reference's positions came back with the wrong size");
  weft::Vec3Array<double> x(rows, 3);
  std::memcpy(x.data(), bytes.data(), bytes.size());
  return x;
}

// Estimated costs, in units of about one spring (or particle) visited by a force
// evaluation: only their order and ratios within a phase matter (largest first). Measured
// against the actual times in docs/distributed.md.
constexpr double kDispatch = 500;  // a parallel pass's start and end, in those units
constexpr double kRunSetUp = 2e4;  // building a Simulation (model copy, arena)

/// Work of one force evaluation of the scene.
double evaluationWork(const weft::Model<double>& model) {
  return static_cast<double>(model.springCount() + model.particleCount()) + kDispatch;
}

/// Force evaluations (or their equivalent) per step of a fixed-step method. Implicit Euler:
/// one evaluation and a Jacobian product per CG iteration, whose count grows with dt over the
/// explicit limit (about 10 per multiple of RK4's stable step, capped: the study's flag
/// and rope take 8 to 400).
double evaluationsPerStep(IntegratorKind kind, double dtOverRk4Limit) {
  switch (kind) {
    case IntegratorKind::Midpoint:
      return 2;
    case IntegratorKind::Rk4:
      return 4;
    case IntegratorKind::Rk45:
      return 6;
    case IntegratorKind::ImplicitEuler:
      return 2 + 1.5 * std::clamp(10 * dtOverRk4Limit, 1.0, 400.0);
    case IntegratorKind::Projective:  // 10 solves, each about 8 evaluations' worth (the flag's factor)
      return 1 + 10 * 8;
    default:
      return 1;
  }
}

}  // namespace

namespace {

struct SceneData {
  Reference ref;
  double omegaMax = 0, energy0 = 0, energyMargin = 0;
  double work = 0;      // estimated work of one force evaluation
  double rk4Limit = 0;  // the kernel's RK4 estimate, s
};

/// One scene x integrator x precision: its stability limit, then its points.
struct Cell {
  std::size_t scene = 0;
  IntegratorKind kind{};
  bool isFloat = false;
  double estimate = 0, scale = 0;
  std::optional<double> measured;
};

struct Point {
  std::size_t cell = 0;
  double dt = 0, tolerance = 0;
};

std::string cellName(const std::vector<SceneDef>& scenes, const Cell& c) {
  return scenes[c.scene].name + " " + weft::integratorName(c.kind) + " " + (c.isFloat ? "float" : "double");
}

int study(const StudyOptions& o, const Ranks& ranks, bool& written);

/// CPUs this process may run on (its affinity mask; the machine's if that cannot be read).
int usableCpuCount() {
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof set, &set) == 0) return CPU_COUNT(&set);
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

}  // namespace

int plotStudy(const StudyOptions& o);

int runStudy(const StudyOptions& o) {
  Ranks ranks = Ranks::join();
  try {
    bool written = false;
    const int code = study(o, ranks, written);
    // Before forking the plotter: an MPI process should not fork (some transports break).
    ranks.finish();
    if (written) {
      const int plotted = plotStudy(o);
      if (plotted != 0) return plotted;
    }
    return code;
  } catch (const std::exception& e) {
    if (ranks.size() > 1) {  // the other ranks would wait for this one forever
      std::cerr << "weft: " << e.what() << " (rank " << ranks.rank() << " of " << ranks.size() << ", on "
                << ranks.host() << ")\n";
      ranks.abort(2);
    }
    throw;
  }
}

namespace {

int study(const StudyOptions& o, const Ranks& ranks, bool& written) {
  namespace fs = std::filesystem;
  {
    // Rank 0 writes the files: only its file system needs the directory.
    std::string refused;
    if (ranks.root()) {
      std::error_code made;
      fs::create_directories(o.out, made);
      if (made || !fs::is_directory(o.out))
        refused = "study --out: cannot create the output directory '" + o.out +
                  "': " + (made ? made.message() : std::string("a file of that name is in the way"));
    }
    if (ranks.broadcast(refused.empty() ? 0 : 1) != 0) {
      if (ranks.root()) std::cerr << "weft: " << refused << "\n";
      return 2;
    }
  }
  const int maxThreads = *std::max_element(o.threads.begin(), o.threads.end());
  {
    // oneTBB runs no more threads than the process's CPU mask allows, and mpirun binds each
    // rank to one core by default: a "2 threads" run would quietly take one. Refused under
    // MPI (naming the ranks), a warning in a single process (as before, it still runs).
    Packer mine;
    mine.put(usableCpuCount());
    mine.put(ranks.host());
    std::string tooFew;
    const std::vector<std::string> all = ranks.allGather(mine.bytes());
    for (std::size_t r = 0; r < all.size(); ++r) {
      Unpacker in(all[r]);
      const int cpus = in.get<int>();
      const std::string host = in.getString();
      if (cpus < maxThreads)
        tooFew += (tooFew.empty() ? "" : ", ") +
                  std::string(ranks.distributed() ? "rank " + std::to_string(r) + " on " : "") + host + ": " +
                  std::to_string(cpus) + " CPU(s)";
    }
    if (!tooFew.empty() && ranks.root())
      std::cerr << "weft study: --threads asks for " << maxThreads << " threads, but " << tooFew
                << (ranks.distributed() ? " (mpirun binds each rank to one core by default: give each rank its "
                                          "threads with --map-by slot:PE=" +
                                              std::to_string(maxThreads) + ", or --bind-to none; docs/distributed.md)\n"
                                        : "; the runs with more threads than that are timed on fewer\n");
    if (!tooFew.empty() && ranks.distributed()) return 2;
  }
  const bool quick = o.quick;
  std::vector<SceneDef> scenes;
  {
    SceneDef osc;
    osc.name = "oscillator";
    osc.duration = 2;
    osc.analytic = true;
    osc.gravity = {0, 0, 0};
    SceneDef rope;
    rope.name = "rope";
    rope.size = 32;
    rope.duration = quick ? 0.5 : 1.0;
    SceneDef flag;
    flag.name = quick ? "flag24" : "flag64";
    flag.size = quick ? 24 : 64;
    flag.duration = quick ? 0.1 : 0.25;
    for (const SceneDef& scene : {osc, rope, flag})
      if (o.scenes.empty() || std::find(o.scenes.begin(), o.scenes.end(),
                                        scene.name.substr(0, scene.name == "oscillator" ? 10 : 4)) != o.scenes.end())
        scenes.push_back(scene);
  }
  const std::vector<double> dtFactors =
      quick ? std::vector<double>{0.9, 0.3, 0.1} : std::vector<double>{0.9, 0.5, 0.25, 0.125, 1.0 / 16, 1.0 / 32};
  const std::vector<double> implicitFactors =
      quick ? std::vector<double>{30, 3, 0.3} : std::vector<double>{100, 30, 10, 3, 1, 0.3};
  const std::vector<double> tolerances = quick ? std::vector<double>{1e-3, 1e-5, 1e-7}
                                               : std::vector<double>{1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9};
  const int bisections = quick ? 4 : 7;
  const int repetitions = quick ? 1 : 3;
  const auto started = std::chrono::steady_clock::now();
  std::vector<TaskRecord> schedule;

  // Phase 1: the references, one task per scene.
  std::vector<SceneData> data(scenes.size());
  {
    std::vector<StudyTask> tasks;
    for (std::size_t s = 0; s < scenes.size(); ++s) {
      const weft::ModelAndState<double> model = build<double>(scenes[s]);
      data[s].work = evaluationWork(model.model);
      data[s].rk4Limit = weft::estimateStableTimeStep(model.model, IntegratorKind::Rk4);
      data[s].omegaMax = weft::maxAngularFrequency(model.model);
      data[s].energy0 = weft::energy(model.model, model.state, scenes[s].gravity).total();
      // RK4 at dt and dt / 2 (reference()): three runs' worth at dt.
      const double steps = scenes[s].duration / ((quick ? 0.1 : 0.05) * data[s].rk4Limit);
      tasks.push_back(
          {"reference " + scenes[s].name, scenes[s].analytic ? 1.0 : 3 * steps * 4 * data[s].work + 2 * kRunSetUp});
    }
    const std::vector<std::string> results = runSpread(
        ranks, "references", tasks,
        [&](std::size_t s) {
          const Reference ref = reference(scenes[s], quick);
          Packer out;
          pack(out, ref.xHalf);
          pack(out, ref.x);
          for (const double v : {ref.energy, ref.selfCheck, ref.dt}) out.put(v);
          return out.bytes();
        },
        schedule);
    for (std::size_t s = 0; s < scenes.size(); ++s) {
      Unpacker in(results[s]);
      Reference& ref = data[s].ref;
      ref.xHalf = unpackPositions(in);
      ref.x = unpackPositions(in);
      ref.energy = in.get<double>();
      ref.selfCheck = in.get<double>();
      ref.dt = in.get<double>();
      data[s].energyMargin = std::max(std::abs(data[s].energy0), std::abs(ref.energy - data[s].energy0));
    }
  }

  // Phase 2: the largest stable step of each scene x integrator x precision (bisection).
  std::vector<Cell> cells;
  {
    std::vector<StudyTask> tasks;
    for (std::size_t s = 0; s < scenes.size(); ++s) {
      const weft::ModelAndState<double> model = build<double>(scenes[s]);
      for (const IntegratorKind kind : weft::kAllIntegrators)
        for (const bool isFloat : {false, true}) {
          Cell c;
          c.scene = s;
          c.kind = kind;
          c.isFloat = isFloat;
          c.estimate = weft::estimateStableTimeStep(model.model, kind);
          // Scale of the bisection: the estimate, or for methods without an imaginary-axis
          // limit (explicit Euler, midpoint: damping alone keeps them stable) symplectic
          // Euler's; implicit Euler is tried up to the whole duration.
          c.scale = c.estimate > 0 && std::isfinite(c.estimate)
                        ? c.estimate
                        : weft::estimateStableTimeStep(model.model, IntegratorKind::SymplecticEuler);
          // Probes near the limit, each over the duration but at least 1000 steps; the
          // limit is the estimate, or for explicit Euler and midpoint about 1/45 and 1/4 of
          // symplectic Euler's (the study's scenes); implicit Euler is stable at its first
          // probe (half the duration: two steps).
          const double duration = scenes[s].duration;
          const double expected = c.scale / (kind == IntegratorKind::ExplicitEuler ? 45.0
                                             : kind == IntegratorKind::Midpoint    ? 4.0
                                                                                   : 1.0);
          const double cost =
              !weft::integratorIsExplicit(kind)
                  ? 2 * evaluationsPerStep(kind, duration / 2 / data[s].rk4Limit) * data[s].work + kRunSetUp
                  : (bisections + 2) *
                        (std::max(duration / expected, 1000.0) * evaluationsPerStep(kind, 1) * data[s].work +
                         kRunSetUp);
          tasks.push_back({"limit " + cellName(scenes, c), cost});
          cells.push_back(c);
        }
    }
    const std::vector<std::string> results = runSpread(
        ranks, "stability limits", tasks,
        [&](std::size_t i) {
          const Cell& c = cells[i];
          const SceneDef& scene = scenes[c.scene];
          const SceneData& d = data[c.scene];
          std::optional<double> measured;
          if (!weft::integratorIsExplicit(c.kind))
            measured = largestStableStep(c.isFloat, scene, c.kind, c.scale, scene.duration / 2, bisections, maxThreads,
                                         d.energy0, d.energyMargin);
          else if (c.kind != IntegratorKind::Rk45)
            measured = largestStableStep(c.isFloat, scene, c.kind, c.scale / 16, c.scale * 16, bisections, maxThreads,
                                         d.energy0, d.energyMargin);
          else  // fixed-step rk45 (the adaptive one is limited only by its substeps)
            measured = largestStableStep(c.isFloat, scene, c.kind, c.scale / 4, c.scale * 64, bisections, maxThreads,
                                         d.energy0, d.energyMargin);
          Packer out;
          out.put(measured.has_value());
          out.put(measured.value_or(NAN));
          return out.bytes();
        },
        schedule);
    for (std::size_t i = 0; i < cells.size(); ++i) {
      Unpacker in(results[i]);
      if (in.get<bool>()) cells[i].measured = in.get<double>();
    }
  }

  std::ostringstream stableTable, referenceTable;
  for (std::size_t s = 0; s < scenes.size(); ++s)
    referenceTable << "| " << scenes[s].name << " | " << scenes[s].duration << " | "
                   << (scenes[s].analytic ? std::string("exact solution")
                                          : "RK4 double, dt " + fmt(data[s].ref.dt) +
                                                " s; vs 2 dt: " + fmt(data[s].ref.selfCheck) + " m")
                   << " |\n";
  for (const Cell& c : cells) {
    const double limit = c.measured.value_or(NAN);
    stableTable << "| " << scenes[c.scene].name << " | " << weft::integratorName(c.kind) << " | "
                << (c.isFloat ? "float" : "double") << " | " << fmt(c.estimate) << " | "
                << (c.measured ? fmt(limit) : std::string("none found")) << " | "
                << (c.measured && c.estimate > 0 && std::isfinite(c.estimate) && std::isfinite(limit)
                        ? fmt(limit / c.estimate, 3)
                        : std::string("-"))
                << " | " << (std::isfinite(limit) ? fmt(limit * data[c.scene].omegaMax, 3) : std::string("-"))
                << " |\n";
  }

  // Phase 3: the sweep, one task per point (all its thread counts and repetitions).
  std::vector<Point> points;
  std::vector<StudyTask> pointTasks;
  for (std::size_t ci = 0; ci < cells.size(); ++ci) {
    const Cell& c = cells[ci];
    const SceneDef& scene = scenes[c.scene];
    const SceneData& d = data[c.scene];
    const double limit = c.measured.value_or(NAN);
    std::vector<Point> mine;
    if (c.kind == IntegratorKind::Rk45) {
      const double frame = scene.duration / std::ceil(scene.duration * 60 - 1e-9);
      // Float cannot resolve an error estimate much below its epsilon (1.2e-7): tighter
      // tolerances only shrink the substeps towards minSubstep.
      for (const double tol : tolerances)
        if (!c.isFloat || tol >= 1e-6) mine.push_back({ci, frame, tol});
    } else if (!weft::integratorIsExplicit(c.kind)) {
      for (const double f : implicitFactors)
        if (f * d.rk4Limit <= scene.duration / 2) mine.push_back({ci, f * d.rk4Limit, 0});
    } else if (c.measured && std::isfinite(limit)) {
      for (const double f : dtFactors) mine.push_back({ci, f * limit, 0});
    }
    for (const Point& p : mine) {
      // Explicit Euler's tiny stable steps would take most of the study's time: skip
      // points needing more than this many steps (they are slower than every other
      // method at any accuracy anyway).
      if (scene.duration / p.dt > (quick ? 20000 : 100000)) continue;
      double steps = scene.duration / p.dt;
      double perStep = evaluationsPerStep(c.kind, p.dt / d.rk4Limit);
      if (c.kind == IntegratorKind::Rk45) {
        // Substeps per frame: at loose tolerances the stability limit's count (fixed-step
        // rk45's limit), then about 10^(1/5) more per decade below 1e-6.
        const double stable = std::isfinite(limit) ? p.dt / limit : 1.0;
        perStep *= std::max(1.0, stable) * std::max(1.0, 2 * std::pow(1e-6 / p.tolerance, 0.2));
      }
      const double cost = repetitions * static_cast<double>(o.threads.size()) * (steps * perStep * d.work + kRunSetUp);
      std::ostringstream name;
      name << "point " << cellName(scenes, c) << " dt " << fmt(p.dt);
      if (p.tolerance > 0) name << " tol " << fmt(p.tolerance);
      pointTasks.push_back({name.str(), cost});
      points.push_back(p);
    }
  }
  const std::vector<std::string> pointResults = runSpread(
      ranks, "points", pointTasks,
      [&](std::size_t i) {
        const Point& p = points[i];
        const Cell& c = cells[p.cell];
        const SceneDef& scene = scenes[c.scene];
        const Reference& ref = data[c.scene].ref;
        const double limit = c.measured.value_or(NAN);
        weft::IntegratorOptions io;
        io.relativeTolerance = io.absoluteTolerance = p.tolerance > 0 ? p.tolerance : 1e-6;
        io.linearTolerance = c.isFloat ? 1e-5 : 1e-8;
        std::uint64_t hashOne = 0;
        Packer out;
        for (const int threads : o.threads) {
          std::vector<double> walls;
          RunResult r;
          for (int rep = 0; rep < repetitions; ++rep) {
            r = runAny(c.isFloat, scene, c.kind, p.dt, io, threads);
            walls.push_back(r.wall);
          }
          std::sort(walls.begin(), walls.end());
          Row row;
          row.scene = scene.name;
          row.integrator = weft::integratorName(c.kind);
          row.precision = c.isFloat ? "float" : "double";
          row.threads = threads;
          row.steps = r.steps;
          row.dt = scene.duration / static_cast<double>(std::max<Index>(r.steps, 1));
          if (!r.status.ok()) row.dt = p.dt;
          row.tolerance = p.tolerance;
          row.simulated = row.dt * static_cast<double>(r.steps);
          row.status = r.status.ok() ? "ok" : weft::stepCodeName(r.status.code);
          row.wall = walls[walls.size() / 2];
          row.wallPerSimulated = r.status.ok() ? row.wall / scene.duration : NAN;
          if (r.status.ok()) {
            row.error = errorAt(scene, r.x, &r.v, ref.x, scene.duration);
            row.errorHalf = errorAt(scene, r.xHalf, nullptr, ref.xHalf, scene.duration / 2);
            row.energyError = std::abs(r.energy - ref.energy) / std::max(std::abs(ref.energy), 1e-12);
          }
          const double n = static_cast<double>(std::max<Index>(r.steps, 1));
          row.forceEvaluations = static_cast<double>(r.work.forceEvaluations) / n;
          row.linearIterations = static_cast<double>(r.work.linearIterations) / n;
          row.rejected = static_cast<double>(r.work.rejectedSubsteps) / n;
          row.substeps = static_cast<double>(r.work.substeps) / n;
          row.stableMeasured = limit;
          row.stableEstimate = c.estimate;
          if (threads == o.threads.front()) hashOne = r.hash;
          row.sameAsOneThread = r.hash == hashOne;
          row.host = ranks.host();
          pack(out, row);
        }
        return out.bytes();
      },
      schedule);
  std::vector<Row> rows;
  for (const std::string& result : pointResults) {
    Unpacker in(result);
    while (!in.done()) rows.push_back(unpackRow(in));
  }
  if (!ranks.root()) {  // rank 0 writes the files
    bool allSame = true;
    for (const Row& r : rows) allSame = allSame && r.sameAsOneThread;
    return allSame ? 0 : 1;
  }

  // CSV.
  const fs::path csvPath = fs::path(o.out) / "study.csv";
  {
    // dt, tolerances and the stable steps with every digit: a row reads back as the run it was.
    std::ostringstream csv;
    csv << "scene,integrator,precision,threads,dt,tolerance,steps,simulated_seconds,error,error_half,energy_drift,"
           "wall_seconds,wall_per_simulated_second,host,force_evaluations,linear_iterations,rejected_substeps,substeps,"
           "stable_dt_measured,stable_dt_estimate,status,bitwise_same_as_first_thread_count\n";
    csv.precision(17);
    for (const Row& r : rows)
      csv << r.scene << ',' << r.integrator << ',' << r.precision << ',' << r.threads << ',' << r.dt << ','
          << r.tolerance << ',' << r.steps << ',' << r.simulated << ',' << fmt(r.error, 9) << ',' << fmt(r.errorHalf, 9)
          << ',' << fmt(r.energyError, 9) << ',' << r.wall << ',' << fmt(r.wallPerSimulated, 9) << ',' << r.host << ','
          << r.forceEvaluations << ',' << r.linearIterations << ',' << r.rejected << ',' << r.substeps << ','
          << fmt(r.stableMeasured, 17) << ',' << fmt(r.stableEstimate, 17) << ',' << r.status << ','
          << (r.sameAsOneThread ? 1 : 0) << '\n';
    writeTextFile(csvPath.string(), csv.str());
  }

  // Markdown: cheapest configuration per scene and error target, then the limits.
  std::ostringstream md;
  md << "# weft study (" << (quick ? "quick" : "full") << ")\n\n"
     << "Error: oscillator = phase-space error / amplitude at T; rope and flag = largest position error of any "
        "particle at T, m. Wall time per simulated second on "
     << maxThreads << " thread(s), median of " << repetitions << ".\n";
  std::vector<std::string> hosts;
  for (const Row& r : rows)
    if (std::find(hosts.begin(), hosts.end(), r.host) == hosts.end()) hosts.push_back(r.host);
  if (hosts.size() > 1)
    md << "The runs were timed on " << hosts.size()
       << " machines (study.csv's host column): compare wall times within one machine.\n";
  md << "\n## References\n\n| scene | T (s) | reference |\n|---|---|---|\n"
     << referenceTable.str() << "\n## Cheapest run reaching each error\n\n"
     << "| scene | error <= | integrator | precision | dt (s) | rk45 tol | error | wall s / simulated s |\n"
     << "|---|---|---|---|---|---|---|---|\n";
  for (const SceneDef& scene : scenes)
    for (const double target : {1e-2, 1e-4, 1e-6, 1e-8}) {
      const Row* best = nullptr;
      for (const Row& r : rows)
        if (r.scene == scene.name && r.threads == maxThreads && r.status == "ok" && r.error <= target &&
            (!best || r.wallPerSimulated < best->wallPerSimulated))
          best = &r;
      md << "| " << scene.name << " | " << fmt(target) << " | ";
      if (best)
        md << best->integrator << " | " << best->precision << " | " << fmt(best->dt) << " | "
           << (best->tolerance > 0 ? fmt(best->tolerance) : "-") << " | " << fmt(best->error, 3) << " | "
           << fmt(best->wallPerSimulated, 3) << " |\n";
      else
        md << "none reached it | | | | | |\n";
    }
  md << "\n## Largest stable dt: estimate (kernel) vs measured (bisection, fixed steps)\n\n"
     << "| scene | integrator | precision | estimate (s) | measured (s) | measured / estimate | omega_max dt |\n"
     << "|---|---|---|---|---|---|---|\n"
     << stableTable.str();
  bool allSame = true;
  for (const Row& r : rows) allSame = allSame && r.sameAsOneThread;
  md << "\nEvery run's final state bitwise identical across thread counts: " << (allSame ? "yes" : "**no**") << "\n";
  const fs::path mdPath = fs::path(o.out) / "study.md";
  writeTextFile(mdPath.string(), md.str());
  written = true;
  std::cout << md.str();
  std::cout << "\nwrote " << csvPath.string() << " and " << mdPath.string() << " (" << rows.size() << " runs";
  if (ranks.size() > 1) std::cout << " on " << ranks.size() << " ranks, " << hosts.size() << " host(s)";
  std::cout << ", " << fmt(std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(), 3)
            << " s)\n";

  if (!o.schedule.empty()) {
    std::ostringstream out;
    out << "phase,task,estimated_cost,rank,host,wall_seconds\n";
    out.precision(6);
    for (const TaskRecord& t : schedule)
      out << t.phase << ',' << t.name << ',' << t.cost << ',' << t.rank << ',' << t.host << ',' << t.wall << '\n';
    writeTextFile(o.schedule, out.str());
  }
  return allSame ? 0 : 1;
}

}  // namespace

int plotStudy(const StudyOptions& o) {
  if (!o.plot) return 0;
  namespace fs = std::filesystem;
  const int maxThreads = *std::max_element(o.threads.begin(), o.threads.end());
  const fs::path csvPath = fs::path(o.out) / "study.csv";
  const fs::path script = fs::path(WEFT_SOURCE_DIR) / "tools" / "plot_study.py";
  const fs::path prefix = fs::path(o.out) / "study";
  if (!fs::exists(script) || !fs::exists("/usr/bin/python3")) {
    std::cerr << "weft study: plot skipped (" << script << " or /usr/bin/python3 missing)\n";
    return 0;
  }
  const std::string cmd = "/usr/bin/python3 '" + script.string() + "' '" + csvPath.string() + "' '" + prefix.string() +
                          "' --threads " + std::to_string(maxThreads);
  std::cout.flush();
  if (std::system(cmd.c_str()) != 0) {
    std::cerr << "weft study: plotting failed (is python3-matplotlib installed? bash tools/setup.sh)\n";
    return 1;
  }
  return 0;
}

}  // namespace weftcli
