#include "gl_api.hpp"

#include <stdexcept>

namespace weftrender {

GlApi loadGl(GlLookup lookup) {
  GlApi gl;
#define WEFT_GL_LOAD(type, name)                        \
  gl.name = reinterpret_cast<type>(lookup("gl" #name)); \
  if (gl.name == nullptr)                               \
    throw std::runtime_error("the OpenGL context does not provide gl" #name " (OpenGL 3.3 core needed)");
  WEFT_GL_FUNCTIONS(WEFT_GL_LOAD)
#undef WEFT_GL_LOAD
  return gl;
}

}  // namespace weftrender
