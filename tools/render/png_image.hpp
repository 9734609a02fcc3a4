// tools/render/png_image.hpp — 8-bit RGB images in and out of PNG files (libpng).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace weftrender {

/// An 8-bit RGB image, rows from the top.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // (height x width x 3)
  std::uint8_t* pixel(int x, int y) { return &rgb[3 * (static_cast<std::size_t>(y) * width + x)]; }
  const std::uint8_t* pixel(int x, int y) const { return &rgb[3 * (static_cast<std::size_t>(y) * width + x)]; }
};

/// Writes `image` as an RGB PNG (compression 9), through `path`.tmp renamed to `path` once
/// complete. Throws std::runtime_error naming the path.
void writePng(const std::string& path, const Image& image);

/// Reads a PNG (any bit depth and colour type, converted to 8-bit RGB). Throws
/// std::runtime_error naming the path.
Image readPng(const std::string& path);

/// The mean of each factor x factor block of an RGBA buffer whose rows run from the bottom
/// (OpenGL's order), as RGB rows from the top: supersampling's resolve.
Image downsample(const std::uint8_t* rgba, int width, int height, int factor);

}  // namespace weftrender
