// The `weft` command line. Parsing is CLI11's (Debian libcli11-dev); every bad option
// exits non-zero with a message naming the option and the value.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "render_command.hpp"
#include "run_command.hpp"
#include "soak_command.hpp"
#include "strip_command.hpp"
#include "study_command.hpp"
#include "view_command.hpp"
#include "weft/integrate/integrator.hpp"
#include "weft/io/scene.hpp"

namespace {
// CLI::PositiveNumber lets "nan" through: a time step or a tolerance must be a finite
// number (> 0, or >= 0 when zero is allowed).
CLI::Validator finiteNumber(bool allowZero) {
  return CLI::Validator(
      [allowZero](std::string& text) -> std::string {
        // (strtod, not stod: stod throws for a number it can read but not hold, and the
        // message must say which of the two it is.)
        const char* begin = text.c_str();
        char* end = nullptr;
        errno = 0;
        const double value = std::strtod(begin, &end);
        if (text.empty() || end != begin + text.size() || std::isspace(static_cast<unsigned char>(text[0])))
          return "'" + text + "' is not a number";
        if (errno == ERANGE && value == 0) return "'" + text + "' is too small for a double and would be read as 0";
        if (errno == ERANGE && std::isinf(value)) return "'" + text + "' is too large for a double";
        if (!(std::isfinite(value) && (allowZero ? value >= 0 : value > 0)))
          return std::string("must be a finite number ") + (allowZero ? ">= 0" : "> 0") + ", got " + text;
        return {};
      },
      allowZero ? "FINITE >= 0" : "FINITE > 0");
}
const CLI::Validator finitePositive = finiteNumber(false);
const CLI::Validator finiteNonNegative = finiteNumber(true);

// CLI::NonNegativeNumber's message prints the range up to DBL_MAX (300 digits).
const CLI::Validator nonNegativeInteger(
    [](std::string& text) -> std::string {
      try {
        size_t used = 0;
        const long long value = std::stoll(text, &used);
        if (used != text.size()) return "must be a whole number >= 0, got " + text;
        if (value < 0) return "must be >= 0, got " + text;
      } catch (const std::exception&) {
        return "must be a whole number >= 0, got " + text;
      }
      return {};
    },
    "INTEGER >= 0");

// CLI11 converts integers with strtoll(text, base 0): "010" would be 8 and "0x10" 16. Every
// integer option is read in base 10: leading zeros are dropped, other prefixes refused.
const CLI::Validator decimalInteger(
    [](std::string& text) -> std::string {
      const std::size_t blank = text.find_first_not_of(" \t\n\r\f\v");  // (strtoll skips leading white space)
      text.erase(0, blank == std::string::npos ? text.size() : blank);
      const std::size_t sign = !text.empty() && (text[0] == '+' || text[0] == '-') ? 1 : 0;
      std::size_t first = sign;
      while (first + 1 < text.size() && text[first] == '0') ++first;
      if (first == sign) return {};
      for (std::size_t k = first; k < text.size(); ++k)
        if (text[k] < '0' || text[k] > '9') return "must be a whole number in base 10, got " + text;
      text = text.substr(0, sign) + text.substr(first);
      return {};
    },
    "", "decimal");

/// Puts decimalInteger in front of the checks of every integer option of `app` and its
/// subcommands (CLI11 names their type INT or UINT, before the checks' names).
void readIntegersInBaseTen(CLI::App& app) {
  for (CLI::Option* option : app.get_options()) {
    const std::string full = option->get_type_name();  // "INT", or "INT:<the checks' names>"
    const std::string type = full.substr(0, full.find(':'));
    if (type == "INT" || type == "UINT") option->transform(decimalInteger);
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) readIntegersInBaseTen(*sub);
}

std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

/// Arguments a subcommand did not take: each named, an unknown option with the closest
/// one it has (a typo such as --szie for --size).
int reportExtras(const CLI::App& cmd, const std::vector<std::string>& extras) {
  bool afterUnknownOption = false;
  for (const std::string& extra : extras) {
    std::string message = "weft " + cmd.get_name() + ": ";
    const bool option = extra.rfind("-", 0) == 0;
    if (!option && afterUnknownOption) {  // the value of the unknown option just reported
      afterUnknownOption = false;
      continue;
    }
    afterUnknownOption = option && extra.find('=') == std::string::npos;
    if (option) {
      const std::string name = extra.substr(0, extra.find('='));
      message += "unknown option '" + name + "'";
      std::string best;
      std::size_t bestDistance = 3;  // suggest only close matches
      for (const CLI::Option* option : cmd.get_options()) {
        for (const std::string& known : option->get_lnames()) {
          const std::size_t d = editDistance(name, "--" + known);
          if (d < bestDistance) {
            bestDistance = d;
            best = "--" + known;
          }
        }
      }
      if (!best.empty()) message += " (did you mean " + best + "?)";
    } else {
      message += "unexpected argument '" + extra + "' (one scene per run)";
    }
    std::cerr << message << "\n";
  }
  std::cerr << "Run with --help for more information.\n";
  return 2;
}
/// "WxH": two whole numbers from 16 to 8192.
const CLI::Validator imageSize(
    [](std::string& text) -> std::string {
      const std::size_t x = text.find('x');
      int w = 0, h = 0;
      try {
        size_t used = 0;
        if (x == std::string::npos) throw std::invalid_argument("no x");
        w = std::stoi(text.substr(0, x), &used);
        if (used != x) throw std::invalid_argument("width");
        h = std::stoi(text.substr(x + 1), &used);
        if (used != text.size() - x - 1) throw std::invalid_argument("height");
      } catch (const std::exception&) {
        return "must be WIDTHxHEIGHT in pixels (e.g. 640x480), got " + text;
      }
      if (w < 16 || h < 16 || w > 8192 || h > 8192)
        return "width and height must be from 16 to 8192 pixels, got " + text;
      return {};
    },
    "WxH");

/// "AZ,EL" or "AZ,EL,DIST": degrees in [-3600, 3600], degrees in (-90, 90), metres in (0, 1e9].
const CLI::Validator cameraAngles(
    [](std::string& text) -> std::string {
      std::vector<double> values;
      std::size_t begin = 0;
      try {
        while (begin <= text.size()) {
          const std::size_t comma = std::min(text.find(',', begin), text.size());
          size_t used = 0;
          const std::string part = text.substr(begin, comma - begin);
          values.push_back(std::stod(part, &used));
          if (used != part.size() || !std::isfinite(values.back())) throw std::invalid_argument(part);
          begin = comma + 1;
        }
      } catch (const std::exception&) {
        return "must be AZIMUTH,ELEVATION[,DISTANCE] (degrees, degrees, metres), got " + text;
      }
      if (values.size() < 2 || values.size() > 3)
        return "must be AZIMUTH,ELEVATION[,DISTANCE] (degrees, degrees, metres), got " + text;
      // (Bounded so that the camera's position and the picture stay finite numbers.)
      if (!(std::abs(values[0]) <= 3600)) return "azimuth must be between -3600 and 3600 degrees, got " + text;
      if (!(values[1] > -90 && values[1] < 90)) return "elevation must be between -90 and 90 degrees, got " + text;
      if (values.size() == 3 && !(values[2] > 0 && values[2] <= 1e9))
        return "distance must be > 0 and at most 1e9 m, got " + text;
      return {};
    },
    "AZ,EL[,DIST]");

CLI::App* addRenderCommand(CLI::App& app, weftcli::RenderOptions& render, const std::string& names) {
  CLI::App* cmd = app.add_subcommand(
      "render", "Run a scene and draw it offscreen into PNG pictures: cloth, obstacles, bodies, a ground grid");
  cmd->allow_extras();
  cmd->add_option("scene", render.run.scene, "A built-in scene (" + names + ") or a JSON scene file");
  cmd->add_option("--out", render.out, "Directory of the pictures (created): frame_000000.png, ...")->required();
  cmd->add_option("--every", render.every,
                  "A picture every K steps (K >= 1; default: 30 pictures per simulated second); picture 0 is the "
                  "initial state")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            try {
              size_t used = 0;
              const long long value = std::stoll(text, &used);
              if (used == text.size() && value >= 1) return {};
            } catch (const std::exception&) {
            }
            return "must be a whole number >= 1, got " + text;
          },
          "INTEGER >= 1"));
  cmd->add_option_function<std::string>(
         "--size",
         [&render](const std::string& text) {
           const std::size_t x = text.find('x');
           render.width = std::stoi(text.substr(0, x));
           render.height = std::stoi(text.substr(x + 1));
         },
         "Picture size in pixels, WIDTHxHEIGHT (default 640x480)")
      ->check(imageSize);
  cmd->add_option_function<std::string>(
         "--camera",
         [&render](const std::string& text) {
           std::vector<double> values;
           std::size_t begin = 0;
           while (begin <= text.size()) {
             const std::size_t comma = std::min(text.find(',', begin), text.size());
             values.push_back(std::stod(text.substr(begin, comma - begin)));
             begin = comma + 1;
           }
           render.azimuth = values[0];
           render.elevation = values[1];
           if (values.size() == 3) render.distance = values[2];
         },
         "AZIMUTH,ELEVATION[,DISTANCE]: degrees about the vertical (0: from +z), degrees above the horizon, "
         "metres from the centre (default 35,22 and the distance that frames the whole run)")
      ->check(cameraAngles);
  cmd->add_option_function<std::string>(
         "--framing", [&render](const std::string& text) { render.framingEach = text == "each"; },
         "run: one camera frames the whole run (default) | each: every picture framed on its own (stills)")
      ->check(CLI::IsMember({"run", "each"}));
  cmd->add_option("--supersample", render.supersample,
                  "Draw at N times the size and average down (anti-aliasing; 1 to 4, default 2)")
      ->check(CLI::Range(1, 4));
  cmd->add_option(
         "--scene-size", render.run.size,
         "Built-in scenes: what `weft run --size` sets (grid side, rope particles, boxes of stack, bodies of pile)")
      ->check(CLI::Range(std::int64_t(2), std::int64_t(1) << 15));
  cmd->add_option("--steps", render.run.steps, "Number of fixed steps (default: the scene's)")
      ->check(nonNegativeInteger);
  cmd->add_option("--dt", render.run.dt, "Time step in seconds (> 0)")->check(finitePositive);
  std::vector<std::string> integrators;
  for (const weft::IntegratorKind kind : weft::kAllIntegrators) integrators.emplace_back(weft::integratorName(kind));
  std::string integratorList;
  for (const std::string& name : integrators) integratorList += (integratorList.empty() ? "" : " | ") + name;
  cmd->add_option("--integrator", render.run.integrator, integratorList)->check(CLI::IsMember(integrators));
  cmd->add_option("--precision", render.run.precision, "float | double")->check(CLI::IsMember({"float", "double"}));
  cmd->add_option("--threads", render.run.threads, "Worker threads of the simulation (0 = all cores)")
      ->check(CLI::Range(0, 1024));
  return cmd;
}

