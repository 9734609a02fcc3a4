#include "run_command.hpp"

#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "output_file.hpp"
#include "process_memory.hpp"
#include "unchecked_state.hpp"
#include "weft/io/gltf.hpp"
#include "weft/io/scene.hpp"
#include "weft/weft.hpp"

namespace weftcli {

namespace {

/// The shortest text that reads back as v ("0.0166667" would not).
std::string shortest(double v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, result.ptr);
}

/// Memory the machine has available for a new allocation, bytes (MemAvailable of
/// /proc/meminfo; infinity if unreadable).
double availableBytes() {
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  double kib = 0;
  std::string unit;
  while (meminfo >> key >> kib >> unit)
    if (key == "MemAvailable:") return kib * 1024;
  return std::numeric_limits<double>::infinity();
}

std::string gib(double bytes) {
  char text[32];
  if (bytes >= 1024.0 * 1024 * 1024)
    std::snprintf(text, sizeof text, "%.1f GiB", bytes / (1024.0 * 1024 * 1024));
  else
    std::snprintf(text, sizeof text, "%.0f MiB", bytes / (1024.0 * 1024));
  return text;
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
  j["factorizations"] = w.factorizations;  // projective: in all (one per step size), not per step
  // implicit Euler: the share of steps (work_total: the steps) whose CG the multigrid preconditioned
  j["multigrid_solves"] = static_cast<double>(w.multigridSolves) / n;
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
  if (w.factorizations > 0)  // projective dynamics
    out << ", " << static_cast<double>(w.linearIterations) / n
        << " global solves (largest last-iteration change relative to the step's displacement " << w.linearResidual
        << "), " << w.factorizations << " factorisation" << (w.factorizations == 1 ? "" : "s");
  else if (w.linearIterations > 0 || w.linearResidual > 0)
    out << ", " << static_cast<double>(w.linearIterations) / n << " CG iterations (largest residual "
        << w.linearResidual << ", " << w.linearUnconverged << " solves at the cap"
        << (w.multigridSolves > 0 ? ", " + std::to_string(w.multigridSolves) + " with the multigrid" : std::string())
        << ")";
  return out.str();
}

/// The file of frame k: frame_000042.obj.
std::string frameFileName(std::int64_t k, const std::string& format) {
  char name[48];
  std::snprintf(name, sizeof name, "frame_%06lld.", static_cast<long long>(k));
  return name + format;
}

/// Writes the frames of `weft run --out DIR`: one OBJ or PLY file per frame, or all
/// frames into DIR/frames.wcache, or into one animated DIR/run.glb.
template <class S>
class FrameSink {
 public:
  /// `scene` names the scene in messages (and the glTF object); `steps` is the run's length.
  FrameSink(const weft::OutputSpec& o, const weft::Model<S>& model, const std::string& scene, std::int64_t steps)
      : dir_(o.directory), format_(o.format) {
    if (format_ != "cache") topology_ = weft::frameTopology(model);
    if (format_ == "gltf") checkGltf(o, model, scene, steps);
    if (model.particleCount() == 0)
      throw std::invalid_argument("--out " + dir_ + ": the scene '" + scene +
                                  "' has no particles to write (frames hold particles; rigid bodies are not written "
                                  "to them: weft render draws them)");
    std::error_code error;
    std::filesystem::create_directories(dir_, error);
    if (error) throw std::runtime_error("cannot create the output directory '" + dir_ + "': " + error.message());
    if (format_ == "cache") {
      cache_.emplace((std::filesystem::path(dir_) / "frames.wcache").string(), model.particleCount());
    } else if (format_ == "gltf") {
      try {
        gltf_.emplace((std::filesystem::path(dir_) / "run.glb").string(), model.particleCount(), topology_,
                      weft::GltfOptions{scene});
      } catch (const std::exception& e) {
        throw std::runtime_error("--out " + dir_ + " --format gltf: " + e.what());
      }
    }
  }

  /// Writes the state's frame; returns why not when the format cannot hold it (a glTF frame
  /// is float: a coordinate past float's range), leaving the frames before it as they were.
  std::string write(const weft::State<S>& state) {
    if (cache_) {
      cache_->append(state);
    } else if (gltf_) {
      try {
        gltf_->append(state);
      } catch (const std::invalid_argument& e) {  // (the writer checks every value before it writes)
        return e.what();
      }
    } else {
      const std::string path = (std::filesystem::path(dir_) / frameFileName(written_, format_)).string();
      if (format_ == "ply")
        weft::writePly(path, state.x, topology_);
      else
        weft::writeObj(path, state.x, topology_);
    }
    ++written_;
    return {};
  }
  void close() {
    if (cache_) cache_->close();
    if (gltf_) gltf_->close();
  }
  /// Continues a resumed run's numbering: frames 0 .. count - 1 are on disk already.
  void resumeAt(std::int64_t count) { written_ = count; }
  std::int64_t written() const { return written_; }

 private:
  /// A glTF file holds a mesh with an animation: refused before the run when the scene has
  /// no particles or the run would write more frames than one file holds.
  void checkGltf(const weft::OutputSpec& o, const weft::Model<S>& model, const std::string& scene,
                 std::int64_t steps) const {
    if (model.particleCount() == 0)
      throw std::invalid_argument("--format gltf: the scene '" + scene +
                                  "' has no particles to write (rigid bodies are not exported to glTF)");
    if (!topology_.triangles.empty() && !topology_.lines.empty())
      throw std::invalid_argument("--format gltf: the scene '" + scene + "' has cloth (" +
                                  std::to_string(topology_.triangles.size()) + " triangles) and ropes (" +
                                  std::to_string(topology_.lines.size()) +
                                  " lines): a glTF frame here holds one kind; use --format obj, ply or cache");
    const std::int64_t frames = steps / o.every + 1;
    const std::int64_t most = weft::gltfMaxFrames(model.particleCount(), topology_);
    if (frames > most) {
      std::ostringstream msg;
      msg << "--format gltf --every " << o.every << ": " << frames << " frames of " << steps << " steps, more than the "
          << most << " one glTF file of '" << scene << "' holds (" << model.particleCount() << " particles; at most "
          << weft::kGltfMaxFrames << " frames, one morph target each, and 4 GiB)";
      if (most > 1) msg << "; use --every " << (steps + most - 2) / (most - 1) << " or more";
      throw std::invalid_argument(msg.str());
    }
  }

