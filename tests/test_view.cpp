// `weft view` from outside: without a display it says so and exits non-zero; under a
// virtual X display (xvfb-run, from tools/setup.sh) it runs a few hundred frames of the
// split screen and writes a screenshot, read back here.
// WEFT_CLI_PATH is the binary's path, given by CMake ($<TARGET_FILE:weft_cli>).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "png_image.hpp"
#include "support/cli_runner.hpp"

#ifndef WEFT_CLI_PATH
#error "WEFT_CLI_PATH must name the weft binary"
#endif

namespace weft::test {
namespace {

// Cloth (a deep red front, a cream back) is warm; the sky, the grid and the shadows are not.
bool warm(const std::uint8_t* p) { return p[0] > p[2] + 25 && p[0] >= p[1]; }

double warmShare(const weftrender::Image& image, int x0, int x1) {
  long count = 0;
  for (int y = 0; y < image.height; ++y)
    for (int x = x0; x < x1; ++x) count += warm(image.pixel(x, y)) ? 1 : 0;
  return static_cast<double>(count) / (static_cast<double>(x1 - x0) * image.height);
}

TEST(View, WithoutADisplayItSaysSoAndFails) {
  const CliRun run = runProgram(
      "env", std::string("-u DISPLAY -u WAYLAND_DISPLAY '") + WEFT_CLI_PATH + "' view flag --scene-size 8 --frames 5",
      Stderr::Capture);
  EXPECT_EQ(run.exitCode, 2) << run.out << run.err;
  EXPECT_NE(run.err.find("no display"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("weft render"), std::string::npos) << run.err;  // what to use instead
}

TEST(View, SplitScreenUnderAVirtualDisplay) {
  const std::string shot = ::testing::TempDir() + "weft_view_screenshot_" + std::to_string(getpid()) + ".png";
  std::filesystem::remove(shot);
  // 300 frames of the 16 x 16 flag, RK4 on the left and symplectic Euler on the right.
  const CliRun run = runProgram("xvfb-run",
                                std::string("-a -s '-screen 0 640x480x24' '") + WEFT_CLI_PATH +
                                    "' view flag --scene-size 16 --compare symplectic --frames 300 "
                                    "--size 320x240 --screenshot '" +
                                    shot + "'",
                                Stderr::Capture);
  ASSERT_EQ(run.exitCode, 0) << run.out << run.err;
  EXPECT_NE(run.out.find("300 frames"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("It runs until closed: the scene's length ("), std::string::npos) << run.out;
  const weftrender::Image image = weftrender::readPng(shot);
  ASSERT_EQ(image.width, 320);
  ASSERT_EQ(image.height, 240);
  // The cloth in each half (the same scene under two integrators), not filling it.
  for (const auto& [x0, x1] : {std::pair{0, 160}, std::pair{160, 320}}) {
    SCOPED_TRACE(x0);
    EXPECT_GT(warmShare(image, x0, x1), 0.02);
    EXPECT_LT(warmShare(image, x0, x1), 0.8);
  }
  // The readout: white text on a dark panel in the top left corner of each pane.
  for (const int x0 : {0, 160}) {
    int dark = 0, white = 0;
    for (int y = 0; y < 30; ++y)
      for (int x = x0; x < x0 + 100; ++x) {
        const std::uint8_t* p = image.pixel(x, y);
        dark += p[0] < 140 && p[1] < 140 && p[2] < 140;  // the sky and the grid are above 180
        white += p[0] > 230 && p[1] > 230 && p[2] > 230;
      }
    EXPECT_GT(dark, 300) << x0;
    EXPECT_GT(white, 50) << x0;
  }
  std::filesystem::remove(shot);
}

}  // namespace
}  // namespace weft::test
