#include "renderer.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace weftrender {

namespace {

const char* kMeshVertex = R"(#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
uniform mat4 viewProjection;
uniform mat4 model;
out vec3 worldPosition;
out vec3 worldNormal;
void main() {
  vec4 p = model * vec4(position, 1.0);
  worldPosition = p.xyz;
  worldNormal = normal;
  gl_Position = viewProjection * p;
}
)";

const char* kMeshFragment = R"(#version 330 core
in vec3 worldPosition;
in vec3 worldNormal;
uniform vec3 frontColour;
uniform vec3 backColour;
uniform vec3 eye;
uniform vec3 keyDirection;
uniform vec3 fillDirection;
uniform vec4 flatColour;  // alpha > 0: the shadow pass, this colour as it is
out vec4 colour;
void main() {
  if (flatColour.a > 0.0) {
    colour = flatColour;
    return;
  }
  vec3 n = normalize(worldNormal);
  vec3 base = frontColour;
  if (!gl_FrontFacing) {
    n = -n;
    base = backColour;
  }
  vec3 v = normalize(eye - worldPosition);
  float key = max(dot(n, keyDirection), 0.0);
  float fill = max(dot(n, fillDirection), 0.0);
  vec3 ambient = mix(vec3(0.32, 0.28, 0.24), vec3(0.62, 0.72, 0.86), 0.5 + 0.5 * n.y);
  vec3 h = normalize(keyDirection + v);
  float specular = key > 0.0 ? 0.22 * pow(max(dot(n, h), 0.0), 48.0) : 0.0;
  vec3 lit = base * (0.42 * ambient + 0.92 * key * vec3(1.0, 0.96, 0.90) + 0.28 * fill * vec3(0.85, 0.90, 1.0)) +
             vec3(specular);
  colour = vec4(pow(clamp(lit, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
}
)";

const char* kGroundFragment = R"(#version 330 core
in vec3 worldPosition;
in vec3 worldNormal;
uniform vec3 centre;
uniform float spacing;
uniform float fadeRadius;
out vec4 colour;
float lines(vec2 c) {
  vec2 d = abs(fract(c - 0.5) - 0.5) / max(fwidth(c), vec2(1e-6));
  return 1.0 - min(min(d.x, d.y), 1.0);
}
void main() {
  vec2 c = worldPosition.xz / spacing;
  float minor = lines(c), major = lines(c / 5.0);
  vec3 base = vec3(0.80, 0.80, 0.78);
  vec3 shade = mix(base, vec3(0.52, 0.54, 0.58), max(0.55 * minor, 0.95 * major));
  float fade = 1.0 - smoothstep(0.45 * fadeRadius, fadeRadius, distance(worldPosition.xz, centre.xz));
  colour = vec4(pow(shade, vec3(1.0 / 2.2)), fade);
}
)";

const char* kBackgroundVertex = R"(#version 330 core
out float height;
void main() {
  vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);
  height = 0.5 * p.y + 0.5;
  gl_Position = vec4(p, 1.0, 1.0);
}
)";

const char* kBackgroundFragment = R"(#version 330 core
in float height;
out vec4 colour;
void main() { colour = vec4(mix(vec3(0.96, 0.96, 0.95), vec3(0.74, 0.82, 0.91), clamp(height, 0.0, 1.0)), 1.0); }
)";

/// 1, 2 or 5 x 10^k, the nearest at or below `x` (> 0).
float niceStep(float x) {
  const float decade = std::pow(10.f, std::floor(std::log10(x)));
  const float m = x / decade;
  return decade * (m >= 5 ? 5.f : m >= 2 ? 2.f : 1.f);
}

Eigen::Vector3f direction(float azimuth, float elevation) {
  return {std::cos(elevation) * std::sin(azimuth), std::sin(elevation), std::cos(elevation) * std::cos(azimuth)};
}

}  // namespace

Renderer::Renderer(const GlApi& gl) : gl_(gl) {
  meshProgram_ = program(kMeshVertex, kMeshFragment, "mesh");
  groundProgram_ = program(kMeshVertex, kGroundFragment, "ground");
  backgroundProgram_ = program(kBackgroundVertex, kBackgroundFragment, "background");
  gl_.GenVertexArrays(1, &emptyArray_);
}

