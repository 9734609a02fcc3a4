// tools/render/render_scene.hpp — the steps `weft render` (and the study's strip of
// integrators) share: a SceneDrawer for a Simulation, the camera framed on a run's
// snapshots, one snapshot drawn offscreen into an image.
#pragma once

#include <cstdint>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "camera.hpp"
#include "draw_scene.hpp"
#include "offscreen_context.hpp"
#include "png_image.hpp"
#include "renderer.hpp"

namespace weftrender {

/// Default camera angles, radians: from the front right, a little above.
/// (Exactly the degrees `--camera 35,22` gives, so that naming the default reproduces it.)
inline constexpr float kDefaultAzimuth = static_cast<float>(35 * std::numbers::pi / 180);
inline constexpr float kDefaultElevation = static_cast<float>(22 * std::numbers::pi / 180);

/// Creates `directory` (and its parents) and checks that a file can be written in it.
/// Throws std::invalid_argument naming `option`, the directory and the reason.
void prepareOutputDirectory(const std::string& directory, const std::string& option);

/// The drawer of a simulation's scene (bodies start at `firstParticle`), its floors found
/// at the simulation's present state.
template <class S>
SceneDrawer makeDrawer(const weft::Simulation<S>& sim, const std::vector<weft::Index>& firstParticle) {
  const weft::RigidWorld* rigid = sim.rigidWorld();
  SceneDrawer drawer(sim.model(), firstParticle, sim.options().collision, rigid ? &rigid->model() : nullptr);
  drawer.findFloors(drawer.snapshot(sim));
  return drawer;
}

/// Steps between pictures for 30 pictures per simulated second (at least 1).
std::int64_t defaultEvery(double dt);

/// Refuses (std::invalid_argument naming --every) a run whose snapshots would take more
/// than 2 GiB: `steps / every + 1` of them, each the particles (12 bytes) and rigid poses.
void checkSnapshotMemory(const SceneDrawer& drawer, weft::Index pieceCount, std::int64_t steps, std::int64_t every);

/// A fixed camera for a whole run and what goes with it.
struct FramedView {
  OrbitCamera camera;
  float radius = 1;                   // of the framed box, m
  std::optional<float> groundHeight;  // the ground grid's y, m
  float tubeRadius = 0.004f;          // ropes, m
  int width = 640, height = 480;      // pixels of the pictures
};

/// The camera that frames every snapshot (angles in radians, distance in m; unset: the
/// defaults and the framing distance). The ground is the scene's upward plane, else 0.15
/// radii under the lowest framed point.
FramedView frameView(const SceneDrawer& drawer, const std::vector<SceneSnapshot>& snapshots, int width, int height,
                     std::optional<double> azimuthDegrees, std::optional<double> elevationDegrees,
                     std::optional<double> distance);

/// The same for a box given directly (weft view frames the start of a run, extended).
FramedView frameBox(const SceneDrawer& drawer, const Bounds& box, int width, int height,
                    std::optional<double> azimuthDegrees, std::optional<double> elevationDegrees,
                    std::optional<double> distance);

/// Draws one snapshot into the context (sized view.width x view.height times an integer
/// supersampling factor) and returns the averaged-down picture. `frame` is scratch.
Image drawSnapshot(const SceneDrawer& drawer, const SceneSnapshot& snapshot, const FramedView& view, Renderer& renderer,
                   OffscreenContext& context, DrawFrame& frame);

}  // namespace weftrender
