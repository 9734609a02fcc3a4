// `weft render` from outside: pictures of built-in scenes read back with libpng (their
// size, the cloth against the background, the automatic camera's framing) and the
// messages for bad options. Also the camera's framing rule itself.
// WEFT_CLI_PATH is the binary's path, given by CMake ($<TARGET_FILE:weft_cli>).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "camera.hpp"
#include "png_image.hpp"
#include "support/cli_runner.hpp"

#ifndef WEFT_CLI_PATH
#error "WEFT_CLI_PATH must name the weft binary"
#endif

namespace weft::test {
namespace {

using weftrender::Image;

CliRun render(const std::string& args) { return runProgram(WEFT_CLI_PATH, "render " + args, Stderr::Capture); }

/// A directory of this test's own (ctest runs tests side by side; other builds share /tmp).
std::string freshDirectory(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "weft_render_" + name + "_" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  return dir;
}

// Cloth (a deep red front, a cream back) and rigid bodies (amber) are warm; the sky, the
// ground grid, the shadows and the obstacles (blue-grey) are not.
bool warm(const std::uint8_t* p) { return p[0] > p[2] + 25 && p[0] >= p[1]; }
// Obstacles: a dark blue-grey (the sky is blue but light).
bool steel(const std::uint8_t* p) { return p[2] > p[0] + 12 && p[1] < 175 && p[0] < 160; }

struct Coverage {
  double share = 0;            // of the picture's pixels
  bool touchesBorder = false;  // a pixel in the outermost row or column
};

template <class Pred>
Coverage coverage(const Image& image, Pred pred) {
  Coverage c;
  long count = 0;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      if (pred(image.pixel(x, y))) {
        ++count;
        if (x == 0 || y == 0 || x == image.width - 1 || y == image.height - 1) c.touchesBorder = true;
      }
  c.share = static_cast<double>(count) / (static_cast<double>(image.width) * image.height);
  return c;
}

TEST(Render, FlagPicturesFrameTheCloth) {
  const std::string dir = freshDirectory("flag");
  const CliRun run = render("flag --scene-size 16 --steps 400 --every 200 --size 160x120 --out '" + dir + "'");
  ASSERT_EQ(run.exitCode, 0) << run.out << run.err;
  EXPECT_NE(run.out.find("3 pictures of 160 x 120"), std::string::npos) << run.out;
  for (const char* name : {"frame_000000.png", "frame_000001.png", "frame_000002.png"}) {
    SCOPED_TRACE(name);
    const Image image = weftrender::readPng(dir + "/" + name);
    ASSERT_EQ(image.width, 160);
    ASSERT_EQ(image.height, 120);
    // The camera frames the whole run: the cloth is inside the picture, not a speck.
    const Coverage cloth = coverage(image, warm);
    EXPECT_GT(cloth.share, 0.03);
    EXPECT_LT(cloth.share, 0.8);
    EXPECT_FALSE(cloth.touchesBorder);
  }
  // Nothing else in the directory: no temporary files left behind.
  int files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 3);
  // The cloth moves between pictures: they differ.
  const Image first = weftrender::readPng(dir + "/frame_000000.png");
  const Image last = weftrender::readPng(dir + "/frame_000002.png");
  EXPECT_NE(first.rgb, last.rgb);
  std::filesystem::remove_all(dir);
}

TEST(Render, ObstaclesAndRigidBodiesAreDrawn) {
  const std::string dir = freshDirectory("drape");
  CliRun run = render("drape --scene-size 16 --steps 0 --size 160x120 --out '" + dir + "'");
  ASSERT_EQ(run.exitCode, 0) << run.out << run.err;
  Image image = weftrender::readPng(dir + "/frame_000000.png");
  EXPECT_GT(coverage(image, warm).share, 0.02);   // the cloth
  EXPECT_GT(coverage(image, steel).share, 0.02);  // the sphere under it
  EXPECT_FALSE(coverage(image, steel).touchesBorder);

  // Rigid bodies only: the stack of boxes on a floor slab much larger than the stack (not
  // framed: the boxes fill a sensible share of the picture).
  run = render("stack --steps 0 --size 160x120 --out '" + dir + "'");
  ASSERT_EQ(run.exitCode, 0) << run.out << run.err;
  image = weftrender::readPng(dir + "/frame_000000.png");
  const Coverage boxes = coverage(image, warm);
  EXPECT_GT(boxes.share, 0.03);
  EXPECT_FALSE(boxes.touchesBorder);
  std::filesystem::remove_all(dir);
}

TEST(Render, CameraOptionTurnsTheView) {
  const std::string a = freshDirectory("camera_a"), b = freshDirectory("camera_b");
  ASSERT_EQ(render("drape --scene-size 8 --steps 0 --size 64x48 --out '" + a + "'").exitCode, 0);
  const CliRun run = render("drape --scene-size 8 --steps 0 --size 64x48 --camera 120,60 --out '" + b + "'");
  ASSERT_EQ(run.exitCode, 0) << run.err;
  EXPECT_NE(run.out.find("azimuth 120 deg, elevation 60 deg"), std::string::npos) << run.out;
  EXPECT_NE(weftrender::readPng(a + "/frame_000000.png").rgb, weftrender::readPng(b + "/frame_000000.png").rgb);
  std::filesystem::remove_all(a);
  std::filesystem::remove_all(b);
}

TEST(Render, BadInputsAreRefusedNamingTheOption) {
  const std::string dir = freshDirectory("bad");
  struct Case {
    std::string args, mentions1, mentions2;
  };
  // An unwritable --out: a directory under a regular file (root may write anywhere else).
  const std::string file = dir + "_file";
  std::ofstream(file) << "not a directory";
  const Case cases[] = {
      {"flag --size 0x5 --out '" + dir + "'", "--size", "0x5"},
      {"flag --size 640 --out '" + dir + "'", "--size", "640"},
      {"flag --every 0 --out '" + dir + "'", "--every", "0"},
      {"flag --camera 10,95 --out '" + dir + "'", "--camera", "10,95"},
      {"flag --camera 1e308,0,1e308 --out '" + dir + "'", "--camera", "1e308,0,1e308"},
      {"flag --camera 10,20,1e300 --out '" + dir + "'", "--camera", "distance must be > 0 and at most 1e9 m"},
      {"flag --framing sideways --out '" + dir + "'", "--framing", "sideways"},
      {"flag --out '" + file + "/pictures'", "--out", file + "/pictures"},
      {"nosuchscene --out '" + dir + "'", "nosuchscene", "flag"},
      {"flag", "--out", "required"},
      {"flag --out '" + dir + "' --szie 3", "--szie", "--size"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.args);
    const CliRun run = render(c.args);
    EXPECT_EQ(run.exitCode, 2) << run.out << run.err;
    EXPECT_NE(run.err.find(c.mentions1), std::string::npos) << run.err;
    EXPECT_NE(run.err.find(c.mentions2), std::string::npos) << run.err;
  }
  std::filesystem::remove(file);
  std::filesystem::remove_all(dir);
}

// A scene file's output section is weft run's: render says it does not use it (its
// pictures go to --out), and writes nothing there.
TEST(Render, TheScenesOutputSectionIsNamedAsNotUsed) {
  const std::string dir = freshDirectory("unused");
  std::filesystem::create_directories(dir);
  const std::string file = dir + "/rope.json", frames = dir + "/frames";
  std::ofstream(file) << R"({"name": "rope", "dt": 0.001, "steps": 2, "bodies": [{"type": "rope", "particles": 5}],
    "output": {"directory": ")" +
                             frames + R"(", "every": 3}})";
  const CliRun run = render("'" + file + "' --out '" + dir + "/pictures' --steps 2 --size 64x48");
  EXPECT_EQ(run.exitCode, 0) << run.out << run.err;
  EXPECT_NE(run.err.find("weft render: note: output.directory applies to weft run's frames, and weft render draws "
                         "into --out (not used)"),
            std::string::npos)
      << run.err;
  EXPECT_NE(run.err.find("weft render: note: output.every"), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(frames));
  std::filesystem::remove_all(dir);
}

