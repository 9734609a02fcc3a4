// `weft run`: run a built-in scene and summarise it.
#pragma once

#include <cstdint>
#include <string>

#include "weft/integrate/integrator.hpp"

namespace weftcli {

struct RunOptions {
  std::string scene = "flag";
  std::int64_t size = 0;  // 0: the scene's default
  std::int64_t steps = 2000;
  double dt = 0;  // 0: the scene's default
  std::string integrator = "rk4";
  weft::IntegratorOptions integration;  // rk45 tolerances, implicit CG settings
  bool fixedStep = false;               // rk45 without error control
  double drag = 0;                      // viscous drag, N s/m (0: absent)
  std::string precision = "double";
  int threads = 0;
  std::string strategy = "auto";
  bool json = false;
  std::string out;             // frames directory; empty: write no frames
  std::string format = "obj";  // obj | ply | cache
  std::int64_t every = 1;      // write a frame every this many steps (>= 1)
};

/// Runs the scene; prints a summary (or one JSON object). Returns the process exit code:
/// 0 when every step succeeded, 3 when the stability check stopped the run. With `out`,
/// frames go to that directory (created): frame 0 is the initial state, then one frame
/// after every `every` steps (frame_000000.obj / .ply, or one frames.wcache).
int runScene(const RunOptions& options);

}  // namespace weftcli