/// True, naming `option` and the value on stderr, when `values` holds one twice (the command
/// then exits 2): study and soak run each thread count and scene of their lists once, and
/// soak compares the thread counts' hashes, so a repeated count would compare a run with itself.
template <class T>
bool givenTwice(const CLI::App& command, const char* option, std::vector<T> values) {
  std::sort(values.begin(), values.end());
  const auto twice = std::adjacent_find(values.begin(), values.end());
  if (twice == values.end()) return false;
  std::cerr << "weft " << command.get_name() << ": " << option << " " << *twice
            << " is given twice; give each value once\n";
  return true;
}
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"weft — multithreaded cloth and collision kernel"};
  app.require_subcommand(1);
  weftcli::RunOptions run;
  CLI::App* cmd = app.add_subcommand("run", "Run a built-in scene or a JSON scene file and print its figures");
  cmd->allow_extras();  // reported below, with the closest option to a misspelt one
  std::string names;
  for (const std::string& name : weft::builtinSceneNames()) names += (names.empty() ? "" : ", ") + name;
  cmd->add_option("scene", run.scene,
                  "A built-in scene (" + names +
                      "; docs/scenes.md says what each is) or a JSON scene file (docs/scenes.md). Options given "
                      "below override the scene's values");
  cmd->add_option("--size", run.size,
                  "Built-in scenes: grid side (cloth), particle count (rope), boxes (stack) or bodies (pile); "
                  "ball-on-brick, bullet and slope have a fixed layout")
      ->check(CLI::Range(std::int64_t(2), std::int64_t(1) << 15));
  cmd->add_option("--steps", run.steps, "Number of fixed steps")->check(nonNegativeInteger);
  cmd->add_option("--dt", run.dt, "Time step in seconds (> 0); default scales with --size")->check(finitePositive);
  std::vector<std::string> integrators;
  for (const weft::IntegratorKind kind : weft::kAllIntegrators) integrators.emplace_back(weft::integratorName(kind));
  cmd->add_option("--integrator", run.integrator,
                  "euler | symplectic | midpoint | rk4 | verlet | rk45 | implicit | projective")
      ->check(CLI::IsMember(integrators));
  cmd->add_option("--rtol", run.relativeTolerance,
                  "rk45: relative tolerance per coordinate (>= 0; at least 64 machine epsilons are used)")
      ->check(finiteNonNegative);
  cmd->add_option("--atol", run.absoluteTolerance, "rk45: absolute tolerance per coordinate, m and m/s (> 0)")
      ->check(finitePositive);
  cmd->add_flag("--fixed-step", run.fixedStep, "rk45: one fixed Dormand-Prince step per step, no error control");
  cmd->add_option("--cg-tolerance", run.linearTolerance, "implicit: CG stops at |r| <= this x |b| (in [0, 1))")
      ->check(finiteNonNegative & CLI::Range(0.0, 0.999999));
  cmd->add_option("--cg-max-iterations", run.maxLinearIterations, "implicit: CG iteration cap (1 to 2^30)")
      ->check(CLI::Range(std::int64_t(1), std::int64_t(weft::kMaxIterationCap)));
  std::vector<std::string> preconditioners;
  std::string preconditionerList;
  for (const weft::Preconditioner p : weft::kAllPreconditioners) {
    preconditioners.emplace_back(weft::preconditionerName(p));
    preconditionerList += (preconditionerList.empty() ? "" : " | ") + preconditioners.back();
  }
  cmd->add_option("--cg-preconditioner", run.preconditioner,
                  "implicit: CG preconditioner: " + preconditionerList +
                      " (default auto: block-jacobi, and the multigrid where block-jacobi takes more than (at first) " +
                      std::to_string(weft::kAutoMultigridIterations) + " CG iterations and the multigrid costs less)")
      ->check(CLI::IsMember(preconditioners));
  cmd->add_option("--pd-iterations", run.projectiveIterations,
                  "projective: local/global iterations per step, one global solve each (1..10000; default 10)")
      ->check(CLI::Range(1, 10000));
  cmd->add_option("--precision", run.precision, "float | double")->check(CLI::IsMember({"float", "double"}));
  cmd->add_option("--threads", run.threads, "Worker threads (0 = all cores)")->check(CLI::Range(0, 1024));
  cmd->add_option("--drag", run.drag, "Viscous drag on every particle, N s/m (>= 0; 0 = none, free)")
      ->check(finiteNonNegative);
  cmd->add_option("--strategy", run.strategy, "Force accumulation: auto | gather | coloured | grid-stencil")
      ->check(CLI::IsMember({"auto", "gather", "coloured", "colored", "grid-stencil", "grid"}));
  cmd->add_option("--narrow-phase", run.narrowPhase,
                  "Rigid bodies: exact (separating axes) | ofg (Opposing Face Geometry) | witness (cached "
                  "separating plane, default)")
      ->check(CLI::IsMember({"exact", "ofg", "witness"}));
  cmd->add_option("--ofg-faces", run.ofgFaces, "Rigid bodies: faces per side the Opposing Face Geometry keeps (1..64)")
      ->check(CLI::Range(1, weft::kMaxOfgFaces));
  cmd->add_option("--max-memory", run.maxMemory,
                  "MiB the run may take (default: what the machine has available); a scene that needs more "
                  "is refused before anything is allocated (one whose self-collision may need more once its cloth "
                  "folds is warned of)")
      ->check(finitePositive);
  cmd->add_option("--time-of-impact", run.timeOfImpact,
                  "Rigid bodies: speculative (contacts before touching, one solve a step; default) | rollback "
                  "(chunks cut at the time of impact, taken back when too deep)")
      ->check(CLI::IsMember({"speculative", "rollback"}));
  CLI::Option* out = cmd->add_option("--out", run.out, "Write frames into this directory (created)");
  cmd->add_option("--format", run.format,
                  "Frame format: obj | ply | cache (one frames.wcache) | gltf (one animated run.glb); default obj")
      ->check(CLI::IsMember({"obj", "ply", "cache", "gltf"}))
      ->needs(out);
  CLI::Option* every =
      cmd->add_option("--every", run.every,
                      "Write a frame (--out) and a checkpoint (--checkpoint) every K steps (K >= 1, default 1 for "
                      "frames; without it a checkpoint is written at the end only); frame 0 is the initial state")
          ->check(CLI::Range(std::int64_t(1), std::numeric_limits<std::int64_t>::max()));
  CLI::Option* checkpoint = cmd->add_option(
      "--checkpoint", run.checkpoint,
      "Write a checkpoint to FILE (through FILE.tmp, renamed) every --every steps, at the end and when interrupted "
      "(Ctrl-C): `--resume FILE` continues the run bit for bit");
  cmd->add_option("--resume", run.resume,
                  "Continue from a checkpoint written by --checkpoint for the same scene and options, up to --steps "
                  "in all");
  every->check(
      [out, checkpoint](const std::string&) -> std::string {
        return out->count() + checkpoint->count() > 0 ? "" : "--every needs --out or --checkpoint";
      },
      "");
  cmd->add_flag("--json", run.json, "Print exactly one JSON object instead of the summary");
  cmd->add_flag("!--no-progress", run.progress, "No progress bar (there is none with --json or when not a terminal)");

  weftcli::StudyOptions study;
  CLI::App* studyCmd = app.add_subcommand(
      "study",
      "Error, stability limit and wall time of every integrator x dt x precision x threads (CSV, Markdown, plot)");
  studyCmd->add_flag("--quick", study.quick, "Small scenes and a coarse sweep (under a minute)");
  studyCmd->add_option("--out", study.out, "Output directory (default: study)");
  studyCmd->add_option("--threads", study.threads, "Thread counts to time (default: 1 2)")
      ->check(CLI::Range(1, 1024))
      ->expected(1, 16);
  studyCmd->add_flag("!--no-plot", study.plot, "Do not draw the plot");
  studyCmd->add_option("--scene", study.scenes, "Only these scenes: oscillator, rope, flag (default: all)")
      ->check(CLI::IsMember({"oscillator", "rope", "flag"}));
  studyCmd->add_option("--schedule", study.schedule,
                       "Also write how the work was spread: one CSV row per task (phase, estimated cost, rank, host, "
                       "wall seconds); with mpirun -np N the ranks share the sweep (docs/distributed.md)");

  std::string stripDirectory;
  studyCmd->add_option("--strip", stripDirectory,
                       "Also draw the flag under each integrator at the same time into DIR/strip.png (and strip.md): "
                       "needs weft built with rendering");
  weftcli::RenderOptions render;
  CLI::App* renderCmd = addRenderCommand(app, render, names);

  std::string integratorList;
  for (const std::string& name : integrators) integratorList += (integratorList.empty() ? "" : " | ") + name;
  weftcli::ViewOptions view;
  CLI::App* viewCmd = app.add_subcommand(
      "view",
      "Open a window on a scene, live: orbit, pause, step, change integrator, dt, precision and threads, "
      "compare two integrators side by side, pull the cloth with the mouse");
  viewCmd->allow_extras();
  viewCmd->add_option("scene", view.run.scene, "A built-in scene (" + names + ") or a JSON scene file");
  viewCmd
      ->add_option("--scene-size", view.run.size,
                   "Built-in scenes: what `weft run --size` sets (grid side, rope particles, boxes of stack, bodies "
                   "of pile)")
      ->check(CLI::Range(std::int64_t(2), std::int64_t(1) << 15));
  viewCmd->add_option("--dt", view.run.dt, "Time step in seconds (> 0)")->check(finitePositive);
  viewCmd->add_option("--integrator", view.run.integrator, integratorList)->check(CLI::IsMember(integrators));
  viewCmd
      ->add_option("--compare", view.compare,
                   "Split screen from the start: the right pane runs the same scene under this integrator")
      ->check(CLI::IsMember(integrators));
  viewCmd->add_option("--precision", view.run.precision, "float | double")->check(CLI::IsMember({"float", "double"}));
  viewCmd->add_option("--threads", view.run.threads, "Worker threads (0 = all cores)")->check(CLI::Range(0, 1024));
  viewCmd
      ->add_option_function<std::string>(
          "--size",
          [&view](const std::string& text) {
            const std::size_t x = text.find('x');
            view.width = std::stoi(text.substr(0, x));
            view.height = std::stoi(text.substr(x + 1));
          },
          "Window size in pixels, WIDTHxHEIGHT (default 1280x720)")
      ->check(imageSize);
  CLI::Option* frames = viewCmd->add_option("--frames", view.frames, "Close after N frames (N >= 1)")
                            ->check(CLI::Range(std::int64_t(1), std::int64_t(1) << 40));
  viewCmd->add_option("--screenshot", view.screenshot, "With --frames: write the last frame to this PNG file")
      ->needs(frames);

  weftcli::SoakOptions soak;
  CLI::App* soakCmd = app.add_subcommand(
      "soak",
      "Long runs of every built-in scene on 1 and 2 threads: no NaN, bounded energy, no memory growth, one hash");
  soakCmd->add_option("--seconds", soak.seconds, "Simulated seconds per scene (default 60)")->check(finitePositive);
  soakCmd->add_option("--max-steps", soak.maxSteps, "Steps per scene at most (default 1000000)")
      ->check(CLI::Range(std::int64_t(1), std::numeric_limits<std::int64_t>::max()));
  soakCmd->add_option("--scene", soak.scenes, "Only these built-in scenes (default: all)")
      ->check(CLI::IsMember(weft::builtinSceneNames()));
  soakCmd->add_option("--threads", soak.threads, "Thread counts whose final hashes must agree (default: 1 2)")
      ->check(CLI::Range(1, 1024))
      ->expected(1, 16);
  soakCmd->add_option("--out", soak.out, "Also write the Markdown table to this file");

  readIntegersInBaseTen(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints the message (naming the option and the value); bad input exits 2,
    // --help exits 0.
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (cmd->parsed() && !cmd->remaining().empty()) return reportExtras(*cmd, cmd->remaining());
  if (renderCmd->parsed() && !renderCmd->remaining().empty()) return reportExtras(*renderCmd, renderCmd->remaining());
  if (viewCmd->parsed() && !viewCmd->remaining().empty()) return reportExtras(*viewCmd, viewCmd->remaining());
  if (studyCmd->parsed() &&
      (givenTwice(*studyCmd, "--threads", study.threads) || givenTwice(*studyCmd, "--scene", study.scenes)))
    return 2;
  if (soakCmd->parsed() &&
      (givenTwice(*soakCmd, "--threads", soak.threads) || givenTwice(*soakCmd, "--scene", soak.scenes)))
    return 2;
  try {
    if (studyCmd->parsed()) {
      const int code = weftcli::runStudy(study);
      // Under mpirun the strip is drawn once, by rank 0 (the launcher's rank variables).
      const char* rank = std::getenv("OMPI_COMM_WORLD_RANK");
      if (!rank) rank = std::getenv("PMI_RANK");
      if (code != 0 || stripDirectory.empty() || (rank && std::string(rank) != "0")) return code;
      return weftcli::writeIntegratorStrip(stripDirectory, study.quick);
    }
    if (soakCmd->parsed()) return weftcli::runSoak(soak);
    if (renderCmd->parsed()) return weftcli::renderScene(render);
    if (viewCmd->parsed()) return weftcli::viewScene(view);
    return weftcli::runScene(run);
  } catch (const std::exception& e) {
    std::cerr << "weft: " << e.what() << "\n";
    return 2;
  }
}