  std::string dir_;
  std::string format_;
  weft::FrameTopology topology_;
  std::optional<weft::FrameCacheWriter<S>> cache_;
  std::optional<weft::GltfAnimationWriter<S>> gltf_;
  std::int64_t written_ = 0;
};

/// The record of a frame directory's numbering, `DIR/frames.json`: frame k of a run is its
/// step k x every, also across --resume, so a resumed run must take frames with the same
/// period and format as the run that began the directory.
constexpr const char* kFramesRecord = "frames.json";

void writeFramesRecord(const weft::OutputSpec& output, const std::string& scene) {
  nlohmann::ordered_json j;
  j["scene"] = scene;
  j["format"] = output.format;
  j["every"] = output.every;
  j["frame_k_is_step"] = "k x every";
  writeTextFile((std::filesystem::path(output.directory) / kFramesRecord).string(), j.dump(2) + "\n");
}

/// Before a resumed run writes obj or ply frames into a directory that has some: with the
/// directory's record, the same period and format (frames written again are the same
/// bits); without one (frames of a weft before the record), the frames on disk must end
/// just before the one the run writes next. Otherwise the run would write over frames of
/// other steps or leave a gap, and it is refused before its first step.
void checkResumedFrames(const weft::OutputSpec& output, std::int64_t step) {
  const std::string record = (std::filesystem::path(output.directory) / kFramesRecord).string();
  std::error_code error;
  if (std::filesystem::exists(record, error)) {
    nlohmann::json j;
    try {
      std::ifstream in(record);
      j = nlohmann::json::parse(in);
      (void)j.at("every").get<std::int64_t>();
      (void)j.at("format").get<std::string>();
    } catch (const std::exception& e) {
      throw std::runtime_error("--resume: cannot read the frame record '" + record + "' (" + e.what() +
                               "): remove it to resume by the frames' numbers alone");
    }
    const std::int64_t every = j["every"].get<std::int64_t>();
    const std::string format = j["format"].get<std::string>();
    if (every != output.every || format != output.format)
      throw std::invalid_argument("--resume: the frames in '" + output.directory + "' were written as " + format +
                                  " every " + std::to_string(every) + " steps (" + kFramesRecord +
                                  "), and this run asks for " + output.format + " every " +
                                  std::to_string(output.every) +
                                  ": resume with the run's --every and --format, or into another directory (--out)");
    return;
  }
  const std::int64_t next = step / output.every + 1;
  const auto frameName = [&](std::int64_t k) { return frameFileName(k, output.format); };
  std::int64_t highest = -1;
  std::optional<std::pair<std::int64_t, std::string>> other;  // the other format's first frame
  for (const auto& entry : std::filesystem::directory_iterator(output.directory, error)) {
    const std::string name = entry.path().filename().string();
    const std::string ext = entry.path().extension().string();
    if (!name.starts_with("frame_") || (ext != ".obj" && ext != ".ply")) continue;
    const std::string digits = name.substr(6, name.size() - 6 - ext.size());
    if (digits.empty() || digits.size() > 18 ||
        !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }))
      continue;
    const std::int64_t k = std::stoll(digits);
    if (ext != "." + output.format) {
      if (!other || k < other->first) other = {k, name};  // (the same file whatever the directory's order)
      continue;
    }
    highest = std::max(highest, k);
  }
  if (other)
    throw std::invalid_argument("--resume: the frame directory '" + output.directory + "' holds " + other->second +
                                ", and this run writes " + output.format +
                                " frames: resume with the format the run began with (--format), or into another "
                                "directory (--out)");
  if (highest < 0 || highest == next - 1) return;
  std::ostringstream msg;
  msg << "--resume: the frames in '" << output.directory << "' end at " << frameName(highest)
      << ", and this run continues from step " << step << " and writes " << frameName(next) << " next (frame k is step "
      << "k x --every " << output.every
      << "): " << (highest >= next ? "it would write over frames " : "it would leave frames missing ")
      << "(were they written with another --every, or after the checkpoint?); resume with the --every the run began "
      << "with, into another directory (--out), or after moving ";
  if (highest >= next)
    msg << "the frames after " << frameName(next - 1) << " away";
  else
    msg << "those frames away";
  throw std::invalid_argument(msg.str());
}

/// A one-line progress bar on stdout, drawn only when stdout is a terminal and only once
/// the run has taken more than a second.
class Progress {
 public:
  Progress(bool enabled, std::int64_t total) : enabled_(enabled && isatty(STDOUT_FILENO) == 1), total_(total) {}
  void update(std::int64_t done) {
    if (!enabled_) return;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (elapsed < 1.0 || elapsed - lastDraw_ < 0.1) return;
    lastDraw_ = elapsed;
    const double fraction = total_ > 0 ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
    const int width = 40, filled = static_cast<int>(fraction * width);
    const double eta = fraction > 0 ? elapsed * (1 - fraction) / fraction : 0;
    std::printf("\r[%.*s%*s] %3.0f%% %lld/%lld steps, %.1f s left ", filled, "########################################",
                width - filled, "", 100 * fraction, static_cast<long long>(done), static_cast<long long>(total_), eta);
    std::fflush(stdout);
    drawn_ = true;
  }
  void finish() {
    if (drawn_) {
      std::printf("\r%*s\r", 80, "");
      std::fflush(stdout);
    }
  }

 private:
  bool enabled_;
  std::int64_t total_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  double lastDraw_ = 0;
  bool drawn_ = false;
};

/// An integrator setting: its option on the command line (null: none), its key in scene
/// files, the integrator that reads it (and whether only rk45's error control does), and
/// whether the command line gave it or the scene's value differs from the default. The
/// refusals of options and the notes on scene keys below both go through this one list.
struct IntegratorSetting {
  const char* option;
  const char* key;
  weft::IntegratorKind reader;
  bool errorControl;
  bool given, set;
};

/// The integrators' settings; `given` says the command line gave one, `set` that the scene
/// file wrote its key or the run's value is not the default.
std::vector<IntegratorSetting> integratorSettings(const RunOptions& o, const weft::IntegratorOptions& io,
                                                  const std::set<std::string>& fileKeys) {
  const weft::IntegratorOptions d;
  using K = weft::IntegratorKind;
  std::vector<IntegratorSetting> settings = {
      {"--rtol", "integration.rtol", K::Rk45, true, o.relativeTolerance.has_value(),
       io.relativeTolerance != d.relativeTolerance},
      {"--atol", "integration.atol", K::Rk45, true, o.absoluteTolerance.has_value(),
       io.absoluteTolerance != d.absoluteTolerance},
      {nullptr, "integration.min_substep", K::Rk45, true, false, io.minSubstep != d.minSubstep},
      {nullptr, "integration.max_substeps", K::Rk45, true, false, io.maxSubsteps != d.maxSubsteps},
      {"--fixed-step", "integration.adaptive", K::Rk45, false, o.fixedStep, io.adaptive != d.adaptive},
      {"--cg-tolerance", "integration.cg_tolerance", K::ImplicitEuler, false, o.linearTolerance.has_value(),
       io.linearTolerance != d.linearTolerance},
      {"--cg-max-iterations", "integration.cg_max_iterations", K::ImplicitEuler, false,
       o.maxLinearIterations.has_value(), io.maxLinearIterations != d.maxLinearIterations},
      {"--cg-preconditioner", "integration.cg_preconditioner", K::ImplicitEuler, false, o.preconditioner.has_value(),
       io.preconditioner != d.preconditioner},
      {"--pd-iterations", "integration.projective_iterations", K::Projective, false, o.projectiveIterations.has_value(),
       io.projectiveIterations != d.projectiveIterations},
  };
  for (IntegratorSetting& setting : settings) setting.set = setting.set || fileKeys.count(setting.key) > 0;
  return settings;
}

