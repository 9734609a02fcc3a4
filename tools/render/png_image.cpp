#include "png_image.hpp"

#include <png.h>

#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>

namespace weftrender {

namespace {
struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

[[noreturn]] void pngError(png_structp png, png_const_charp message) {
  auto* text = static_cast<std::string*>(png_get_error_ptr(png));
  if (text) *text = message;
  png_longjmp(png, 1);
}
}  // namespace

// libpng reports errors by longjmp: nothing with a destructor may live between setjmp and
// the calls that can jump, so the writes and reads are done in plain functions below with
// C resources only, and the C++ objects are set up around them.
namespace {
bool writeRows(std::FILE* f, const Image& image, std::string& error) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, pngError, nullptr);
  if (!png) return false;
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_init_io(png, f);
  png_set_compression_level(png, 9);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), 8,
               PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (int y = 0; y < image.height; ++y) png_write_row(png, image.pixel(0, y));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

bool readRows(std::FILE* f, Image& image, std::string& error) {
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &error, pngError, nullptr);
  if (!png) return false;
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  png_init_io(png, f);
  png_read_info(png, info);
  const png_uint_32 w = png_get_image_width(png, info), h = png_get_image_height(png, info);
  png_set_expand(png);
  png_set_strip_16(png);
  png_set_strip_alpha(png);
  png_set_gray_to_rgb(png);
  png_read_update_info(png, info);
  if (w == 0 || h == 0 || w > 65536 || h > 65536 || png_get_rowbytes(png, info) != 3 * w) {
    error = "unexpected image layout";
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  if (image.rgb.size() != 3ull * w * h) {  // sized by the caller from a first pass: see readPng
    image.width = static_cast<int>(w);
    image.height = static_cast<int>(h);
    png_destroy_read_struct(&png, &info, nullptr);
    return true;
  }
  for (png_uint_32 y = 0; y < h; ++y) png_read_row(png, image.pixel(0, static_cast<int>(y)), nullptr);
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return true;
}
}  // namespace

void writePng(const std::string& path, const Image& image) {
  const std::string tmp = path + ".tmp";
  std::string error;
  bool ok = false;
  {
    File f(std::fopen(tmp.c_str(), "wb"));
    if (!f) throw std::runtime_error("cannot write '" + path + "': " + std::strerror(errno));
    ok = writeRows(f.get(), image, error);
    ok = std::fflush(f.get()) == 0 && ok;
  }
  std::error_code renameError;
  if (ok) std::filesystem::rename(tmp, path, renameError);
  if (!ok || renameError) {
    std::remove(tmp.c_str());
    throw std::runtime_error("cannot write '" + path + "': " + (error.empty() ? renameError.message() : error));
  }
}

Image readPng(const std::string& path) {
  Image image;
  std::string error;
  // Two passes over the file: the header gives the size, then the rows are read into an
  // image of that size (no C++ allocation while libpng may longjmp).
  for (int pass = 0; pass < 2; ++pass) {
    File f(std::fopen(path.c_str(), "rb"));
    if (!f) throw std::runtime_error("cannot read '" + path + "': " + std::strerror(errno));
    if (!readRows(f.get(), image, error)) throw std::runtime_error("cannot read '" + path + "' as PNG: " + error);
    if (pass == 0) image.rgb.assign(3ull * static_cast<std::size_t>(image.width) * image.height, 0);
  }
  return image;
}

Image downsample(const std::uint8_t* rgba, int width, int height, int factor) {
  Image image;
  image.width = width / factor;
  image.height = height / factor;
  image.rgb.resize(3ull * static_cast<std::size_t>(image.width) * image.height);
  const int n = factor * factor;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      int sum[3] = {0, 0, 0};
      for (int dy = 0; dy < factor; ++dy) {
        const int row = height - 1 - (y * factor + dy);  // bottom-up source
        for (int dx = 0; dx < factor; ++dx) {
          const std::uint8_t* p = rgba + 4 * (static_cast<std::size_t>(row) * width + x * factor + dx);
          for (int k = 0; k < 3; ++k) sum[k] += p[k];
        }
      }
      std::uint8_t* out = image.pixel(x, y);
      for (int k = 0; k < 3; ++k) out[k] = static_cast<std::uint8_t>((sum[k] + n / 2) / n);
    }
  return image;
}

}  // namespace weftrender
