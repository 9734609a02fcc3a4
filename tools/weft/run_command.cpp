#include "run_command.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "energy.hpp"
#include "weft/weft.hpp"

namespace weftcli {

namespace {

double peakResidentMegabytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

std::string hex(std::uint64_t h) {
  char buffer[19];
  std::snprintf(buffer, sizeof buffer, "0x%016llx", static_cast<unsigned long long>(h));
  return buffer;
}

/// Per-step averages (divide by `steps`) of a work total; residual and error estimate are
/// the largest seen.
nlohmann::ordered_json workJson(const weft::StepWork& w, std::int64_t steps) {
  const double n = steps > 0 ? static_cast<double>(steps) : 1.0;
  nlohmann::ordered_json j;
  j["force_evaluations"] = static_cast<double>(w.forceEvaluations) / n;
  j["substeps"] = static_cast<double>(w.substeps) / n;
  j["rejected_substeps"] = static_cast<double>(w.rejectedSubsteps) / n;
  j["linear_iterations"] = static_cast<double>(w.linearIterations) / n;
  j["linear_unconverged"] = static_cast<double>(w.linearUnconverged) / n;
  j["max_linear_residual"] = w.linearResidual;
  j["max_error_estimate"] = w.errorEstimate;
  return j;
}

std::string workLine(const weft::StepWork& w, std::int64_t steps) {
  const double n = steps > 0 ? static_cast<double>(steps) : 1.0;
  std::ostringstream out;
  out.precision(4);
  out << static_cast<double>(w.forceEvaluations) / n << " force evaluations";
  if (w.substeps != steps || w.rejectedSubsteps > 0)
    out << ", " << static_cast<double>(w.substeps) / n << " substeps (" << static_cast<double>(w.rejectedSubsteps) / n
        << " rejected), largest error estimate " << w.errorEstimate;
  if (w.linearIterations > 0 || w.linearResidual > 0)
    out << ", " << static_cast<double>(w.linearIterations) / n << " CG iterations (largest residual "
        << w.linearResidual << ", " << w.linearUnconverged << " solves at the cap)";
  return out.str();
}

/// Writes the frames of `weft run --out DIR`: one OBJ or PLY file per frame, or all
/// frames into DIR/frames.wcache.
template <class S>
class FrameSink {
 public:
  FrameSink(const RunOptions& o, const weft::Model<S>& model) : dir_(o.out), format_(o.format) {
    std::error_code error;
    std::filesystem::create_directories(dir_, error);
    if (error) throw std::runtime_error("cannot create --out directory '" + dir_ + "': " + error.message());
    if (format_ == "cache")
      cache_.emplace((std::filesystem::path(dir_) / "frames.wcache").string(), model.particleCount());
    else
      topology_ = weft::frameTopology(model);
  }

  void write(const weft::State<S>& state) {
    if (cache_) {
      cache_->append(state);
    } else {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%06lld.%s", static_cast<long long>(written_), format_.c_str());
      const std::string path = (std::filesystem::path(dir_) / name).string();
      if (format_ == "ply")
        weft::writePly(path, state.x, topology_);
      else
        weft::writeObj(path, state.x, topology_);
    }
    ++written_;
  }
  void close() {
    if (cache_) cache_->close();
  }
  std::int64_t written() const { return written_; }