/// Whether a body has a box or hull piece: the narrow phase's pairs (a sphere's test is its own).
bool hasHulls(const weft::RigidOptions& rigid) {
  return std::any_of(rigid.bodies.begin(), rigid.bodies.end(), [](const weft::RigidBodyDesc& b) {
    return std::any_of(b.shapes.begin(), b.shapes.end(),
                       [](const weft::RigidShapeDesc& s) { return s.kind != weft::RigidShapeDesc::Kind::Sphere; });
  });
}
std::string spheresOnly(const weft::SceneSpec& spec) {
  return "the scene '" + spec.name + "' has spheres only (a sphere's test is its own)";
}

const char* const kFixedRk45 = "this run takes fixed rk45 steps (--fixed-step or integration.adaptive false)";

/// An option given on the command line that this run would not read is refused, naming
/// the option and what it needs: `--rtol` with euler would otherwise run as if it were not
/// there, and the user would believe the tolerance was applied.
void refuseInapplicableOptions(const RunOptions& o, const weft::SceneSpec& spec) {
  const weft::IntegratorKind integrator = spec.simulation.integrator;
  const auto refuse = [](const char* option, const std::string& needs, const std::string& instead) {
    throw std::invalid_argument(std::string(option) + " applies to " + needs + ", and " + instead +
                                ": drop the option or change the run");
  };
  // Rigid bodies always run in double with their own solver: the particles' settings have
  // nothing to act on in a scene without particles.
  if (spec.bodies.empty()) {
    const std::string none =
        "the scene '" + spec.name + "' has none (its rigid bodies run in double with their own solver)";
    const char* particles = "particles (cloth and ropes)";
    if (o.integrator) refuse("--integrator", particles, none);
    if (o.precision) refuse("--precision", particles, none);
    if (o.drag) refuse("--drag", particles, none);
    if (o.strategy) refuse("--strategy", particles, none);
  }
  const std::string integrates = std::string("this run integrates with ") + weft::integratorName(integrator);
  for (const IntegratorSetting& s : integratorSettings(o, spec.simulation.integration, spec.givenKeys)) {
    if (!s.given) continue;
    if (spec.bodies.empty())
      refuse(s.option, "particles (cloth and ropes)",
             "the scene '" + spec.name + "' has none (its rigid bodies run in double with their own solver)");
    if (integrator != s.reader)
      refuse(s.option, std::string("--integrator ") + weft::integratorName(s.reader), integrates);
    if (s.errorControl && !spec.simulation.integration.adaptive) refuse(s.option, "rk45's error control", kFixedRk45);
  }
  const weft::RigidOptions& rigid = spec.simulation.rigid;
  const std::string noBodies = "the scene '" + spec.name + "' has no rigid bodies";
  if (o.narrowPhase && rigid.bodies.empty()) refuse("--narrow-phase", "scenes with rigid bodies", noBodies);
  if (o.timeOfImpact && rigid.bodies.empty()) refuse("--time-of-impact", "scenes with rigid bodies", noBodies);
  if (o.ofgFaces && rigid.bodies.empty()) refuse("--ofg-faces", "scenes with rigid bodies", noBodies);
  if (o.timeOfImpact && rigid.timeOfImpact == weft::RigidTimeOfImpact::Rollback && !rigid.continuous)
    throw std::invalid_argument(
        "--time-of-impact rollback finds each pair's time of impact along its motion, and the "
        "scene '" +
        spec.name + "' sets rigid_bodies.continuous false: drop one of them");
  const bool hulls = hasHulls(rigid);
  const std::string spheres = spheresOnly(spec);
  if (o.narrowPhase && !rigid.bodies.empty() && !hulls) refuse("--narrow-phase", "pairs of boxes and hulls", spheres);
  if (o.ofgFaces && !rigid.bodies.empty() && !hulls) refuse("--ofg-faces", "pairs of boxes and hulls", spheres);
  if (o.ofgFaces && rigid.narrowPhase.method != weft::NarrowPhaseMethod::Ofg)
    refuse("--ofg-faces", "the Opposing Face Geometry narrow phase (--narrow-phase ofg)",
           std::string("this run uses ") + weft::narrowPhaseMethodName(rigid.narrowPhase.method));
}

}  // namespace