// With the stability check off nothing stops a state that overflows; render must not draw
// it as blank pictures and end "ok" (weft run says not_finite for the same file).
TEST(Render, AStateThatIsNotFiniteEndsThePicturesAndIsNotOk) {
  const std::string dir = freshDirectory("not_finite");
  std::filesystem::create_directories(dir);
  const std::string file = dir + "/overflow.json";
  std::ofstream(file) << R"({"name": "overflow", "dt": 2e-4, "steps": 3, "gravity": [0, -1e300, 0],
    "stability": {"enabled": false},
    "bodies": [{"type": "cloth_grid", "width": 12, "height": 12, "pins": [0, 11]}]})";
  const CliRun run = render("'" + file + "' --out '" + dir + "/pictures' --every 1 --size 64x48");
  EXPECT_EQ(run.exitCode, 3) << run.out << run.err;
  EXPECT_NE(run.out.find("not finite"), std::string::npos) << run.out;
  EXPECT_TRUE(std::filesystem::exists(dir + "/pictures/frame_000000.png"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/pictures/frame_000001.png"));
  std::filesystem::remove_all(dir);
}

TEST(RenderCamera, FramingKeepsEveryCornerInsideTheMargin) {
  weftrender::Bounds box;
  box.add(Eigen::Vector3f(-1.f, 0.f, -0.2f));
  box.add(Eigen::Vector3f(2.f, 0.5f, 0.3f));
  for (const float azimuth : {0.f, 0.6f, 2.f, -1.2f})
    for (const float elevation : {0.f, 0.4f, 1.2f}) {
      const float aspect = 4.f / 3.f, margin = 0.85f;
      const weftrender::OrbitCamera camera = weftrender::frameBounds(box, aspect, azimuth, elevation, margin);
      const Eigen::Matrix4f m = camera.projection(aspect, box.radius()) * camera.view();
      float largest = 0;
      for (int corner = 0; corner < 8; ++corner) {
        const Eigen::Vector4f p((corner & 1 ? box.hi : box.lo).x(), (corner & 2 ? box.hi : box.lo).y(),
                                (corner & 4 ? box.hi : box.lo).z(), 1.f);
        const Eigen::Vector4f clip = m * p;
        ASSERT_GT(clip.w(), 0.f);
        largest = std::max({largest, std::abs(clip.x() / clip.w()), std::abs(clip.y() / clip.w())});
      }
      // Inside the margin, and tight: some corner reaches it.
      EXPECT_LE(largest, margin + 1e-4f) << azimuth << " " << elevation;
      EXPECT_GE(largest, margin - 1e-4f) << azimuth << " " << elevation;
    }
}

}  // namespace
}  // namespace weft::test