 private:
  std::string dir_;
  std::string format_;
  weft::FrameTopology topology_;
  std::optional<weft::FrameCacheWriter<S>> cache_;
  std::int64_t written_ = 0;
};

template <class S>
int run(const RunOptions& o) {
  const weft::BuiltinScene scene = weft::parseBuiltinScene(o.scene);
  const weft::Index size = o.size > 0 ? static_cast<weft::Index>(o.size) : weft::defaultSceneSize(scene);
  weft::SimulationOptions options;
  options.integrator = weft::parseIntegrator(o.integrator);
  options.dt = o.dt > 0 ? o.dt : weft::defaultTimeStep(scene, size);
  options.threads = o.threads;
  options.forceStrategy = weft::parseForceStrategy(o.strategy);
  options.integration = o.integration;
  options.effects.drag = o.drag;
  options.integration.adaptive = !o.fixedStep;
  weft::Simulation<S> sim(weft::makeBuiltinScene<S>(scene, size), options);

  // Without --out the run is one sim.run(steps). With it, the steps go in chunks of
  // --every with a frame after each; wall time counts the stepping only.
  std::optional<FrameSink<S>> frames;
  weft::StepStatus status;
  double wall = 0;
  if (o.out.empty()) {
    const auto start = std::chrono::steady_clock::now();
    status = sim.run(static_cast<weft::Index>(o.steps));
    wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  } else {
    frames.emplace(o, sim.model());
    frames->write(sim.state());
    for (std::int64_t remaining = o.steps; remaining > 0 && status.ok();) {
      const std::int64_t chunk = std::min(remaining, o.every);
      const auto start = std::chrono::steady_clock::now();
      status = sim.run(static_cast<weft::Index>(chunk));
      wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      remaining -= chunk;
      if (status.ok() && chunk == o.every) frames->write(sim.state());
    }
    frames->close();
  }

  const weft::Model<S>& model = sim.model();
  const weft::State<S>& state = sim.state();
  const std::int64_t done = sim.stepCount();
  const double stepsPerSecond = wall > 0 ? static_cast<double>(done) / wall : 0;
  const double springEvals = static_cast<double>(sim.forceEvaluations()) * model.springCount();
  const double springEvalsPerSecond = wall > 0 ? springEvals / wall : 0;
  const std::string hash = hex(weft::stateHash(state));
  const auto byClass = model.springCountByClass();
  const Energy e = energy(model, state, options.gravity);
  const double lowest = static_cast<double>(state.x.col(1).minCoeff());
  const double stableDt = weft::estimateStableTimeStep(model, options.integrator);

  if (o.json) {
    nlohmann::ordered_json j;
    j["scene"] = o.scene;
    j["particles"] = model.particleCount();
    j["springs"] = model.springCount();
    j["springs_by_class"] = {{"structural", byClass[0]}, {"shear", byClass[1]}, {"bend", byClass[2]}};
    j["integrator"] = weft::integratorName(options.integrator);
    j["precision"] = o.precision;
    j["threads"] = sim.threadCount();
    j["force_strategy"] = weft::forceStrategyName(sim.forceStrategy());
    j["steps"] = done;
    j["steps_requested"] = o.steps;
    j["dt"] = options.dt;
    j["simulated_seconds"] = state.time;
    j["wall_seconds"] = wall;
    j["steps_per_second"] = stepsPerSecond;
    j["spring_evals_per_second"] = springEvalsPerSecond;
    j["force_evaluations"] = sim.forceEvaluations();
    j["work_per_step"] = workJson(sim.totalWork(), done);
    j["work_total"] = workJson(sim.totalWork(), 1);
    if (std::isfinite(stableDt))
      j["stable_dt_estimate"] = stableDt;
    else
      j["stable_dt_estimate"] = nullptr;  // no limit (implicit Euler, or a model without springs)
    j["status"] = weft::stepCodeName(status.code);
    if (!status.ok()) j["status_message"] = status.message();
    j["state_hash"] = hash;
    j["energy"] = {{"kinetic", e.kinetic}, {"spring", e.spring}, {"gravity", e.gravity}};
    j["lowest_y"] = lowest;
    if (frames) {
      j["frames_written"] = frames->written();
      j["output"] = o.out;
    }
    j["peak_rss_mb"] = peakResidentMegabytes();
    std::cout << j.dump() << std::endl;
  } else {
    std::ostringstream out;
    out.precision(6);
    out << "weft run " << o.scene << "\n"
        << "  model        " << model.particleCount() << " particles (" << model.pinnedCount() << " pinned), "
        << model.springCount() << " springs (structural " << byClass[0] << ", shear " << byClass[1] << ", bend "
        << byClass[2] << ")\n"
        << "  integrator   " << weft::integratorName(options.integrator) << ", " << o.precision << ", dt " << options.dt
        << " s, " << sim.threadCount() << " thread(s), forces: " << weft::forceStrategyName(sim.forceStrategy()) << "\n"
        << "  stable dt    " << (std::isfinite(stableDt) ? std::to_string(stableDt) + " s" : std::string("unlimited"))
        << " estimated for this integrator (omega_max <= " << weft::maxAngularFrequency(model) << " rad/s)\n"
        << "  work/step    " << workLine(sim.totalWork(), done) << "\n"
        << "  steps        " << done << " of " << o.steps << " (" << state.time << " s simulated)\n"
        << "  wall time    " << wall << " s: " << stepsPerSecond << " steps/s, " << springEvalsPerSecond / 1e6
        << " M spring evaluations/s\n"
        << "  energy       kinetic " << e.kinetic << " J, spring " << e.spring << " J, gravity " << e.gravity
        << " J; lowest point y = " << lowest << " m\n"
        << "  status       " << (status.ok() ? std::string("ok") : status.message()) << "\n"
        << "  state hash   " << hash << "\n"
        << "  peak memory  " << peakResidentMegabytes() << " MB resident\n";
    if (frames)
      out << "  frames       " << frames->written() << " (" << o.format << ", every " << o.every << " steps) in "
          << o.out << "\n";
    std::cout << out.str();
  }
  return status.ok() ? 0 : 3;
}

}  // namespace

int runScene(const RunOptions& options) {
  return options.precision == "float" ? run<float>(options) : run<double>(options);
}

}  // namespace weftcli