Renderer::~Renderer() {
  const auto release = [this](Slot& s) {
    if (s.vertexArray) gl_.DeleteVertexArrays(1, &s.vertexArray);
    for (GLuint* b : {&s.positions, &s.normals, &s.indices})
      if (*b) gl_.DeleteBuffers(1, b);
  };
  release(ground_);
  release(overlay_);
  for (Slot& s : slots_) release(s);
  gl_.DeleteVertexArrays(1, &emptyArray_);
  for (GLuint p : {meshProgram_, groundProgram_, backgroundProgram_}) gl_.DeleteProgram(p);
}

GLuint Renderer::program(const char* vertex, const char* fragment, const char* name) {
  const auto compile = [&](GLenum type, const char* source) {
    const GLuint shader = gl_.CreateShader(type);
    gl_.ShaderSource(shader, 1, &source, nullptr);
    gl_.CompileShader(shader);
    GLint ok = 0;
    gl_.GetShaderiv(shader, GL_COMPILE_STATUS, &ok);
    if (!ok) {
      char log[2048] = {};
      gl_.GetShaderInfoLog(shader, sizeof log, nullptr, log);
      gl_.DeleteShader(shader);
      throw std::runtime_error(std::string("the ") + name + (type == GL_VERTEX_SHADER ? " vertex" : " fragment") +
                               " shader does not compile: " + log);
    }
    return shader;
  };
  const GLuint vs = compile(GL_VERTEX_SHADER, vertex), fs = compile(GL_FRAGMENT_SHADER, fragment);
  const GLuint p = gl_.CreateProgram();
  gl_.AttachShader(p, vs);
  gl_.AttachShader(p, fs);
  gl_.LinkProgram(p);
  gl_.DeleteShader(vs);
  gl_.DeleteShader(fs);
  GLint ok = 0;
  gl_.GetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl_.GetProgramInfoLog(p, sizeof log, nullptr, log);
    gl_.DeleteProgram(p);
    throw std::runtime_error(std::string("the ") + name + " shaders do not link: " + log);
  }
  return p;
}

Renderer::Slot Renderer::makeSlot() {
  Slot s;
  gl_.GenVertexArrays(1, &s.vertexArray);
  gl_.GenBuffers(1, &s.positions);
  gl_.GenBuffers(1, &s.normals);
  gl_.GenBuffers(1, &s.indices);
  gl_.BindVertexArray(s.vertexArray);
  gl_.BindBuffer(GL_ARRAY_BUFFER, s.positions);
  gl_.EnableVertexAttribArray(0);
  gl_.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
  gl_.BindBuffer(GL_ARRAY_BUFFER, s.normals);
  gl_.EnableVertexAttribArray(1);
  gl_.VertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
  gl_.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, s.indices);  // recorded in the vertex array
  gl_.BindVertexArray(0);
  return s;
}

Renderer::Slot& Renderer::slot(std::size_t i) {
  while (slots_.size() <= i) slots_.push_back(makeSlot());
  return slots_[i];
}

void Renderer::upload(const DrawMesh& mesh, Slot& s) {
  gl_.BindVertexArray(s.vertexArray);
  gl_.BindBuffer(GL_ARRAY_BUFFER, s.positions);
  gl_.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(mesh.positions.size() * sizeof(float)), mesh.positions.data(),
                 GL_STREAM_DRAW);
  gl_.BindBuffer(GL_ARRAY_BUFFER, s.normals);
  gl_.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(mesh.normals.size() * sizeof(float)), mesh.normals.data(),
                 GL_STREAM_DRAW);
  gl_.BufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(mesh.indices.size() * sizeof(std::uint32_t)),
                 mesh.indices.data(), GL_STREAM_DRAW);
}