/// Settings of the scene file that this run does not read (the command line's are refused
/// by sceneFor, since a scene file may carry settings for several integrators and be run
/// with --integrator): each is said on stderr and listed in the JSON summary.
std::vector<std::string> unusedSceneSettings(const RunOptions& o, const weft::SceneSpec& spec,
                                             const std::string& command) {
  std::vector<std::string> unused;
  const weft::SimulationOptions& sim = spec.simulation;
  const weft::IntegratorKind integrator = sim.integrator;
  const weft::IntegratorOptions& io = sim.integration;
  const weft::SimulationOptions defaultSim;
  // A setting counts as given when the file wrote its key (whatever the value) or, for a
  // spec without a file, when it differs from its default.
  const auto written = [&](const std::string& key) {
    // The key itself or any key below it ("effects" is given by "effects.drag").
    const auto it = spec.givenKeys.lower_bound(key);
    return it != spec.givenKeys.end() &&
           (*it == key || (it->starts_with(key) && (it->at(key.size()) == '.' || it->at(key.size()) == '[')));
  };
  const auto note = [&](bool set, const std::string& key, const std::string& needs, const std::string& instead) {
    if (set) unused.push_back(key + " applies to " + needs + ", and " + instead);
  };
  const auto noteKey = [&](bool nonDefault, const std::string& key, const std::string& needs,
                           const std::string& instead) { note(nonDefault || written(key), key, needs, instead); };
  const weft::RigidOptions& rigid = sim.rigid;
  const weft::RigidOptions defaultRigid;
  const std::vector<IntegratorSetting> settings = integratorSettings(o, io, spec.givenKeys);
  if (spec.bodies.empty()) {
    // Rigid bodies only: they run in double with their own solver, and nothing of the
    // particles' is read.
    const std::string none = "the scene '" + spec.name + "' has none";
    const char* particles = "particles (cloth and ropes)";
    noteKey(integrator != defaultSim.integrator, "integrator", particles, none);
    noteKey(spec.precision != weft::Precision::Double, "precision", particles, none + " (rigid bodies run in double)");
    noteKey(sim.forceStrategy != defaultSim.forceStrategy, "force_strategy", particles, none);
    noteKey(sim.effects.drag != 0 || sim.effects.wind.enabled || sim.effects.repulsion.enabled(), "effects", particles,
            none);
    noteKey(sim.collision.any(), "collision", particles,
            none + " (rigid bodies meet static rigid bodies, not collision obstacles)");
    note(std::any_of(settings.begin(), settings.end(), [](const IntegratorSetting& s) { return s.set; }), "integration",
         particles, none);
    note(rigid.particleContacts != defaultRigid.particleContacts ||
             rigid.particleSupports != defaultRigid.particleSupports ||
             rigid.particleThickness != defaultRigid.particleThickness || written("rigid_bodies.particle_contacts") ||
             written("rigid_bodies.particle_supports") || written("rigid_bodies.particle_thickness"),
         "rigid_bodies.particle_contacts, particle_supports and particle_thickness", particles, none);
  } else {
    const std::string integrates = std::string("this run integrates with ") + weft::integratorName(integrator);
    for (const IntegratorSetting& s : settings) {
      if (integrator != s.reader)
        note(s.set, s.key, weft::integratorName(s.reader), integrates);
      else if (s.errorControl && !io.adaptive)
        note(s.set, s.key, "rk45's error control", kFixedRk45);
    }
  }
  if (!rigid.bodies.empty()) {
    if (rigid.timeOfImpact == weft::RigidTimeOfImpact::Speculative) {
      const char* rollback = "time_of_impact \"rollback\"";
      const char* speculative = "this run's is speculative";
      noteKey(rigid.rollbackPenetration != defaultRigid.rollbackPenetration, "rigid_bodies.rollback_penetration",
              rollback, speculative);
      if (!rigid.redoDeepSteps)  // (redone steps are halved at most max_halvings times too)
        noteKey(rigid.maxHalvings != defaultRigid.maxHalvings, "rigid_bodies.max_halvings",
                "time_of_impact \"rollback\" or redo_deep_steps", "this run has neither");
    } else {
      noteKey(rigid.redoDeepSteps != defaultRigid.redoDeepSteps, "rigid_bodies.redo_deep_steps",
              "time_of_impact \"speculative\"", "this run's is rollback");
    }
    const char* pairs = "pairs of boxes and hulls";
    const std::string spheres = spheresOnly(spec);
    if (!hasHulls(rigid)) {
      noteKey(rigid.narrowPhase.method != weft::NarrowPhaseOptions{}.method, "rigid_bodies.narrow_phase", pairs,
              spheres);
      noteKey(rigid.narrowPhase.ofgFaces != weft::NarrowPhaseOptions{}.ofgFaces, "rigid_bodies.ofg_faces", pairs,
              spheres);
    } else if (rigid.narrowPhase.method != weft::NarrowPhaseMethod::Ofg) {
      noteKey(rigid.narrowPhase.ofgFaces != weft::NarrowPhaseOptions{}.ofgFaces, "rigid_bodies.ofg_faces",
              "narrow_phase \"ofg\"",
              std::string("this run uses ") + weft::narrowPhaseMethodName(rigid.narrowPhase.method));
    }
  }
  const bool cloth = std::any_of(spec.bodies.begin(), spec.bodies.end(),
                                 [](const weft::BodySpec& b) { return b.kind != weft::BodyKind::Rope; });
  if (!cloth)
    noteKey(spec.simulation.selfCollision.enabled, "self_collision", "cloth (its triangles)",
            "the scene '" + spec.name + "' has none");
  if (!spec.bodies.empty()) {
    // Wind gusts: their shape with no gusts to shape.
    const weft::WindEffect& wind = sim.effects.wind;
    if (wind.enabled && wind.gustStrength == 0)
      for (const char* key : {"gust_scale", "gust_period", "gust_modes", "seed"})
        noteKey(false, std::string("effects.wind.") + key, "gusts (effects.wind.gust_strength > 0)",
                "this run's wind is steady");
    // The mesh obstacles' feature edges and corners: continuous detection against meshes.
    const weft::CollisionOptions& c = sim.collision;
    const weft::CollisionOptions dc;
    const bool meshes = !spec.meshObstacles.empty() || !c.meshes.empty();
    const char* features = "continuous detection against mesh obstacles";
    const std::string why =
        !meshes ? "the scene '" + spec.name + "' has no mesh obstacle" : std::string("collision.continuous is false");
    if (!meshes || !c.continuous) {
      noteKey(c.edges != dc.edges, "collision.edges", features, why);
      noteKey(c.corners != dc.corners, "collision.corners", features, why);
      noteKey(c.featureAngle != dc.featureAngle, "collision.feature_angle", features, why);
    }
    // Materials of spring families a body's size leaves without a spring (a family its
    // flags leave out is refused by the reader).
    for (size_t k = 0; k < spec.bodies.size(); ++k) {
      const weft::BodySpec& b = spec.bodies[k];
      const std::string f = "bodies[" + std::to_string(k) + "].materials.";
      if (b.kind == weft::BodyKind::Rope && b.rope.particleCount < 3)
        noteKey(false, f + "bend", "springs between every second particle",
                "this rope has " + std::to_string(b.rope.particleCount) + " particles");
      if (b.kind == weft::BodyKind::ClothGrid && b.grid.width < 3 && b.grid.height < 3)
        noteKey(false, f + "bend", "springs between every second particle of a row or column",
                "this grid is " + std::to_string(b.grid.width) + " x " + std::to_string(b.grid.height));
      if (b.kind == weft::BodyKind::ClothGrid && (b.grid.width < 2 || b.grid.height < 2))
        noteKey(false, f + "shear", "the diagonals of the grid's cells",
                "this grid is " + std::to_string(b.grid.width) + " x " + std::to_string(b.grid.height));
    }
  }
  if (!spec.simulation.stability.enabled)
    noteKey(spec.simulation.stability.maxStretch != weft::StabilityOptions{}.maxStretch, "stability.max_stretch",
            "the stability check", "stability.enabled is false");
  const weft::OutputSpec defaultOutput;
  if (command != "run") {
    // (render draws into --out; view draws on the screen, for as long as its window is open)
    const std::string other = "weft " + command + (command == "render" ? " draws into --out" : " draws on screen");
    noteKey(!spec.output.directory.empty(), "output.directory", "weft run's frames", other);
    noteKey(spec.output.format != defaultOutput.format, "output.format", "weft run's frames", other);
    noteKey(spec.output.every != defaultOutput.every, "output.every", "weft run's frames", other);
  } else if (spec.output.directory.empty()) {
    noteKey(spec.output.format != defaultOutput.format, "output.format", "frames (output.directory or --out)",
            "this run writes none");
    // (A checkpoint's period is --every's only: the file's output.every sets the frames'.)
    if (!o.every)
      noteKey(spec.output.every != defaultOutput.every, "output.every", "frames (output.directory or --out)",
              "this run writes none");
  }
  return unused;
}

