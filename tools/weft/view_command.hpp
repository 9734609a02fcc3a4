// `weft view`: a scene in a window, live (GLFW, OpenGL 3.3 core; the renderer of
// `weft render`).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "run_command.hpp"

namespace weftcli {

struct ViewOptions {
  RunOptions run;                         // the scene and what overrides its values
  std::optional<std::string> compare;     // split screen from the start: the right pane's integrator
  int width = 1280, height = 720;         // window size, pixels
  std::optional<std::int64_t> frames;     // close after this many frames (tests, recordings)
  std::optional<std::string> screenshot;  // with frames: the last frame as a PNG file
};

/// Opens the window and runs until it is closed (or `frames` have been drawn). Returns 0,
/// or 2 when there is no display to open a window on, when the display gives no OpenGL 3.3
/// core context, or when this weft was built without GLFW. Throws std::exception for a
/// bad scene.
int viewScene(const ViewOptions& options);

}  // namespace weftcli