void Renderer::draw(const DrawFrame& frame, const OrbitCamera& camera, const Viewport& vp, float sceneRadius,
                    float lightAzimuth) {
  const float radius = std::max(sceneRadius, 1e-3f);
  gl_.Viewport(vp.x, vp.y, vp.width, vp.height);
  gl_.Scissor(vp.x, vp.y, vp.width, vp.height);
  gl_.Enable(GL_SCISSOR_TEST);
  gl_.ClearStencil(0);
  gl_.Clear(GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
  gl_.Disable(GL_CULL_FACE);

  // 1. Background.
  gl_.Disable(GL_DEPTH_TEST);
  gl_.Disable(GL_BLEND);
  gl_.UseProgram(backgroundProgram_);
  gl_.BindVertexArray(emptyArray_);
  gl_.DrawArrays(GL_TRIANGLES, 0, 3);

  const Eigen::Matrix4f viewProjection =
      camera.projection(static_cast<float>(vp.width) / static_cast<float>(vp.height), radius) * camera.view();
  const Eigen::Matrix4f identity = Eigen::Matrix4f::Identity();
  // Key light: upper left of the camera at lightAzimuth; fill: lower right, behind.
  const Eigen::Vector3f key = direction(lightAzimuth - 0.7f, 0.85f);
  const Eigen::Vector3f fill = direction(lightAzimuth + 2.2f, 0.3f);
  const Eigen::Vector3f eye = camera.eye();
  gl_.Enable(GL_DEPTH_TEST);
  gl_.DepthFunc(GL_LEQUAL);
  gl_.DepthMask(GL_TRUE);

  // 2. Ground grid.
  const bool ground = frame.groundHeight.has_value();
  const float g = frame.groundHeight.value_or(0.f);
  if (ground) {
    if (ground_.vertexArray == 0) ground_ = makeSlot();
    const float h = 8.f * radius, cx = camera.target.x(), cz = camera.target.z();
    DrawMesh quad;
    quad.positions = {cx - h, g, cz - h, cx + h, g, cz - h, cx + h, g, cz + h, cx - h, g, cz + h};
    quad.normals = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
    quad.indices = {0, 2, 1, 0, 3, 2};
    upload(quad, ground_);
    gl_.UseProgram(groundProgram_);
    gl_.UniformMatrix4fv(gl_.GetUniformLocation(groundProgram_, "viewProjection"), 1, GL_FALSE, viewProjection.data());
    gl_.UniformMatrix4fv(gl_.GetUniformLocation(groundProgram_, "model"), 1, GL_FALSE, identity.data());
    gl_.Uniform3fv(gl_.GetUniformLocation(groundProgram_, "centre"), 1, camera.target.data());
    gl_.Uniform1f(gl_.GetUniformLocation(groundProgram_, "spacing"), niceStep(0.25f * radius));
    gl_.Uniform1f(gl_.GetUniformLocation(groundProgram_, "fadeRadius"), 6.f * radius);
    gl_.Enable(GL_BLEND);
    gl_.BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    gl_.DrawElements(GL_TRIANGLES, 6, GL_UNSIGNED_INT, nullptr);
  }

  gl_.UseProgram(meshProgram_);
  gl_.UniformMatrix4fv(gl_.GetUniformLocation(meshProgram_, "viewProjection"), 1, GL_FALSE, viewProjection.data());
  gl_.Uniform3fv(gl_.GetUniformLocation(meshProgram_, "eye"), 1, eye.data());
  gl_.Uniform3fv(gl_.GetUniformLocation(meshProgram_, "keyDirection"), 1, key.data());
  gl_.Uniform3fv(gl_.GetUniformLocation(meshProgram_, "fillDirection"), 1, fill.data());
  const GLint modelAt = gl_.GetUniformLocation(meshProgram_, "model");
  const GLint flatAt = gl_.GetUniformLocation(meshProgram_, "flatColour");
  const GLint frontAt = gl_.GetUniformLocation(meshProgram_, "frontColour");
  const GLint backAt = gl_.GetUniformLocation(meshProgram_, "backColour");
  for (std::size_t i = 0; i < frame.meshes.size(); ++i) upload(frame.meshes[i], slot(i));

  // 3. Shadows on the ground, each pixel darkened once.
  if (ground && key.y() > 0.05f) {
    // p' = p - L (p.y - g') / L.y with g' a hair above the ground: column-major 4 x 4.
    const float lift = g + 1e-3f * radius;
    Eigen::Matrix4f flatten = Eigen::Matrix4f::Identity();
    flatten.block<3, 1>(0, 1) -= key / key.y();
    flatten.block<3, 1>(0, 3) += key * (lift / key.y());
    gl_.UniformMatrix4fv(modelAt, 1, GL_FALSE, flatten.data());
    const float shadow[4] = {0.f, 0.f, 0.05f, 0.28f};
    gl_.Uniform4fv(flatAt, 1, shadow);
    gl_.Enable(GL_STENCIL_TEST);
    gl_.StencilFunc(GL_EQUAL, 0, 0xff);
    gl_.StencilOp(GL_KEEP, GL_KEEP, GL_INCR);
    gl_.DepthMask(GL_FALSE);
    gl_.Enable(GL_POLYGON_OFFSET_FILL);
    gl_.PolygonOffset(-1.f, -1.f);
    for (std::size_t i = 0; i < frame.meshes.size(); ++i) {
      if (!frame.meshes[i].castsShadow || frame.meshes[i].indices.empty()) continue;
      gl_.BindVertexArray(slots_[i].vertexArray);
      gl_.DrawElements(GL_TRIANGLES, static_cast<GLsizei>(frame.meshes[i].indices.size()), GL_UNSIGNED_INT, nullptr);
    }
    gl_.Disable(GL_POLYGON_OFFSET_FILL);
    gl_.Disable(GL_STENCIL_TEST);
    gl_.DepthMask(GL_TRUE);
  }

  // 4. The meshes.
  gl_.Disable(GL_BLEND);
  gl_.UniformMatrix4fv(modelAt, 1, GL_FALSE, identity.data());
  const float none[4] = {0.f, 0.f, 0.f, 0.f};
  gl_.Uniform4fv(flatAt, 1, none);
  for (std::size_t i = 0; i < frame.meshes.size(); ++i) {
    const DrawMesh& m = frame.meshes[i];
    if (m.indices.empty()) continue;
    gl_.Uniform3fv(frontAt, 1, m.front.data());
    gl_.Uniform3fv(backAt, 1, m.back.data());
    gl_.BindVertexArray(slots_[i].vertexArray);
    gl_.DrawElements(GL_TRIANGLES, static_cast<GLsizei>(m.indices.size()), GL_UNSIGNED_INT, nullptr);
  }
  gl_.BindVertexArray(0);
  gl_.Disable(GL_SCISSOR_TEST);
}

}  // namespace weftrender