weft::SceneSpec sceneFor(const RunOptions& o) {
  // A built-in scene name, else a scene file (anything that exists or ends in .json);
  // anything else is an unknown scene name (builtinSceneSpec lists the known ones).
  bool builtin = false;
  for (const std::string& n : weft::builtinSceneNames()) builtin = builtin || n == o.scene;
  weft::SceneSpec spec;
  if (!builtin && (o.scene.ends_with(".json") || std::filesystem::exists(o.scene))) {
    if (o.size > 0) throw std::invalid_argument("--size applies to built-in scenes only, not to '" + o.scene + "'");
    spec = weft::readSceneFile(o.scene);
  } else {
    spec = weft::builtinSceneSpec(o.scene, static_cast<weft::Index>(o.size));
  }
  weft::SimulationOptions& sim = spec.simulation;
  if (o.steps) {
    spec.steps = *o.steps;
    spec.duration = 0;
  }
  if (o.dt) {
    const std::int64_t steps = weft::sceneStepCount(spec);
    sim.dt = *o.dt;
    if (spec.steps <= 0) spec.steps = steps;  // a duration-based file keeps its step count
  }
  if (o.integrator) sim.integrator = weft::parseIntegrator(*o.integrator);
  if (o.relativeTolerance) sim.integration.relativeTolerance = *o.relativeTolerance;
  if (o.absoluteTolerance) sim.integration.absoluteTolerance = *o.absoluteTolerance;
  if (o.linearTolerance) sim.integration.linearTolerance = *o.linearTolerance;
  if (o.maxLinearIterations) sim.integration.maxLinearIterations = static_cast<weft::Index>(*o.maxLinearIterations);
  if (o.preconditioner) sim.integration.preconditioner = weft::parsePreconditioner(*o.preconditioner);
  if (o.projectiveIterations) sim.integration.projectiveIterations = *o.projectiveIterations;
  if (o.fixedStep) sim.integration.adaptive = false;
  if (o.drag) sim.effects.drag = *o.drag;
  if (o.precision) spec.precision = *o.precision == "float" ? weft::Precision::Float : weft::Precision::Double;
  if (o.threads) sim.threads = *o.threads;
  if (o.strategy) sim.forceStrategy = weft::parseForceStrategy(*o.strategy);
  if (o.narrowPhase) {
    sim.rigid.narrowPhase.method = *o.narrowPhase == "exact" ? weft::NarrowPhaseMethod::Exact
                                   : *o.narrowPhase == "ofg" ? weft::NarrowPhaseMethod::Ofg
                                                             : weft::NarrowPhaseMethod::Witness;
  }
  if (o.ofgFaces) sim.rigid.narrowPhase.ofgFaces = *o.ofgFaces;
  if (o.timeOfImpact)
    sim.rigid.timeOfImpact =
        *o.timeOfImpact == "rollback" ? weft::RigidTimeOfImpact::Rollback : weft::RigidTimeOfImpact::Speculative;
  if (o.out) spec.output.directory = *o.out;
  if (o.format) spec.output.format = *o.format;
  if (o.every) spec.output.every = *o.every;
  refuseInapplicableOptions(o, spec);
  return spec;
}

namespace {

std::vector<std::string> effectNames(const weft::SimulationOptions& o) {
  std::vector<std::string> names;
  if (o.effects.drag != 0) names.emplace_back("drag");
  if (o.effects.wind.enabled) names.emplace_back("wind");
  if (o.effects.repulsion.enabled()) names.emplace_back("repulsion");
  if (!o.kinematicPins.empty()) names.emplace_back("kinematic_pins");
  if (o.collision.any()) names.emplace_back("collision");
  if (o.selfCollision.enabled) names.emplace_back("self_collision");
  if (!o.rigid.bodies.empty()) names.emplace_back("rigid_bodies");
  return names;
}

const char* signalName(int signal) { return signal == SIGINT ? "SIGINT" : signal == SIGTERM ? "SIGTERM" : "a signal"; }

// Ctrl-C (SIGINT) and SIGTERM during the steps: the handler only records the signal; the
// loop finishes the step it is in, then writes frames and the checkpoint and reports. A
// second signal while that step is still running stops the process at once (the signal's
// default action): a step that does not end must not hold the run hostage. During the last
// writes a second signal is ignored, so that they are not cut short.
volatile std::sig_atomic_t gSignal = 0;
volatile std::sig_atomic_t gStepping = 0;  // inside Simulation::step

extern "C" void onSignal(int signal) {
  if (gSignal != 0 && gStepping != 0) {  // (signal and raise are async-signal-safe)
    std::signal(signal, SIG_DFL);
    std::raise(signal);
    return;
  }
  gSignal = signal;
}

/// Installs the handler for the lifetime of the object, and puts the previous ones back.
class SignalScope {
 public:
  SignalScope() {
    struct sigaction action {};
    action.sa_handler = onSignal;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &previousInt_);
    sigaction(SIGTERM, &action, &previousTerm_);
  }
  ~SignalScope() {
    sigaction(SIGINT, &previousInt_, nullptr);
    sigaction(SIGTERM, &previousTerm_, nullptr);
  }
  SignalScope(const SignalScope&) = delete;
  SignalScope& operator=(const SignalScope&) = delete;

 private:
  struct sigaction previousInt_ {};
  struct sigaction previousTerm_ {};
};

