// `weft run`: run a built-in scene or a JSON scene file and summarise it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "weft/integrate/integrator.hpp"
#include "weft/io/scene.hpp"

namespace weftcli {

/// Command-line settings. Every optional one overrides the scene's value when given.
struct RunOptions {
  std::string scene = "flag";  // a built-in scene name or the path of a .json scene file
  std::int64_t size = 0;       // built-in scenes: grid side or particle count (0: default)
  std::optional<std::int64_t> steps;
  std::optional<double> dt;
  std::optional<std::string> integrator;
  std::optional<double> relativeTolerance, absoluteTolerance, linearTolerance;
  std::optional<std::int64_t> maxLinearIterations;
  std::optional<std::string> preconditioner;  // implicit: jacobi | block-jacobi | projective | multigrid | auto
  std::optional<int> projectiveIterations;
  bool fixedStep = false;  // rk45 without error control
  std::optional<double> drag;
  std::optional<std::string> precision;
  std::optional<int> threads;
  std::optional<std::string> strategy;
  std::optional<std::string> narrowPhase;   // rigid bodies: exact | ofg | witness
  std::optional<int> ofgFaces;              // rigid bodies: k of the Opposing Face Geometry
  std::optional<std::string> timeOfImpact;  // rigid bodies: speculative | rollback
  std::optional<double> maxMemory;          // MiB the run may take (default: what the machine has available)
  bool json = false;
  bool progress = true;  // a progress bar when stdout is a terminal and the run is long
  std::optional<std::string> out;
  std::optional<std::string> format;
  std::optional<std::int64_t> every;
  std::optional<std::string> checkpoint;  // write a checkpoint here: every `every` steps, at the end, when interrupted
  std::optional<std::string> resume;      // continue the run from this checkpoint
};

/// The scene `options.scene` names (a built-in one, else a scene file) with the options
/// given applied over its values: what `weft run`, `weft render` and `weft view` simulate.
/// Throws for a bad scene (std::exception naming file, field and value).
weft::SceneSpec sceneFor(const RunOptions& options);

/// The scene file's settings that `command` ("run", "render" or "view") does not read,
/// given a value other than their default ("integration.rtol applies to rk45, and this run
/// integrates with rk4"); render and view take none of the file's `output` section, and
/// view none of its length. Options given on the command line that a run would not read
/// are refused by sceneFor instead.
std::vector<std::string> unusedSceneSettings(const RunOptions& options, const weft::SceneSpec& spec,
                                             const std::string& command = "run");

/// Runs the scene; prints a summary (or one JSON object). Returns the process exit code:
/// 0 when every step succeeded, 3 when the stability check stopped the run, 130 / 143 when
/// SIGINT / SIGTERM interrupted it (the current step is finished, frames and the checkpoint
/// are written, the summary says "interrupted"). With an
/// output directory, frames go there (created): frame 0 is the initial state, then one
/// frame after every `every` steps (frame_000000.obj / .ply, or one frames.wcache).
/// Throws for a bad scene (std::exception with a message naming file, field and value).
int runScene(const RunOptions& options);

}  // namespace weftcli