namespace weftrender {

void Renderer::drawOverlay(const std::vector<float>& triangles, const Eigen::Vector4f& colour, const Viewport& vp) {
  if (triangles.empty()) return;
  if (overlay_.vertexArray == 0) overlay_ = makeSlot();
  // The 2D points as 3D positions at z = 0 (normals unused by the flat colour).
  DrawMesh mesh;
  const std::size_t n = triangles.size() / 2;
  mesh.positions.resize(3 * n);
  mesh.normals.assign(3 * n, 0.f);
  mesh.indices.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    mesh.positions[3 * i] = triangles[2 * i];
    mesh.positions[3 * i + 1] = triangles[2 * i + 1];
    mesh.positions[3 * i + 2] = 0.f;
    mesh.indices[i] = static_cast<std::uint32_t>(i);
  }
  upload(mesh, overlay_);
  // Pixels to clip space.
  Eigen::Matrix4f pixels = Eigen::Matrix4f::Identity();
  pixels(0, 0) = 2.f / static_cast<float>(vp.width);
  pixels(1, 1) = 2.f / static_cast<float>(vp.height);
  pixels(0, 3) = -1.f;
  pixels(1, 3) = -1.f;
  const Eigen::Matrix4f identity = Eigen::Matrix4f::Identity();
  gl_.Viewport(vp.x, vp.y, vp.width, vp.height);
  gl_.Scissor(vp.x, vp.y, vp.width, vp.height);
  gl_.Enable(GL_SCISSOR_TEST);
  gl_.Disable(GL_DEPTH_TEST);
  gl_.Enable(GL_BLEND);
  gl_.BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  gl_.UseProgram(meshProgram_);
  gl_.UniformMatrix4fv(gl_.GetUniformLocation(meshProgram_, "viewProjection"), 1, GL_FALSE, pixels.data());
  gl_.UniformMatrix4fv(gl_.GetUniformLocation(meshProgram_, "model"), 1, GL_FALSE, identity.data());
  // The flat path draws a colour as it is when its alpha is > 0.
  const Eigen::Vector4f c(colour.x(), colour.y(), colour.z(), std::max(colour.w(), 1e-3f));
  gl_.Uniform4fv(gl_.GetUniformLocation(meshProgram_, "flatColour"), 1, c.data());
  gl_.DrawElements(GL_TRIANGLES, static_cast<GLsizei>(n), GL_UNSIGNED_INT, nullptr);
  gl_.BindVertexArray(0);
  gl_.Disable(GL_BLEND);
  gl_.Disable(GL_SCISSOR_TEST);
}

}  // namespace weftrender