template <class S>
int run(const RunOptions& o, const weft::SceneSpec& spec) {
  const std::vector<std::string> unused = unusedSceneSettings(o, spec);
  for (const std::string& u : unused) std::cerr << "weft run: note: " << u << " (not used)\n";
  // Memory asked for before it is taken: what this process holds now plus what the scene
  // will, against what the machine has (or --max-memory).
  // Besides the scene's arrays, the first step's runtime (TBB's arena and threads, the
  // allocator's arenas: about 1.5 MB resident) and, when assimp reads a mesh (formats other
  // than PLY, STL and OBJ), its importers (about 17 MB of its code and tables become
  // resident), both measured on the built-in scenes (rope, and drape-mesh when assimp read
  // its OBJ torus).
  const weft::MemoryEstimate need = weft::estimateSceneMemory(spec);
  constexpr double kRuntimeBytes = 1.5 * 1024 * 1024, kMeshImportBytes = 17.0 * 1024 * 1024;
  const double estimate = residentBytes() + kRuntimeBytes + (need.readsMeshes ? kMeshImportBytes : 0) + need.bytes;
  // With self-collision, what the candidate and contact lists take once the cloth has
  // folded on itself (the same as `estimate` without).
  const double foldedEstimate = estimate + (need.foldedBytes - need.bytes);
  const double limit = o.maxMemory ? *o.maxMemory * 1024 * 1024 : availableBytes();
  const auto limitText = [&] {
    return (o.maxMemory ? "--max-memory allows " : "this machine has ") + gib(limit) +
           (o.maxMemory ? "" : " available (--max-memory sets the limit)");
  };
  if (estimate > limit) {
    std::cerr << "weft run: " << spec.name << " needs about " << gib(estimate) << " (" << need.particles
              << " particles, " << need.springs << " springs, " << need.triangles << " triangles, "
              << (spec.precision == weft::Precision::Float ? "float" : "double") << ", "
              << weft::integratorName(spec.simulation.integrator) << "); " << limitText() << "\n";
    return 2;
  }
  if (foldedEstimate > limit)  // it starts, and may run out once its cloth folds
    std::cerr << "weft run: warning: " << spec.name << " needs about " << gib(estimate) << " to start and up to "
              << gib(foldedEstimate) << " once its cloth folds on itself (self-collision's candidate lists, "
              << need.triangles << " triangles); " << limitText() << "\n";
  weft::AssembledScene<S> assembled = weft::assembleScene<S>(spec);
  weft::SimulationOptions options = assembled.options;
  options.profileEffects = true;  // two clock reads per block and effect; none without effects
  const std::vector<std::string> effects = effectNames(options);
  weft::Simulation<S> sim(std::move(assembled.built), options);
  const std::int64_t steps = weft::sceneStepCount(spec);
  const weft::OutputSpec& output = spec.output;
  const std::string precision = spec.precision == weft::Precision::Float ? "float" : "double";

  // A resumed run continues from the checkpoint's step up to `steps` in all (the checkpoint
  // must come from the same scene and options: load refuses another model, precision or
  // integrator).
  if (o.resume) {
    if (!output.directory.empty() && (output.format == "cache" || output.format == "gltf"))
      throw std::runtime_error(
          std::string("--resume cannot append to ") +
          (output.format == "cache" ? "a frame cache (--format cache)" : "a glTF file (--format gltf)") +
          ": resume with obj or ply frames, or without --out");
    const double askedDt = sim.timeStep();
    sim.load(*o.resume);
    // The checkpoint carries its time step; a run that asks for another would count its
    // steps for one and take them at the other.
    if (sim.timeStep() != askedDt)
      throw std::runtime_error("--resume: the checkpoint '" + *o.resume +
                               "' was written at dt = " + shortest(sim.timeStep()) +
                               " s, this run asks for dt = " + shortest(askedDt) + " s (the scene's dt or --dt)");
    if (sim.stepCount() > steps)
      throw std::runtime_error("--resume: the checkpoint '" + *o.resume + "' is at step " +
                               std::to_string(sim.stepCount()) + ", beyond the " + std::to_string(steps) +
                               " steps asked for (--steps)");
  }
  // A checkpoint file that exists holds a run's work: only the run that continues it
  // (--resume with the same file) writes over it.
  if (o.checkpoint) {
    std::error_code error;
    const bool exists = std::filesystem::exists(*o.checkpoint, error);
    const bool continued = o.resume && exists && std::filesystem::equivalent(*o.resume, *o.checkpoint, error);
    if (exists && !continued)
      throw std::invalid_argument("--checkpoint " + *o.checkpoint +
                                  ": the file exists, and a checkpoint holds a run's work: continue that run with "
                                  "--resume " +
                                  *o.checkpoint + ", or remove the file first");
  }
  std::optional<FrameSink<S>> frames;  // (its checks first: a refused run leaves no checkpoint behind)
  if (!output.directory.empty()) {
    frames.emplace(output, sim.model(), spec.name, steps);
    if (o.resume) checkResumedFrames(output, sim.stepCount());
  }
  const std::int64_t intersectingAtStart = sim.startIntersectionCount();
  // The warnings known before the first step, said now rather than after a long run (the
  // end says only the new ones): a particle that starts inside an obstacle, deeper than the
  // thickness (the response pushes it out in one step and can tear the cloth around it); a
  // cloth that starts intersecting itself (self-collision keeps cloth from passing through
  // itself and cannot undo an intersection it starts with).
  const double penetrationAtStart = sim.contactSolver() ? sim.contactReport().maxPenetration : 0.0;
  const std::vector<std::string> warnedAtStart = sim.warnings();
  for (const std::string& w : warnedAtStart) std::cerr << "weft run: warning: " << w << "\n";
  // A first checkpoint before any step: a path that cannot be written fails now, not after
  // the run's work.
  if (o.checkpoint) sim.save(*o.checkpoint);
  if (frames) {
    if (output.format == "obj" || output.format == "ply") writeFramesRecord(output, spec.name);
    if (o.resume)
      frames->resumeAt(sim.stepCount() / output.every + 1);
    else
      frames->write(sim.state());
  }
  // Frames and checkpoints after every `every` steps (counted from the run's start, also
  // when resumed); otherwise chunks of about 1% for the progress bar. Wall time counts the
  // stepping only.
  const bool periodic = frames || (o.checkpoint && o.every);
  const std::int64_t every = periodic ? output.every : std::max<std::int64_t>(1, steps / 100);
  Progress progress(o.progress && !o.json, steps);
  weft::StepStatus status = sim.status();
  double wall = 0;
  int interrupted = 0;
  std::string unwritable;  // why the frame of the state the run stopped at could not be written
  {
    SignalScope signals;
    gSignal = 0;
    while (sim.stepCount() < steps && status.ok() && gSignal == 0) {
      const std::int64_t boundary = std::min(steps, (sim.stepCount() / every + 1) * every);
      const auto start = std::chrono::steady_clock::now();
      while (sim.stepCount() < boundary && gSignal == 0) {
        gStepping = 1;
        status = sim.step();
        gStepping = 0;
        if (!status.ok()) break;
      }
      wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (status.ok() && periodic && sim.stepCount() % every == 0) {
        // With the stability check off nothing stops a state that overflowed: the run stops
        // at the first frame or checkpoint that would hold it (neither a frame format nor a
        // checkpoint holds a NaN that means anything), and ends not_finite.
        if (!sim.stateFinite()) break;
        if (frames) {
          unwritable = frames->write(sim.state());
          if (!unwritable.empty()) break;
        }
        if (o.checkpoint && o.every) sim.save(*o.checkpoint);
      }
      progress.update(sim.stepCount());
    }
    interrupted = gSignal;
    progress.finish();
    // Still under the handler, so that a second signal cannot cut these writes short.
    if (frames) frames->close();
    // The last checkpoint: at the end, or where the signal stopped the run (not after a
    // failed step: resuming it would only fail again).
    if (o.checkpoint && status.ok() && sim.stateFinite() && unwritable.empty()) sim.save(*o.checkpoint);
  }

  const weft::Model<S>& model = sim.model();
  const weft::State<S>& state = sim.state();
  const std::int64_t done = sim.stepCount();
  // The exact intersection check first (it builds a tree of its own, about 14 bytes a
  // triangle), so that the peak below is the whole process's: what `/usr/bin/time` would
  // show, and what the memory estimate is for.
  const std::int64_t intersecting = sim.selfIntersectionCount();
  const double peakMb = peakResidentMegabytes();
  const double stepsPerSecond = wall > 0 ? static_cast<double>(done) / wall : 0;
  const double springEvals = static_cast<double>(sim.forceEvaluationCount()) * model.springCount();
  const double springEvalsPerSecond = wall > 0 ? springEvals / wall : 0;
  const weft::RigidWorld* rigid = sim.rigidWorld();
  // With the stability check off (stability.enabled = false) nothing stops a run whose state
  // became NaN or infinite: such a run does not end "ok".
  const bool finite = sim.stateFinite();
  const std::string notFinite =
      notFiniteMessage(sim.stepCount()) +
      (periodic ? std::string("; frames and checkpoints up to the last finite state") : std::string());
  // What the run did that its status does not stop it for, but that its figures should not
  // be read without (to standard error, and in the JSON as `warnings`): Simulation::warnings.
  const std::vector<std::string> warnings = sim.warnings();
  // With obstacles: particles that ended beyond a thin obstacle or inside one.
  weft::ContactReport contacts = sim.contactReport();
  contacts.tunnelled = sim.tunnelledCount();
  // A step that failed in a run that started with a particle inside an obstacle: the start,
  // not the time step, is the likelier cause (the response pushes such a particle out in
  // one step, which can overstretch the springs around it).
  std::ostringstream failureText;
  if (!status.ok()) {
    failureText << status.message();
    if (sim.startPenetration() > 0)
      failureText << "; but the run started with a particle " << sim.startPenetration()
                  << " m inside an obstacle (the warning above), the likelier cause: move the body or the obstacle "
                     "first";
  }
  const std::string failure = failureText.str();
  for (const std::string& w : warnings)
    if (std::find(warnedAtStart.begin(), warnedAtStart.end(), w) == warnedAtStart.end())
      std::cerr << "weft run: warning: " << w << "\n";
  const std::string stoppedUnwritable = "stopped after step " + std::to_string(sim.stepCount()) +
                                        ": its frame cannot be written (" + unwritable +
                                        "); the frames before it are written";
  // With rigid bodies the hash covers them too (equal for any thread count, like the particles').
  const std::string hash =
      hex(rigid ? weft::stateHash(state) ^ weft::rigidStateHash(rigid->state()) : weft::stateHash(state));
  const auto byClass = model.springCountByClass();
  const weft::Energy e = weft::energy(model, state, options.gravity);
  const weft::Stretch stretch = weft::stretch(model, state);  // the structural springs at the end
  const double lowest = model.particleCount() > 0 ? static_cast<double>(state.x.col(1).minCoeff()) : 0.0;
  const double stableDt = weft::estimateStableTimeStep(model, options.integrator);
  const weft::SceneEffectTimes times = sim.effectTimes();
  const auto effectSeconds = [&](const std::string& name) {
    if (name == "drag") return times.forces.drag;
    if (name == "wind") return times.forces.wind;
    if (name == "repulsion") return times.forces.repulsion;
    if (name == "collision") return times.collision;
    if (name == "self_collision") return times.selfCollision;
    if (name == "rigid_bodies") return times.rigidBodies;
    return times.kinematicPins;
  };

  if (o.json) {
    nlohmann::ordered_json j;
    j["scene"] = spec.name;
    j["bodies"] = spec.bodies.size();
    j["particles"] = model.particleCount();
    j["springs"] = model.springCount();
    j["springs_by_class"] = {{"structural", byClass[0]}, {"shear", byClass[1]}, {"bend", byClass[2]}};
    j["triangles"] = model.triangleCount();
    j["integrator"] = weft::integratorName(options.integrator);
    j["precision"] = precision;
    j["threads"] = sim.threadCount();
    j["force_strategy"] = weft::forceStrategyName(sim.forceStrategy());
    j["steps"] = done;
    j["steps_requested"] = steps;
    j["dt"] = options.dt;
    j["simulated_seconds"] = state.time;
    j["wall_seconds"] = wall;
    j["steps_per_second"] = stepsPerSecond;
    j["spring_evals_per_second"] = springEvalsPerSecond;
    j["force_evaluations"] = sim.forceEvaluationCount();
    j["work_per_step"] = workJson(sim.totalWork(), done);
    j["work_total"] = workJson(sim.totalWork(), 1);
    j["effects"] = effects;
    j["unused_settings"] = unused;
    j["warnings"] = warnings;
    // CPU seconds (summed over threads) spent in each effect the scene lists.
    nlohmann::ordered_json perEffect = nlohmann::ordered_json::object();
    for (const std::string& name : effects) perEffect[name] = effectSeconds(name);
    j["effect_cpu_seconds"] = perEffect;
    if (std::isfinite(stableDt))
      j["stable_dt_estimate"] = stableDt;
    else
      j["stable_dt_estimate"] = nullptr;  // no limit (implicit Euler, projective, no springs or nothing free)
    j["status"] = interrupted ? "interrupted" : weft::stepCodeName(status.code);
    if (interrupted)
      j["status_message"] = std::string("stopped by ") + signalName(interrupted) + " after step " +
                            std::to_string(done) + " of " + std::to_string(steps);
    if (!status.ok()) j["status_message"] = failure;
    if (status.ok() && !interrupted && !finite) {
      j["status"] = "not_finite";
      j["status_message"] = notFinite;
    }
    if (status.ok() && !interrupted && finite && !unwritable.empty()) {
      j["status"] = "frame_unwritable";
      j["status_message"] = stoppedUnwritable;
    }
    j["state_finite"] = finite;
    if (o.checkpoint) j["checkpoint"] = *o.checkpoint;
    if (o.resume) j["resumed_from"] = *o.resume;
    j["state_hash"] = hash;
    j["energy"] = {{"kinetic", e.kinetic}, {"spring", e.spring}, {"gravity", e.gravity}};
    j["lowest_y"] = lowest;
    // |x_a - x_b| / rest - 1 over the structural springs at the end (null without any).
    if (stretch.springs > 0) {
      j["max_stretch"] = stretch.max;
      j["mean_stretch"] = stretch.mean;
    } else {
      j["max_stretch"] = nullptr;
      j["mean_stretch"] = nullptr;
    }
    if (sim.contactSolver()) {
      // At the end of the run: particles in contact, the deepest penetration (m); over the
      // run: chunks rolled back, and particles that ended beyond a thin obstacle or inside one.
      const weft::ContactReport& report = contacts;
      j["contacts"] = report.contacts;
      j["max_penetration"] = report.maxPenetration;
      j["rollbacks"] = sim.totalCollision().rollbacks;
      j["edge_contacts"] = sim.totalCollision().edgeContacts;
      j["corner_contacts"] = sim.totalCollision().cornerContacts;
      j["tunnelled"] = report.tunnelled;
      j["max_penetration_at_start"] = penetrationAtStart;
    }
    // Cloth against cloth: pairs of triangles (sharing no particle) that intersect at the end
    // (the exact check, in every scene), and with self-collision what its pass did over the run.
    j["intersecting_pairs"] = intersecting;
    if (const weft::SelfCollisionOptions& self = sim.options().selfCollision; self.enabled) {
      const weft::SelfCollisionStats& t = sim.totalSelfCollision();
      j["intersecting_pairs_at_start"] = intersectingAtStart;
      j["self_contacts"] = t.contacts;
      j["self_collision"] = {{"thickness", self.thickness},
                             {"cull_flat_regions", self.cullFlatRegions},
                             {"max_candidates_per_triangle", self.maxCandidatesPerTriangle},
                             {"passes", t.passes},
                             {"gatherings", t.rebuilds},
                             {"candidates", t.candidates},
                             {"tests", t.tests},
                             {"vertex_triangle_contacts", t.vertexTriangle},
                             {"edge_edge_contacts", t.contacts - t.vertexTriangle},
                             {"failsafe_chunks", t.failsafeChunks},
                             {"frozen", t.frozen},
                             {"unresolved", t.unresolved}};
    } else {
      j["self_contacts"] = 0;
    }
    if (rigid) {
      // Bodies, their contacts at the last step, the deepest penetration then (m), the
      // narrow phase and how often its witness cache answered alone over the run.
      const weft::RigidStats& last = rigid->lastStats();
      const weft::RigidStats& total = rigid->totalStats();
      j["rigid_bodies"] = rigid->model().bodyCount();
      j["body_contacts"] = last.contacts;
      j["body_touching_pairs"] = last.touchingPairs;
      j["particle_body_contacts"] = sim.lastParticleBodyContacts().contacts;  // particles touching bodies, last step
      // Moving bodies' centres through a cloth triangle over the run (the cloth did not hold them)
      j["bodies_through_cloth"] = sim.totalParticleBodyContacts().crossings;
      j["support_contacts"] = last.supportContacts;  // held particles carrying bodies, last step
      j["body_max_penetration"] = last.maxPenetration;
      j["body_max_penetration_run"] = total.maxPenetration;  // deepest over the run
      // ... as a share of the thinner piece's inner radius (1: its middle reached the other's surface)
      j["body_deepest_share_run"] = total.deepestShare;  // above 0.5: a warning
      j["body_energy"] = rigid->energy();
      j["narrow_phase"] = weft::narrowPhaseMethodName(rigid->options().narrowPhase.method);
      j["time_of_impact"] = weft::rigidTimeOfImpactName(rigid->options().timeOfImpact);
      j["body_chunks"] = total.chunks;             // over the run (one per step but under rollback and in redone steps)
      j["body_rollbacks"] = total.rollbacks;       // chunks cut or taken back, over the run
      j["body_redone_steps"] = total.redoneSteps;  // speculative steps taken again in chunks (too deep)
      j["narrow_queries"] = total.narrowQueries;
      j["witness_hit_rate"] = total.narrowQueries > 0
                                  ? static_cast<double>(total.witnessHits) / static_cast<double>(total.narrowQueries)
                                  : 0.0;
    }
    if (!assembled.meshReports.empty()) j["meshes"] = assembled.meshReports;
    if (frames) {
      j["frames_written"] = frames->written();
      j["output"] = output.directory;
    }
    j["peak_rss_mb"] = peakMb;
    j["memory_estimate_mb"] = estimate / (1024.0 * 1024.0);  // asked before assembling (cloth meshes not counted)
    // ... with self-collision, for a cloth folded on itself (its candidate lists full)
    j["memory_estimate_folded_mb"] = foldedEstimate / (1024.0 * 1024.0);
    std::cout << j.dump() << std::endl;
  } else {
    std::ostringstream out;
    out.precision(6);
    out << "weft run " << spec.name << "\n"
        << "  model        " << model.particleCount() << " particles (" << model.pinnedCount() << " pinned), "
        << model.springCount() << " springs (structural " << byClass[0] << ", shear " << byClass[1] << ", bend "
        << byClass[2] << "), " << model.triangleCount() << " triangles, " << spec.bodies.size()
        << (spec.bodies.size() == 1 ? " body\n" : " bodies\n");
    for (const std::string& report : assembled.meshReports) out << "  mesh         " << report << "\n";
    out << "  integrator   " << weft::integratorName(options.integrator) << ", " << precision << ", dt " << options.dt
        << " s, " << sim.threadCount() << " thread(s)"
        << (o.threads && *o.threads > sim.threadCount()
                ? " (" + std::to_string(*o.threads) + " asked for: the most this machine runs)"
                : std::string())
        << ", forces: " << weft::forceStrategyName(sim.forceStrategy()) << "\n"
        << "  stable dt    " << (std::isfinite(stableDt) ? shortest(stableDt) + " s" : std::string("unlimited"))
        << " estimated for this integrator (omega_max <= " << weft::maxAngularFrequency(model) << " rad/s)\n";
    out << "  effects      springs, gravity";
    for (const std::string& name : effects) out << ", " << name << " (" << effectSeconds(name) << " CPU s)";
    out << "\n";
    if (rigid) {
      const weft::RigidStats& total = rigid->totalStats();
      out << "  rigid bodies " << rigid->model().bodyCount()
          << (rigid->model().bodyCount() == 1 ? " body, " : " bodies, ") << rigid->lastStats().contacts
          << " contacts at the end (deepest " << rigid->lastStats().maxPenetration << " m), "
          << sim.lastParticleBodyContacts().contacts << " particle contacts, " << rigid->lastStats().supportContacts
          << " support contacts, narrow phase " << weft::narrowPhaseMethodName(rigid->options().narrowPhase.method)
          << ", time of impact " << weft::rigidTimeOfImpactName(rigid->options().timeOfImpact) << " (" << total.chunks
          << " chunks, " << total.rollbacks << " cut or taken back, " << total.redoneSteps
          << (total.redoneSteps == 1 ? " step" : " steps") << " taken again in halves)"
          << ", witness hit rate "
          << (total.narrowQueries > 0
                  ? static_cast<double>(total.witnessHits) / static_cast<double>(total.narrowQueries)
                  : 0.0)
          << ", energy " << rigid->energy() << " J\n";
    }
    if (sim.contactSolver()) {
      const weft::ContactReport& report = contacts;
      out << "  obstacles    " << report.contacts << " particles in contact at the end (deepest "
          << report.maxPenetration << " m), " << sim.totalCollision().rollbacks << " rollbacks, "
          << sim.totalCollision().edgeContacts << " edge contacts, " << sim.totalCollision().cornerContacts
          << " corner contacts, " << report.tunnelled << " tunnelled\n";
    }
    if (model.triangleCount() > 1) {
      out << "  cloth        " << intersecting << " pairs of triangles intersecting at the end";
      if (intersectingAtStart > 0) out << " (" << intersectingAtStart << " at the start)";
      if (sim.options().selfCollision.enabled) {
        const weft::SelfCollisionStats& t = sim.totalSelfCollision();
        out << "; self-collision: " << t.contacts << " contacts (" << t.vertexTriangle << " vertex-triangle), "
            << t.failsafeChunks << " chunks needed the failsafe (" << t.frozen << " vertices stopped, " << t.unresolved
            << " unresolved)";
      }
      out << "\n";
    }
    out << "  work/step    " << workLine(sim.totalWork(), done) << "\n"
        << "  steps        " << done << " of " << steps << " (" << state.time << " s simulated)\n"
        << "  wall time    " << wall << " s: " << stepsPerSecond << " steps/s, " << springEvalsPerSecond / 1e6
        << " M spring evaluations/s\n"
        << "  energy       kinetic " << e.kinetic << " J, spring " << e.spring << " J, gravity " << e.gravity
        << " J; lowest point y = " << lowest << " m\n";
    if (stretch.springs > 0)
      out << "  stretch      max " << stretch.max << ", mean " << stretch.mean << " over the " << stretch.springs
          << " structural springs at the end (length / rest length - 1)\n";
    out << "  status       "
        << (interrupted ? std::string("interrupted by ") + signalName(interrupted) + " after step " +
                              std::to_string(done) + " of " + std::to_string(steps)
            : !status.ok()        ? failure
            : !finite             ? notFinite
            : !unwritable.empty() ? stoppedUnwritable
            : !warnings.empty()   ? "ok, with " + std::to_string(warnings.size()) +
                                      (warnings.size() == 1 ? " warning" : " warnings") + " (on standard error)"
                                : std::string("ok"))
        << "\n"
        << "  state hash   " << hash << "\n"
        << "  peak memory  " << peakMb << " MiB resident (" << estimate / (1024.0 * 1024.0)
        << " MiB estimated before assembling"
        << (foldedEstimate > estimate ? ", up to " + gib(foldedEstimate) + " once the cloth folds on itself"
                                      : std::string())
        << ")\n";
    if (o.resume) out << "  resumed from " << *o.resume << "\n";
    if (o.checkpoint) out << "  checkpoint   " << *o.checkpoint << "\n";
    if (frames)
      out << "  frames       " << frames->written() << " (" << output.format << ", every " << output.every
          << " steps) in " << output.directory
          << (rigid ? " (the particles; the rigid bodies are not in the frames: weft render draws them)" : "") << "\n";
    std::cout << out.str();
  }
  if (interrupted) return 128 + interrupted;  // the shell's convention: 130 for SIGINT, 143 for SIGTERM
  return status.ok() && finite && unwritable.empty() ? 0 : 3;
}

}  // namespace

int runScene(const RunOptions& options) {
  const weft::SceneSpec spec = sceneFor(options);
  return spec.precision == weft::Precision::Float ? run<float>(options, spec) : run<double>(options, spec);
}

}  // namespace weftcli
