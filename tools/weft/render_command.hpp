// `weft render`: a scene's run as PNG pictures, drawn offscreen (no display, no GPU).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "run_command.hpp"

namespace weftcli {

struct RenderOptions {
  RunOptions run;   // the scene and what overrides its values (scene, size, steps, dt, integrator, precision, threads)
  std::string out;  // directory of the pictures (created)
  std::optional<std::int64_t> every;                   // a picture every K steps (default: 30 per simulated second)
  int width = 640, height = 480;                       // pixels
  std::optional<double> azimuth, elevation, distance;  // --camera AZ,EL[,DIST]: degrees, degrees, m
  int supersample = 2;                                 // rendered at this multiple of the size, then averaged down
  bool framingEach = false;  // --framing each: a camera per picture (default: one for the run)
};

/// Runs the scene, keeping a snapshot every `every` steps, frames the camera on everything
/// the run showed, and writes DIR/frame_000000.png, ... Returns 0, 3 when the stability
/// check stopped the run (the pictures up to then are written), 2 for bad input or when
/// this weft was built without rendering. Throws std::exception for a bad scene or an
/// output that cannot be written (the message names the option and the value).
int renderScene(const RenderOptions& options);

/// Whether this weft was built with `weft render` (OSMesa and libpng found at configure time).
bool renderingBuiltIn();

}  // namespace weftcli
