#include "render_command.hpp"

#include <iostream>

#ifdef WEFT_HAVE_RENDER
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "camera.hpp"
#include "draw_scene.hpp"
#include "offscreen_context.hpp"
#include "png_image.hpp"
#include "render_scene.hpp"
#include "renderer.hpp"
#include "unchecked_state.hpp"
#include "weft/weft.hpp"
#endif

namespace weftcli {

#ifndef WEFT_HAVE_RENDER

bool renderingBuiltIn() { return false; }

int renderScene(const RenderOptions&) {
  std::cerr << "weft render: this weft was built without rendering (OSMesa or libpng was not found when it was "
               "configured: run bash tools/setup.sh, then configure and build again)\n";
  return 2;
}

#else

bool renderingBuiltIn() { return true; }

namespace {

using weftrender::checkSnapshotMemory;
using weftrender::defaultEvery;
using weftrender::drawSnapshot;
using weftrender::FramedView;
using weftrender::frameView;
using weftrender::makeDrawer;
using weftrender::prepareOutputDirectory;
using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

template <class S>
int render(const RenderOptions& o, const weft::SceneSpec& spec) {
  const auto start = Clock::now();
  prepareOutputDirectory(o.out, "--out");
  // The context before the run: a machine that cannot render says so at once.
  weftrender::OffscreenContext context(o.width * o.supersample, o.height * o.supersample);
  weftrender::Renderer renderer(context.gl());

  weft::AssembledScene<S> assembled = weft::assembleScene<S>(spec);
  weft::Simulation<S> sim(std::move(assembled.built), assembled.options);
  const weftrender::SceneDrawer drawer = makeDrawer(sim, assembled.firstParticle);
  const std::int64_t steps = weft::sceneStepCount(spec);
  const std::int64_t every = o.every ? *o.every : defaultEvery(sim.timeStep());
  checkSnapshotMemory(drawer, sim.rigidWorld() ? sim.rigidWorld()->model().pieceCount() : 0, steps, every);

  // The run, a snapshot every `every` steps (the camera frames them all before any is drawn).
  std::vector<weftrender::SceneSnapshot> snapshots;
  snapshots.push_back(drawer.snapshot(sim));
  weft::StepStatus status = sim.status();
  // With the stability check off nothing stops a state that overflowed: the pictures stop at
  // the last finite one, and the run does not end "ok" (as weft run's does not).
  bool finite = sim.stateFinite();
  const auto simulateStart = Clock::now();
  while (sim.stepCount() < steps && status.ok() && finite) {
    const std::int64_t boundary = std::min(steps, (sim.stepCount() / every + 1) * every);
    while (sim.stepCount() < boundary && (status = sim.step()).ok()) {
    }
    finite = sim.stateFinite();
    if (status.ok() && finite) snapshots.push_back(drawer.snapshot(sim));
  }
  const double simulateSeconds = seconds(simulateStart);

  const auto drawStart = Clock::now();
  FramedView view = frameView(drawer, snapshots, o.width, o.height, o.azimuth, o.elevation, o.distance);
  weftrender::DrawFrame frame;
  for (std::size_t f = 0; f < snapshots.size(); ++f) {
    if (o.framingEach) view = frameView(drawer, {snapshots[f]}, o.width, o.height, o.azimuth, o.elevation, o.distance);
    const weftrender::Image image = drawSnapshot(drawer, snapshots[f], view, renderer, context, frame);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06zu.png", f);
    weftrender::writePng((std::filesystem::path(o.out) / name).string(), image);
  }
  const double drawSeconds = seconds(drawStart);

  std::ostringstream out;
  out.precision(4);
  out << "weft render " << spec.name << ": " << snapshots.size() << " pictures of " << o.width << " x " << o.height
      << " in " << o.out << " (frame_000000.png ...), every " << every << " steps of "
      << weft::integratorName(sim.integrator()) << " at dt " << sim.timeStep() << " s, " << sim.state().time
      << " s simulated\n"
      << "  camera       " << (o.framingEach ? "(the last picture's) " : "") << "azimuth "
      << view.camera.azimuth * 180 / std::numbers::pi << " deg, elevation "
      << view.camera.elevation * 180 / std::numbers::pi << " deg, distance " << view.camera.distance
      << " m, looking at (" << view.camera.target.x() << ", " << view.camera.target.y() << ", "
      << view.camera.target.z() << ")\n"
      << "  time         " << simulateSeconds << " s simulating, " << drawSeconds << " s drawing ("
      << 1000 * drawSeconds / static_cast<double>(snapshots.size()) << " ms per picture, " << o.supersample << "x"
      << o.supersample << " supersampled, " << context.renderer() << "), " << seconds(start) << " s in all\n";
  if (!status.ok()) out << "  status       " << status.message() << " (pictures up to the last good step)\n";
  if (status.ok() && !finite)
    out << "  status       " << notFiniteMessage(sim.stepCount()) << "; pictures up to the last finite state\n";
  std::cout << out.str();
  for (const std::string& w : sim.warnings()) std::cerr << "weft render: warning: " << w << "\n";
  return status.ok() && finite ? 0 : 3;
}

}  // namespace

int renderScene(const RenderOptions& options) {
  const weft::SceneSpec spec = sceneFor(options.run);
  for (const std::string& u : unusedSceneSettings(options.run, spec, "render"))
    std::cerr << "weft render: note: " << u << " (not used)\n";
  return spec.precision == weft::Precision::Float ? render<float>(options, spec) : render<double>(options, spec);
}

#endif

}  // namespace weftcli
