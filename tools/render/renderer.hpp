// tools/render/renderer.hpp — draws a DrawFrame with OpenGL 3.3 core: the one renderer of
// `weft render` (offscreen, OSMesa) and `weft view` (a GLFW window).
//
// Design note
// -----------
// Per viewport, in this order:
//   1. background: a vertical gradient (one full-screen triangle, no depth);
//   2. ground grid at DrawFrame::groundHeight: a square of 16 scene radii around the target
//      whose fragment shader draws minor lines every `spacing` and major ones every 5
//      (spacing: 1, 2 or 5 x 10^k near a quarter of the scene radius), anti-aliased with
//      fwidth and faded out with the distance from the target;
//   3. shadows: every mesh again, flattened onto the ground along the key light
//      (p - L (p.y - g) / L.y), blended dark, the stencil letting each pixel be darkened
//      once;
//   4. the meshes, lit in world space: a hemisphere ambient (sky above, earth below), a
//      warm key light and a cool fill from the other side, a Blinn specular, then linear to
//      sRGB. Culling is off and the fragment shader flips the normal of a back-facing
//      fragment and takes the mesh's back colour: both sides of the cloth are lit.
// The key light comes from the upper left of a camera at `lightAzimuth`, so a picture
// taken from any side is lit from the front. Vertex data is streamed each frame (one
// vertex array, position and normal buffers and an index buffer per mesh slot, reused).
#pragma once

#include <vector>

#include "camera.hpp"
#include "draw_scene.hpp"
#include "gl_api.hpp"

namespace weftrender {

struct Viewport {
  int x = 0, y = 0, width = 1, height = 1;  // pixels, from the bottom left
};

class Renderer {
 public:
  /// Compiles the shaders (a context must be current). Throws std::runtime_error with the
  /// compiler's log when one fails.
  explicit Renderer(const GlApi& gl);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Draws `frame` into `viewport`. `sceneRadius` (m) sizes the clip planes, the grid and
  /// the tubes; `lightAzimuth` (rad) places the key light (see the design note).
  void draw(const DrawFrame& frame, const OrbitCamera& camera, const Viewport& viewport, float sceneRadius,
            float lightAzimuth);
  /// Flat 2D triangles over what is drawn (x, y pairs in pixels from the viewport's bottom
  /// left; text_overlay.hpp makes text of them), in `colour` (sRGB, alpha blended).
  void drawOverlay(const std::vector<float>& triangles, const Eigen::Vector4f& colour, const Viewport& viewport);

 private:
  struct Slot {
    GLuint vertexArray = 0, positions = 0, normals = 0, indices = 0;
  };
  GLuint program(const char* vertex, const char* fragment, const char* name);
  Slot makeSlot();
  Slot& slot(std::size_t i);
  void upload(const DrawMesh& mesh, Slot& s);

  GlApi gl_;
  GLuint meshProgram_ = 0, groundProgram_ = 0, backgroundProgram_ = 0;
  GLuint emptyArray_ = 0;  // core profile: a vertex array must be bound to draw
  Slot ground_, overlay_;
  std::vector<Slot> slots_;
};

}  // namespace weftrender
