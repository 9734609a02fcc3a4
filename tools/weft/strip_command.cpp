#include "strip_command.hpp"

#include <iostream>

#ifdef WEFT_HAVE_RENDER
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <vector>

#include "output_file.hpp"
#include "render_scene.hpp"
#include "weft/io/scene.hpp"
#include "weft/weft.hpp"
#endif

namespace weftcli {

#ifndef WEFT_HAVE_RENDER

int writeIntegratorStrip(const std::string&, bool) {
  std::cerr << "weft study --strip: this weft was built without rendering (OSMesa or libpng was not found when it "
               "was configured)\n";
  return 2;
}

#else

namespace {
struct Tile {
  weft::IntegratorKind kind;
  weftrender::SceneSnapshot last;  // the end of the run, or its last good state
  std::string status;
  double wallSeconds = 0, time = 0, energy = 0;
  bool ok = true;
};
}  // namespace

int writeIntegratorStrip(const std::string& directory, bool quick) {
  weftrender::prepareOutputDirectory(directory, "--strip");
  const weft::SceneSpec spec = weft::builtinSceneSpec("flag", quick ? 24 : 32);
  constexpr double kDuration = 0.25;  // s, the study's flag duration
  const int tileWidth = 200, tileHeight = 150, border = 3;

  std::vector<Tile> tiles;
  std::optional<weftrender::SceneDrawer> drawer;
  weftrender::SceneSnapshot initial;
  for (const weft::IntegratorKind kind : weft::kAllIntegrators) {
    weft::SceneSpec s = spec;
    s.simulation.integrator = kind;
    s.simulation.threads = 1;
    weft::AssembledScene<double> assembled = weft::assembleScene<double>(s);
    weft::Simulation<double> sim(std::move(assembled.built), assembled.options);
    if (!drawer) {
      drawer.emplace(weftrender::makeDrawer(sim, assembled.firstParticle));
      initial = drawer->snapshot(sim);
    }
    Tile tile{kind, drawer->snapshot(sim), "ok"};
    const auto steps = static_cast<std::int64_t>(std::llround(kDuration / sim.timeStep()));
    const auto start = std::chrono::steady_clock::now();
    weft::StepStatus status = sim.status();
    while (sim.stepCount() < steps && (status = sim.step()).ok())
      if (sim.stepCount() % 50 == 0 || sim.stepCount() == steps) tile.last = drawer->snapshot(sim);
    tile.wallSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    tile.ok = status.ok();
    if (!tile.ok) tile.status = status.message();
    tile.time = tile.last.time;
    tile.energy = weft::energy(sim.model(), sim.state(), sim.options().gravity).total();
    tiles.push_back(std::move(tile));
  }

  // One camera for all, framed on RK4's run.
  std::vector<weftrender::SceneSnapshot> framing;
  for (const Tile& t : tiles)
    if (t.kind == weft::IntegratorKind::Rk4) framing = {initial, t.last};
  const weftrender::FramedView view = weftrender::frameView(*drawer, framing, tileWidth, tileHeight, {}, {}, {});
  weftrender::OffscreenContext context(2 * tileWidth, 2 * tileHeight);
  weftrender::Renderer renderer(context.gl());
  weftrender::DrawFrame frame;
  weftrender::Image strip;
  strip.width = tileWidth * static_cast<int>(tiles.size());
  strip.height = tileHeight;
  strip.rgb.assign(3ull * static_cast<std::size_t>(strip.width) * strip.height, 0);
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    const weftrender::Image tile = weftrender::drawSnapshot(*drawer, tiles[i].last, view, renderer, context, frame);
    for (int y = 0; y < tileHeight; ++y)
      for (int x = 0; x < tileWidth; ++x) {
        std::uint8_t* out = strip.pixel(static_cast<int>(i) * tileWidth + x, y);
        const bool edge = x < border || y < border || x >= tileWidth - border || y >= tileHeight - border;
        const bool separator = x == 0 && i > 0;
        if (!tiles[i].ok && edge) {
          out[0] = 200, out[1] = 30, out[2] = 30;  // stopped by the stability check
        } else if (separator) {
          out[0] = out[1] = out[2] = 255;
        } else {
          const std::uint8_t* in = tile.pixel(x, y);
          out[0] = in[0], out[1] = in[1], out[2] = in[2];
        }
      }
  }
  weftrender::writePng((std::filesystem::path(directory) / "strip.png").string(), strip);

  std::ostringstream md;
  md.precision(4);
  md << "# The flag under each integrator at the same time\n\n"
     << "`strip.png`, left to right: the " << (quick ? 24 : 32) << " x " << (quick ? 24 : 32) << " flag after "
     << kDuration << " s at dt " << spec.simulation.dt
     << " s (the flag's default), one thread, double. A red frame: the stability check stopped the run; the "
        "picture is its last good state.\n\n"
     << "| integrator | status | simulated, s | wall, s | energy, J |\n|---|---|---|---|---|\n";
  for (const Tile& t : tiles)
    md << "| " << weft::integratorName(t.kind) << " | " << (t.ok ? "ok" : "stopped: " + t.status) << " | " << t.time
       << " | " << t.wallSeconds << " | " << t.energy << " |\n";
  writeTextFile((std::filesystem::path(directory) / "strip.md").string(), md.str());
  std::cout << "weft study --strip: " << directory << "/strip.png and strip.md (" << tiles.size() << " integrators)\n";
  return 0;
}

#endif

}  // namespace weftcli
