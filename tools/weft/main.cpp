// The `weft` command line. Parsing is CLI11's (Debian libcli11-dev); every bad option
// exits non-zero with a message naming the option and the value.
#include <CLI/CLI.hpp>
#include <cmath>
#include <iostream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "run_command.hpp"
#include "study_command.hpp"
#include "weft/integrate/integrator.hpp"

namespace {
// CLI::PositiveNumber lets "nan" through: a time step or a tolerance must be a finite
// number (> 0, or >= 0 when zero is allowed).
CLI::Validator finiteNumber(bool allowZero) {
  return CLI::Validator(
      [allowZero](std::string& text) -> std::string {
        double value = 0;
        try {
          size_t used = 0;
          value = std::stod(text, &used);
          if (used != text.size()) return "'" + text + "' is not a number";
        } catch (const std::exception&) {
          return "'" + text + "' is not a number";
        }
        if (!(std::isfinite(value) && (allowZero ? value >= 0 : value > 0)))
          return std::string("must be a finite number ") + (allowZero ? ">= 0" : "> 0") + ", got " + text;
        return {};
      },
      allowZero ? "FINITE >= 0" : "FINITE > 0");
}
const CLI::Validator finitePositive = finiteNumber(false);
const CLI::Validator finiteNonNegative = finiteNumber(true);
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"weft — multithreaded cloth and collision kernel"};
  app.require_subcommand(1);
  weftcli::RunOptions run;
  CLI::App* cmd = app.add_subcommand("run", "Run a built-in scene and print its figures");
  cmd->add_option("scene", run.scene,
                  "A built-in scene (flag: 64 x 64 cloth pinned at two corners; rope; flag-wind: a flag on a pole "
                  "in gusty wind; hanging-cloth: cloth on a turning bar; drape: cloth onto a sphere; drape-mesh: cloth "
                  "onto an imported torus mesh; rope-on-pegs: a rope "
                  "across three capsules; fast-ball: 100 m/s at a one-triangle wall) or a JSON scene file "
                  "(docs/scenes.md). "
                  "Options given below override the scene's values");
  cmd->add_option("--size", run.size, "Built-in scenes: grid side (cloth) or particle count (rope); default 64")
      ->check(CLI::Range(std::int64_t(2), std::int64_t(1) << 15));
  cmd->add_option("--steps", run.steps, "Number of fixed steps")->check(CLI::NonNegativeNumber);
  cmd->add_option("--dt", run.dt, "Time step in seconds (> 0); default scales with --size")->check(finitePositive);
  std::vector<std::string> integrators;
  for (const weft::IntegratorKind kind : weft::kAllIntegrators) integrators.emplace_back(weft::integratorName(kind));
  cmd->add_option("--integrator", run.integrator, "euler | symplectic | midpoint | rk4 | verlet | rk45 | implicit")
      ->check(CLI::IsMember(integrators));
  cmd->add_option("--rtol", run.relativeTolerance, "rk45: relative tolerance per coordinate (>= 0)")
      ->check(finiteNonNegative);
  cmd->add_option("--atol", run.absoluteTolerance, "rk45: absolute tolerance per coordinate, m and m/s (> 0)")
      ->check(finitePositive);
  cmd->add_flag("--fixed-step", run.fixedStep, "rk45: one fixed Dormand-Prince step per step, no error control");
  cmd->add_option("--cg-tolerance", run.linearTolerance, "implicit: CG stops at |r| <= this x |b| (in [0, 1))")
      ->check(finiteNonNegative & CLI::Range(0.0, 0.999999));
  cmd->add_option("--cg-max-iterations", run.maxLinearIterations, "implicit: CG iteration cap (>= 1)")
      ->check(CLI::PositiveNumber);
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
  cmd->add_option("--ofg-faces", run.ofgFaces, "Rigid bodies: faces per side the Opposing Face Geometry keeps (k >= 1)")
      ->check(CLI::Range(1, 1024));
  cmd->add_option("--time-of-impact", run.timeOfImpact,
                  "Rigid bodies: speculative (contacts before touching, one solve a step; default) | rollback "
                  "(chunks cut at the time of impact, taken back when too deep)")
      ->check(CLI::IsMember({"speculative", "rollback"}));
  CLI::Option* out = cmd->add_option("--out", run.out, "Write frames into this directory (created)");
  cmd->add_option("--format", run.format, "Frame format: obj | ply | cache (one frames.wcache); default obj")
      ->check(CLI::IsMember({"obj", "ply", "cache"}))
      ->needs(out);
  cmd->add_option("--every", run.every, "Write a frame every K steps (K >= 1, default 1); frame 0 is the initial state")
      ->check(CLI::Range(std::int64_t(1), std::numeric_limits<std::int64_t>::max()))
      ->needs(out);
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

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints the message (naming the option and the value); bad input exits 2,
    // --help exits 0.
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    if (studyCmd->parsed()) return weftcli::runStudy(study);
    return weftcli::runScene(run);
  } catch (const std::exception& e) {
    std::cerr << "weft: " << e.what() << "\n";
    return 2;
  }
}
