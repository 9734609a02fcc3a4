#include "render_scene.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <stdexcept>

namespace weftrender {

void prepareOutputDirectory(const std::string& directory, const std::string& option) {
  std::error_code error;
  std::filesystem::create_directories(directory, error);
  if (error)
    throw std::invalid_argument(option + " " + directory + ": cannot create the directory (" + error.message() + ")");
  const std::string probe = (std::filesystem::path(directory) / ".weft-render-probe").string();
  std::FILE* f = std::fopen(probe.c_str(), "wb");
  if (!f)
    throw std::invalid_argument(option + " " + directory + ": cannot write into the directory (" +
                                std::strerror(errno) + ")");
  std::fclose(f);
  std::remove(probe.c_str());
}

std::int64_t defaultEvery(double dt) { return std::max<std::int64_t>(1, std::llround(1.0 / (30.0 * dt))); }

void checkSnapshotMemory(const SceneDrawer& drawer, weft::Index pieceCount, std::int64_t steps, std::int64_t every) {
  const double frames = static_cast<double>(steps / every + 1);
  const double perFrame = 12.0 * static_cast<double>(drawer.particleCount()) +
                          static_cast<double>(sizeof(weft::Pose)) * static_cast<double>(pieceCount) + 64.0;
  const double limit = 2.0 * 1024 * 1024 * 1024;
  if (frames * perFrame > limit) {
    const double most = std::floor(limit / perFrame);
    char text[320];
    std::snprintf(text, sizeof text,
                  "--every %lld: %.0f pictures of %lld steps would keep %.1f GiB of snapshots, more than the 2 GiB "
                  "allowed; use --every %lld or more",
                  static_cast<long long>(every), frames, static_cast<long long>(steps),
                  frames * perFrame / (1024.0 * 1024 * 1024),
                  static_cast<long long>(std::ceil(static_cast<double>(steps) / std::max(1.0, most - 1))));
    throw std::invalid_argument(text);
  }
}

FramedView frameView(const SceneDrawer& drawer, const std::vector<SceneSnapshot>& snapshots, int width, int height,
                     std::optional<double> azimuthDegrees, std::optional<double> elevationDegrees,
                     std::optional<double> distance) {
  Bounds box;
  for (const SceneSnapshot& s : snapshots) box.add(drawer.framedBounds(s));
  return frameBox(drawer, box, width, height, azimuthDegrees, elevationDegrees, distance);
}

FramedView frameBox(const SceneDrawer& drawer, const Bounds& box, int width, int height,
                    std::optional<double> azimuthDegrees, std::optional<double> elevationDegrees,
                    std::optional<double> distance) {
  constexpr double kRadian = std::numbers::pi / 180;
  FramedView view;
  view.width = width;
  view.height = height;
  const float azimuth = azimuthDegrees ? static_cast<float>(*azimuthDegrees * kRadian) : kDefaultAzimuth;
  const float elevation = elevationDegrees ? static_cast<float>(*elevationDegrees * kRadian) : kDefaultElevation;
  view.camera = frameBounds(box, static_cast<float>(width) / static_cast<float>(height), azimuth, elevation);
  if (distance) view.camera.distance = static_cast<float>(*distance);
  view.radius = std::max(box.radius(), 1e-3f);
  view.groundHeight = drawer.groundPlane();
  if (!view.groundHeight && !box.empty()) view.groundHeight = box.lo.y() - 0.15f * view.radius;
  view.tubeRadius = drawer.tubeRadius(box);
  return view;
}

Image drawSnapshot(const SceneDrawer& drawer, const SceneSnapshot& snapshot, const FramedView& view, Renderer& renderer,
                   OffscreenContext& context, DrawFrame& frame) {
  drawer.build(snapshot, view.tubeRadius, frame);
  frame.groundHeight = view.groundHeight;
  renderer.draw(frame, view.camera, Viewport{0, 0, context.width(), context.height()}, view.radius,
                view.camera.azimuth);
  const int factor = context.width() / view.width;
  return downsample(context.finish(), context.width(), context.height(), factor);
}

}  // namespace weftrender
