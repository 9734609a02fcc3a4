#include "offscreen_context.hpp"

#include <GL/osmesa.h>
#include <dlfcn.h>

#include <stdexcept>
#include <string>

namespace weftrender {

namespace {
struct OsMesa {
  decltype(&OSMesaCreateContextAttribs) createContextAttribs = nullptr;
  decltype(&OSMesaMakeCurrent) makeCurrent = nullptr;
  decltype(&OSMesaDestroyContext) destroyContext = nullptr;
  decltype(&OSMesaGetProcAddress) getProcAddress = nullptr;
};

/// The library's entry points, loaded once (the handle is kept for the process).
const OsMesa& osMesa() {
  static const OsMesa api = [] {
    OsMesa a;
    void* library = dlopen("libOSMesa.so.8", RTLD_NOW | RTLD_LOCAL);
    if (!library) library = dlopen("libOSMesa.so", RTLD_NOW | RTLD_LOCAL);
    if (!library)
      throw std::runtime_error(std::string("cannot load Mesa's offscreen renderer (libOSMesa.so.8: Debian's "
                                           "libosmesa6, installed by tools/setup.sh): ") +
                               dlerror());
    a.createContextAttribs =
        reinterpret_cast<decltype(a.createContextAttribs)>(dlsym(library, "OSMesaCreateContextAttribs"));
    a.makeCurrent = reinterpret_cast<decltype(a.makeCurrent)>(dlsym(library, "OSMesaMakeCurrent"));
    a.destroyContext = reinterpret_cast<decltype(a.destroyContext)>(dlsym(library, "OSMesaDestroyContext"));
    a.getProcAddress = reinterpret_cast<decltype(a.getProcAddress)>(dlsym(library, "OSMesaGetProcAddress"));
    if (!a.createContextAttribs || !a.makeCurrent || !a.destroyContext || !a.getProcAddress)
      throw std::runtime_error("libOSMesa lacks OSMesaCreateContextAttribs (Mesa 11.2 or newer is needed)");
    return a;
  }();
  return api;
}

const OsMesa* gApi = nullptr;  // for the lookup below (a plain function pointer)
void* lookup(const char* name) { return reinterpret_cast<void*>(gApi->getProcAddress(name)); }
}  // namespace

OffscreenContext::OffscreenContext(int width, int height)
    : width_(width), height_(height), pixels_(4ull * static_cast<std::size_t>(width) * height) {
  const OsMesa& api = osMesa();
  const int attributes[] = {OSMESA_FORMAT,
                            OSMESA_RGBA,
                            OSMESA_DEPTH_BITS,
                            24,
                            OSMESA_STENCIL_BITS,
                            8,
                            OSMESA_PROFILE,
                            OSMESA_CORE_PROFILE,
                            OSMESA_CONTEXT_MAJOR_VERSION,
                            3,
                            OSMESA_CONTEXT_MINOR_VERSION,
                            3,
                            0};
  OSMesaContext context = api.createContextAttribs(attributes, nullptr);
  if (!context) throw std::runtime_error("OSMesa gives no OpenGL 3.3 core context");
  context_ = context;
  if (!api.makeCurrent(context, pixels_.data(), GL_UNSIGNED_BYTE, width, height)) {
    api.destroyContext(context);
    throw std::runtime_error("OSMesa cannot render into a " + std::to_string(width) + " x " + std::to_string(height) +
                             " buffer");
  }
  gApi = &api;
  try {
    gl_ = loadGl(lookup);
  } catch (...) {
    api.destroyContext(context);
    throw;
  }
}

OffscreenContext::~OffscreenContext() { osMesa().destroyContext(static_cast<OSMesaContext>(context_)); }

const std::uint8_t* OffscreenContext::finish() {
  gl_.Finish();
  return pixels_.data();
}

const char* OffscreenContext::renderer() const { return reinterpret_cast<const char*>(gl_.GetString(GL_RENDERER)); }

}  // namespace weftrender
