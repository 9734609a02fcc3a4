#include "soak_command.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "output_file.hpp"
#include "process_memory.hpp"
#include "unchecked_state.hpp"
#include "weft/io/scene.hpp"
#include "weft/weft.hpp"

namespace weftcli {

namespace {

struct RunResult {
  std::uint64_t hash = 0;
  std::int64_t steps = 0;
  std::string status = "ok";
  double simulated = 0;    // s
  double wall = 0;         // s
  double energyStart = 0;  // J, particles and rigid bodies
  double energyMax = 0, energyMin = 0;
  double residentEarly = 0, residentHalf = 0, residentEnd = 0;  // bytes, after 1 % and 50 % of the steps, at the end
  double heapEarly = 0, heapHalf = 0, heapEnd = 0;  // bytes from the allocator (heapBytes), likewise; -1 if unknown
  bool sampledEarly = false, sampledHalf = false;
  double listsHalf = 0, listsEnd = 0;  // bytes of Simulation::contactListBytes at 50 % and at the end
  std::vector<std::string> warnings;   // Simulation::warnings at the end
};

template <class S>
RunResult soakRun(const weft::SceneSpec& spec, std::int64_t steps, int threads) {
  weft::AssembledScene<S> assembled = weft::assembleScene<S>(spec);
  weft::SimulationOptions options = assembled.options;
  options.threads = threads;
  weft::Simulation<S> sim(std::move(assembled.built), options);
  const auto energy = [&] {
    double e = sim.model().particleCount() > 0 ? weft::energy(sim.model(), sim.state(), options.gravity).total() : 0.0;
    if (const weft::RigidWorld* rigid = sim.rigidWorld()) e += rigid->energy();
    return e;
  };
  RunResult r;
  r.energyStart = r.energyMax = r.energyMin = energy();
  const std::int64_t sample = std::max<std::int64_t>(1, steps / 100);
  weft::StepStatus status;
  while (sim.stepCount() < steps && status.ok()) {
    const auto start = std::chrono::steady_clock::now();
    status = sim.run(static_cast<weft::Index>(std::min(sample, steps - sim.stepCount())));
    r.wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double e = energy();
    r.energyMax = std::max(r.energyMax, e);
    r.energyMin = std::min(r.energyMin, e);
    if (!r.sampledEarly) {
      r.sampledEarly = true;
      r.residentEarly = residentBytes();
      r.heapEarly = heapBytes();
    }
    if (!r.sampledHalf && 2 * sim.stepCount() >= steps) {
      r.sampledHalf = true;
      r.residentHalf = residentBytes();
      r.heapHalf = heapBytes();
      r.listsHalf = static_cast<double>(sim.contactListBytes());
    }
  }
  r.residentEnd = residentBytes();
  r.heapEnd = heapBytes();
  r.listsEnd = static_cast<double>(sim.contactListBytes());
  if (!r.sampledHalf) {  // (a run that stopped early)
    r.residentHalf = r.residentEnd;
    r.heapHalf = r.heapEnd;
    r.listsHalf = r.listsEnd;
  }
  r.steps = sim.stepCount();
  r.simulated = sim.state().time;
  if (!status.ok()) r.status = std::string(weft::stepCodeName(status.code)) + ": " + status.message();
  // (With the stability check off nothing stops a state that overflowed: not "ok" either.)
  else if (!sim.stateFinite())
    r.status = "not_finite: " + notFiniteMessage(sim.stepCount());
  r.warnings = sim.warnings();
  const weft::RigidWorld* rigid = sim.rigidWorld();
  r.hash = rigid ? weft::stateHash(sim.state()) ^ weft::rigidStateHash(rigid->state()) : weft::stateHash(sim.state());
  return r;
}

/// Whether something feeds energy in: wind, moving pins, kinematic bodies (then the energy
/// bound is not checked).
bool driven(const weft::SceneSpec& spec) {
  const weft::SimulationOptions& o = spec.simulation;
  if (o.effects.wind.enabled || !o.kinematicPins.empty()) return true;
  for (const weft::BodySpec& b : spec.bodies)
    for (const weft::PinSpec& p : b.pins)
      if (p.path) return true;
  for (const weft::RigidBodyDesc& b : o.rigid.bodies)
    if (b.motion == weft::BodyMotion::Kinematic) return true;
  return false;
}

std::string fixed(double v, int digits) {
  char text[48];
  std::snprintf(text, sizeof text, "%.*f", digits, v);
  return text;
}

std::string hex(std::uint64_t h) {
  char text[19];
  std::snprintf(text, sizeof text, "0x%016llx", static_cast<unsigned long long>(h));
  return text;
}

}  // namespace

int runSoak(const SoakOptions& o) {
  if (!(std::isfinite(o.seconds) && o.seconds > 0))
    throw std::invalid_argument("--seconds must be finite and > 0, got " + std::to_string(o.seconds));
  if (o.maxSteps < 1) throw std::invalid_argument("--max-steps must be >= 1, got " + std::to_string(o.maxSteps));
  if (o.threads.empty()) throw std::invalid_argument("--threads needs at least one thread count");
  if (!o.out.empty()) checkOutputFile(o.out, "--out");
  const std::vector<std::string> scenes = o.scenes.empty() ? weft::builtinSceneNames() : o.scenes;
  std::ostringstream table, notes;  // notes: the warnings, printed after the table
  table << "| scene | precision | steps | simulated s | wall s (threads";
  // A count above what the machine runs is run on fewer threads (the kernel's cap): the
  // header and stderr say so, since the hashes compared are then of fewer thread counts.
  for (const int t : o.threads) {
    const int runs = weft::Executor(t).threadCount();
    table << " " << t;
    if (runs != t) {
      table << " (runs " << runs << ")";
      std::cerr << "weft soak: note: --threads " << t << " runs on " << runs
                << " threads, the most this machine runs\n";
    }
  }
  table << ") | status | final hash | energy J: start, max, min | rise / range | allocated MB at 1 % -> 50 % -> end | "
           "resident MB at 1 % -> 50 % -> end | checks |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  std::cout << table.str() << std::flush;
  bool allPass = true;
  for (const std::string& name : scenes) {
    const weft::SceneSpec spec = weft::builtinSceneSpec(name);
    const double dt = spec.simulation.dt;
    // (Compared as doubles: --seconds 1e16 is more steps than an int64 holds.)
    const double wanted = std::ceil(o.seconds / dt);
    const std::int64_t steps =
        wanted < static_cast<double>(o.maxSteps) ? static_cast<std::int64_t>(wanted) : o.maxSteps;
    std::vector<RunResult> runs;
    for (const int threads : o.threads)
      runs.push_back(spec.precision == weft::Precision::Float ? soakRun<float>(spec, steps, threads)
                                                              : soakRun<double>(spec, steps, threads));
    // The checks: every run ok, one hash, energy not above its start (beyond 1 % of its
    // range) unless the scene drives it, and the memory allocated flat over the second
    // half of the run (at most 1 MB + 1 % more at the end than at 50 %), apart from what
    // the contact lists grew by (Simulation::contactListBytes: a cloth wrung tighter and
    // tighter lists more pairs to the end, and its lists keep their largest size; the
    // check column says how much). Allocated, not resident: the pages of buffers reserved
    // at construction become resident when first touched (a pile's contact buffers when
    // it lands, maybe in the second half of a short run), which is not an allocation; the
    // table shows both, at 1 % -> 50 % -> end. Where the allocator does not say what it
    // handed out (not glibc), the resident memory is checked instead.
    std::vector<std::string> failed;
    bool sameHash = true;
    for (const RunResult& r : runs) {
      if (r.status != "ok") failed.push_back("status");
      sameHash = sameHash && r.hash == runs.front().hash;
    }
    if (!sameHash) failed.push_back("hash differs between thread counts");
    const RunResult& first = runs.front();
    const double range = std::max({first.energyMax - first.energyMin, std::abs(first.energyStart), 1e-12});
    const double rise = first.energyMax - first.energyStart;
    const bool passive = !driven(spec);
    if (passive && rise > 0.01 * range) failed.push_back("energy rose");
    const bool heapKnown = first.heapHalf >= 0;
    double growth = 0, lists = 0;
    for (const RunResult& r : runs) {
      const double grew = heapKnown ? r.heapEnd - r.heapHalf : r.residentEnd - r.residentHalf;
      growth = std::max(growth, grew - (r.listsEnd - r.listsHalf));
      lists = std::max(lists, r.listsEnd - r.listsHalf);
    }
    if (growth > 1024.0 * 1024 + 0.01 * (heapKnown ? first.heapHalf : first.residentHalf))
      failed.push_back(heapKnown ? "memory allocated grew in the second half" : "memory grew in the second half");
    std::ostringstream row;
    row << "| " << name << " | " << (spec.precision == weft::Precision::Float ? "float" : "double") << " | "
        << first.steps << " | " << fixed(first.simulated, 2) << " | ";
    for (size_t k = 0; k < runs.size(); ++k) row << (k ? " / " : "") << fixed(runs[k].wall, 1);
    row << " | " << (failed.empty() || first.status == "ok" ? first.status : first.status.substr(0, 60)) << " | "
        << hex(first.hash) << (sameHash ? " (all equal)" : " (differ)") << " | " << fixed(first.energyStart, 4) << ", "
        << fixed(first.energyMax, 4) << ", " << fixed(first.energyMin, 4) << " | "
        << (passive ? fixed(rise / range, 4) : std::string("driven")) << " | ";
    if (heapKnown)
      row << fixed(first.heapEarly / (1024.0 * 1024), 1) << " -> " << fixed(first.heapHalf / (1024.0 * 1024), 1)
          << " -> " << fixed(first.heapEnd / (1024.0 * 1024), 1) << " | ";
    else
      row << "unknown | ";
    row << fixed(first.residentEarly / (1024.0 * 1024), 1) << " -> " << fixed(first.residentHalf / (1024.0 * 1024), 1)
        << " -> " << fixed(first.residentEnd / (1024.0 * 1024), 1) << " | ";
    if (failed.empty()) {
      row << "pass";
      // A warning does not fail the soak (the run went on, finite and bounded), but is shown.
      if (!first.warnings.empty())
        row << " (" << first.warnings.size() << (first.warnings.size() == 1 ? " warning" : " warnings")
            << ", below the table)";
      if (lists >= 0.1 * 1024 * 1024)
        row << " (contact lists grew by " << fixed(lists / (1024.0 * 1024), 1) << " MB in the second half)";
    } else {
      allPass = false;
      for (size_t k = 0; k < failed.size(); ++k) row << (k ? ", " : "") << failed[k];
    }
    row << " |\n";
    for (const std::string& w : first.warnings) notes << "- " << name << ": warning: " << w << "\n";
    std::cout << row.str() << std::flush;
    table << row.str();
  }
  if (!notes.str().empty()) {
    std::cout << "\n" << notes.str() << std::flush;
    table << "\n" << notes.str();
  }
  if (!o.out.empty()) writeTextFile(o.out, table.str());
  return allPass ? 0 : 1;
}

}  // namespace weftcli
