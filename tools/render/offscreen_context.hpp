// tools/render/offscreen_context.hpp — an OpenGL 3.3 core context with no display and no
// GPU: Mesa's OSMesa (llvmpipe, or softpipe) rendering into memory.
//
// libOSMesa.so.8 is opened with dlopen (RTLD_LOCAL) when a context is made, not linked:
// the `weft` binary starts where Mesa is absent (only `weft render` then fails, saying
// so), and OSMesa's exported gl* symbols never meet libGL's in `weft view`'s process. The
// library stays loaded until the process ends (unloading Mesa's LLVM is not safe).
#pragma once

#include <cstdint>
#include <vector>

#include "gl_api.hpp"

namespace weftrender {

class OffscreenContext {
 public:
  /// A width x height RGBA colour buffer with depth and stencil, made current on this
  /// thread. Throws std::runtime_error when OSMesa cannot be loaded or gives no 3.3 core
  /// context.
  OffscreenContext(int width, int height);
  ~OffscreenContext();
  OffscreenContext(const OffscreenContext&) = delete;
  OffscreenContext& operator=(const OffscreenContext&) = delete;

  const GlApi& gl() const { return gl_; }
  int width() const { return width_; }
  int height() const { return height_; }
  /// The colour buffer after everything drawn so far has finished: RGBA, rows from the
  /// bottom.
  const std::uint8_t* finish();
  /// GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
  const char* renderer() const;

 private:
  int width_, height_;
  std::vector<std::uint8_t> pixels_;
  void* context_ = nullptr;  // OSMesaContext
  GlApi gl_;
};

}  // namespace weftrender
