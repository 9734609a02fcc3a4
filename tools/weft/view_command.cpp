#include "view_command.hpp"

#include <iostream>

#ifdef WEFT_HAVE_VIEW
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <dlfcn.h>

#include <Eigen/LU>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numbers>
#include <optional>
#include <sstream>
#include <vector>

#include "output_file.hpp"
#include "render_scene.hpp"
#include "text_overlay.hpp"
#include "unchecked_state.hpp"
#include "weft/io/scene.hpp"
#include "weft/weft.hpp"
#endif

namespace weftcli {

#ifndef WEFT_HAVE_VIEW

int viewScene(const ViewOptions&) {
  std::cerr << "weft view: this weft was built without the window (GLFW, OSMesa's header or libpng was not found "
               "when it was configured: run bash tools/setup.sh, then configure and build again)\n";
  return 2;
}

#else

namespace {

using Clock = std::chrono::steady_clock;
constexpr float kRadian = static_cast<float>(std::numbers::pi / 180);

/// What a rebuilt pane keeps of the one it replaces: the particles' state.
struct Carry {
  Eigen::MatrixX3d x, v;
  double time = 0;
};

struct Readout {
  std::string integrator, precision;
  double dt = 0;
  int threads = 1;
  double msPerStep = 0;
  std::int64_t steps = 0;  // last frame
  double time = 0, energy = 0;
  bool ok = true;
  std::string status;
};

/// One simulation of the scene, at either precision.
class Pane {
 public:
  virtual ~Pane() = default;
  virtual void advance(std::int64_t steps) = 0;
  virtual weftrender::SceneSnapshot snapshot(const weftrender::SceneDrawer& drawer) const = 0;
  virtual Readout readout() const = 0;
  virtual Carry carry() const = 0;
  virtual bool freeParticle(weft::Index i) const = 0;
  virtual void drag(weft::Index i, const Eigen::Vector3f& target) = 0;
  virtual void setTimeStep(double dt) = 0;
  virtual double msPerStep() const = 0;
  virtual const std::vector<weft::Index>& firstParticle() const = 0;
  virtual weftrender::SceneDrawer drawer() const = 0;
};

template <class S>
class PaneOf final : public Pane {
 public:
  PaneOf(const weft::SceneSpec& spec, const Carry* carry) {
    weft::AssembledScene<S> a = weft::assembleScene<S>(spec);
    first_ = a.firstParticle;
    sim_ = std::make_unique<weft::Simulation<S> >(std::move(a.built), a.options);
    // The particles carry over (rigid bodies would not: such a scene starts over).
    if (carry && !sim_->rigidWorld() && carry->x.rows() == sim_->model().particleCount()) {
      weft::State<S> s = sim_->state();
      s.x = carry->x.cast<S>();
      s.v = carry->v.cast<S>();
      s.time = carry->time;
      sim_->setState(s);
    }
  }
  void advance(std::int64_t steps) override {
    steps_ = 0;
    if (!status_.ok()) return;
    const auto start = Clock::now();
    while (steps_ < steps && (status_ = sim_->step()).ok()) ++steps_;
    const double ms = 1000 * std::chrono::duration<double>(Clock::now() - start).count();
    if (steps_ > 0) {
      const double now = ms / static_cast<double>(steps_);
      msPerStep_ = msPerStep_ > 0 ? 0.8 * msPerStep_ + 0.2 * now : now;
    }
  }
  weftrender::SceneSnapshot snapshot(const weftrender::SceneDrawer& drawer) const override {
    return drawer.snapshot(*sim_);
  }
  Readout readout() const override {
    Readout r;
    r.integrator = weft::integratorName(sim_->integrator());
    r.precision = sizeof(S) == 4 ? "float" : "double";
    r.dt = sim_->timeStep();
    r.threads = sim_->threadCount();
    r.msPerStep = msPerStep_;
    r.steps = steps_;
    r.time = sim_->state().time;
    r.energy = weft::energy(sim_->model(), sim_->state(), sim_->options().gravity).total();
    if (const weft::RigidWorld* rigid = sim_->rigidWorld()) r.energy += rigid->energy();
    // (With the stability check off nothing stops a state that overflowed.)
    const bool finite = sim_->stateFinite();
    r.ok = status_.ok() && finite;
    r.status = !status_.ok() ? status_.message() : finite ? "stable" : notFiniteMessage(sim_->stepCount());
    return r;
  }
  Carry carry() const override {
    return {sim_->state().x.template cast<double>(), sim_->state().v.template cast<double>(), sim_->state().time};
  }
  bool freeParticle(weft::Index i) const override {
    return i >= 0 && i < sim_->model().particleCount() && !sim_->model().isPinned(i);
  }
  void drag(weft::Index i, const Eigen::Vector3f& target) override {
    if (!freeParticle(i) || !status_.ok()) return;
    weft::State<S> s = sim_->state();
    s.x.row(i) = target.cast<S>().transpose();
    s.v.row(i).setZero();
    sim_->setState(s);
  }
  void setTimeStep(double dt) override {
    sim_->setTimeStep(dt);
    status_ = sim_->status();
  }
  double msPerStep() const override { return msPerStep_; }
  const std::vector<weft::Index>& firstParticle() const override { return first_; }
  weftrender::SceneDrawer drawer() const override { return weftrender::makeDrawer(*sim_, first_); }

 private:
  std::vector<weft::Index> first_;
  std::unique_ptr<weft::Simulation<S> > sim_;
  weft::StepStatus status_;
  double msPerStep_ = 0;
  std::int64_t steps_ = 0;
};

std::unique_ptr<Pane> makePane(const weft::SceneSpec& spec, const Carry* carry) {
  if (spec.precision == weft::Precision::Float) return std::make_unique<PaneOf<float> >(spec, carry);
  return std::make_unique<PaneOf<double> >(spec, carry);
}

weft::IntegratorKind nextIntegrator(weft::IntegratorKind kind) {
  const auto& all = weft::kAllIntegrators;
  const auto at = std::find(std::begin(all), std::end(all), kind);
  return at == std::end(all) || at + 1 == std::end(all) ? *std::begin(all) : *(at + 1);
}

/// Everything the window shows and the input changes.
struct Viewer {
  weft::SceneSpec spec;                  // integrator, dt, precision, threads as set now (the left pane's)
  weft::IntegratorKind rightIntegrator;  // the right pane's
  std::unique_ptr<Pane> left, right;     // right: split screen
  std::optional<weftrender::SceneDrawer> drawer;
  weftrender::FramedView view;
  weftrender::SceneSnapshot leftSnapshot, rightSnapshot;
  bool paused = false, stepOnce = false;
  // Mouse: orbiting, panning or dragging a particle.
  enum class Drag { None, Orbit, Pan, Particle } drag = Drag::None;
  double lastX = 0, lastY = 0;
  weft::Index particle = -1;
  float particleDepth = 0;  // its normalised device depth when picked
  bool particleRight = false;
  std::string message;  // last change, shown for a while
  Clock::time_point messageTime;
  GLFWwindow* window = nullptr;

  void say(const std::string& text) {
    message = text;
    messageTime = Clock::now();
    std::cout << "weft view: " << text << "\n";
  }
  void rebuild(bool keepState) {
    const Carry leftCarry = keepState ? left->carry() : Carry{};
    const Carry rightCarry = keepState && right ? right->carry() : Carry{};
    left = makePane(spec, keepState ? &leftCarry : nullptr);
    if (right) {
      weft::SceneSpec r = spec;
      r.simulation.integrator = rightIntegrator;
      right = makePane(r, keepState ? &rightCarry : nullptr);
    }
  }
  void split(bool on) {
    if (!on) {
      right.reset();
      return;
    }
    weft::SceneSpec r = spec;
    r.simulation.integrator = rightIntegrator;
    const Carry carry = left->carry();  // both start from the same state
    right = makePane(r, &carry);
  }
  /// Frames the present state of the left pane for the pane's shape, extended downwards by
  /// its size (a pinned cloth falls and hangs: it stays in the picture), not below the
  /// ground. Keeps the camera's angles.
  void frame() {
    weftrender::Bounds box = drawer->framedBounds(leftSnapshot);
    if (!box.empty()) {
      const Eigen::Vector3f size = box.hi - box.lo;
      float low = box.lo.y() - std::max({size.x(), size.y(), size.z()});
      if (drawer->groundPlane()) low = std::max(low, *drawer->groundPlane());
      box.lo.y() = std::min(box.lo.y(), low);
    }
    const weftrender::Viewport vp = paneViewport(false);
    view = weftrender::frameBox(*drawer, box, vp.width, vp.height, view.camera.azimuth / kRadian,
                                view.camera.elevation / kRadian, {});
  }
  weftrender::Viewport paneViewport(bool rightPane) const {
    int w = 0, h = 0;
    glfwGetFramebufferSize(window, &w, &h);
    if (!right) return {0, 0, std::max(w, 1), std::max(h, 1)};
    const int half = w / 2;
    return rightPane ? weftrender::Viewport{half, 0, std::max(w - half, 1), std::max(h, 1)}
                     : weftrender::Viewport{0, 0, std::max(half, 1), std::max(h, 1)};
  }
  Eigen::Matrix4f viewProjection(const weftrender::Viewport& vp) const {
    return view.camera.projection(static_cast<float>(vp.width) / static_cast<float>(vp.height), view.radius) *
           view.camera.view();
  }
  /// Cursor (window coordinates, from the top left) to framebuffer pixels from the bottom.
  Eigen::Vector2f pixel(double x, double y) const {
    int ww = 0, wh = 0, fw = 0, fh = 0;
    glfwGetWindowSize(window, &ww, &wh);
    glfwGetFramebufferSize(window, &fw, &fh);
    const float sx = ww > 0 ? static_cast<float>(fw) / static_cast<float>(ww) : 1.f;
    const float sy = wh > 0 ? static_cast<float>(fh) / static_cast<float>(wh) : 1.f;
    return {static_cast<float>(x) * sx, static_cast<float>(fh) - static_cast<float>(y) * sy};
  }
  /// The free particle nearest the cursor within 12 pixels, in the pane under it.
  bool pick(double x, double y) {
    const Eigen::Vector2f p = pixel(x, y);
    particleRight = right && p.x() >= static_cast<float>(paneViewport(true).x);
    const weftrender::Viewport vp = paneViewport(particleRight);
    const Eigen::Matrix4f m = viewProjection(vp);
    const weftrender::SceneSnapshot& snap = particleRight ? rightSnapshot : leftSnapshot;
    const Pane& pane = particleRight ? *right : *left;
    float best = 12.f * 12.f;
    particle = -1;
    for (std::size_t i = 0; 3 * i + 2 < snap.x.size(); ++i) {
      const Eigen::Vector4f clip = m * Eigen::Vector4f(snap.x[3 * i], snap.x[3 * i + 1], snap.x[3 * i + 2], 1.f);
      if (clip.w() <= 0) continue;
      const Eigen::Vector3f ndc = clip.head<3>() / clip.w();
      const Eigen::Vector2f at(static_cast<float>(vp.x) + 0.5f * (ndc.x() + 1) * static_cast<float>(vp.width),
                               static_cast<float>(vp.y) + 0.5f * (ndc.y() + 1) * static_cast<float>(vp.height));
      const float d = (at - p).squaredNorm();
      if (d < best && pane.freeParticle(static_cast<weft::Index>(i))) {
        best = d;
        particle = static_cast<weft::Index>(i);
        particleDepth = ndc.z();
      }
    }
    return particle >= 0;
  }
  /// Moves the dragged particle under the cursor (at its picked depth), in both panes.
  void dragTo(double x, double y) {
    const Eigen::Vector2f p = pixel(x, y);
    const weftrender::Viewport vp = paneViewport(particleRight);
    const Eigen::Vector4f ndc(2 * (p.x() - static_cast<float>(vp.x)) / static_cast<float>(vp.width) - 1,
                              2 * (p.y() - static_cast<float>(vp.y)) / static_cast<float>(vp.height) - 1, particleDepth,
                              1.f);
    const Eigen::Vector4f world = viewProjection(vp).inverse() * ndc;
    const Eigen::Vector3f target = world.head<3>() / world.w();
    left->drag(particle, target);
    if (right) right->drag(particle, target);
  }
};

Viewer* viewerOf(GLFWwindow* window) { return static_cast<Viewer*>(glfwGetWindowUserPointer(window)); }

void handleKey(GLFWwindow* window, int key);

// GLFW calls back through C: nothing may be thrown across it.
void onKey(GLFWwindow* window, int key, int, int action, int) {
  if (action != GLFW_PRESS && action != GLFW_REPEAT) return;
  try {
    handleKey(window, key);
  } catch (const std::exception& e) {
    viewerOf(window)->say(std::string("refused: ") + e.what());
  }
}

void handleKey(GLFWwindow* window, int key) {
  Viewer& v = *viewerOf(window);
  std::ostringstream text;
  text.precision(4);
  switch (key) {
    case GLFW_KEY_ESCAPE:
    case GLFW_KEY_Q:
      glfwSetWindowShouldClose(window, GLFW_TRUE);
      break;
    case GLFW_KEY_SPACE:
      v.paused = !v.paused;
      v.say(v.paused ? "paused" : "running");
      break;
    case GLFW_KEY_N:
    case GLFW_KEY_RIGHT:
      v.paused = true;
      v.stepOnce = true;
      break;
    case GLFW_KEY_R:
      v.rebuild(false);
      v.say("reset to the initial state");
      break;
    case GLFW_KEY_I:
      v.spec.simulation.integrator = nextIntegrator(v.spec.simulation.integrator);
      v.rebuild(true);
      v.say(std::string("integrator ") + weft::integratorName(v.spec.simulation.integrator));
      break;
    case GLFW_KEY_O:
      v.rightIntegrator = nextIntegrator(v.rightIntegrator);
      if (!v.right) v.split(true);
      v.rebuild(true);
      v.say(std::string("right integrator ") + weft::integratorName(v.rightIntegrator));
      break;
    case GLFW_KEY_LEFT_BRACKET:
    case GLFW_KEY_RIGHT_BRACKET: {
      const double dt = v.spec.simulation.dt * (key == GLFW_KEY_LEFT_BRACKET ? 0.5 : 2.0);
      v.spec.simulation.dt = dt;
      v.left->setTimeStep(dt);
      if (v.right) v.right->setTimeStep(dt);
      text << "dt " << dt << " s";
      v.say(text.str());
      break;
    }
    case GLFW_KEY_P:
      v.spec.precision = v.spec.precision == weft::Precision::Float ? weft::Precision::Double : weft::Precision::Float;
      v.rebuild(true);
      v.say(v.spec.precision == weft::Precision::Float ? "precision float" : "precision double");
      break;
    case GLFW_KEY_T: {
      const int t = v.spec.simulation.threads;
      v.spec.simulation.threads = t == 1 ? 2 : t == 2 ? 0 : 1;
      v.rebuild(true);
      text << "threads "
           << (v.spec.simulation.threads == 0 ? std::string("all") : std::to_string(v.spec.simulation.threads));
      v.say(text.str());
      break;
    }
    case GLFW_KEY_V:
      v.split(!v.right);
      v.frame();
      v.say(v.right ? "split screen" : "one pane");
      break;
    case GLFW_KEY_F:
      v.frame();
      break;
    default:
      break;
  }
}

void onButton(GLFWwindow* window, int button, int action, int) {
  Viewer& v = *viewerOf(window);
  v.lastX = v.lastY = 0;
  if (action == GLFW_RELEASE) {
    v.drag = Viewer::Drag::None;
    return;
  }
  glfwGetCursorPos(window, &v.lastX, &v.lastY);
  if (button == GLFW_MOUSE_BUTTON_LEFT)
    v.drag = v.pick(v.lastX, v.lastY) ? Viewer::Drag::Particle : Viewer::Drag::Orbit;
  else if (button == GLFW_MOUSE_BUTTON_RIGHT || button == GLFW_MOUSE_BUTTON_MIDDLE)
    v.drag = Viewer::Drag::Pan;
}

void onCursor(GLFWwindow* window, double x, double y) {
  Viewer& v = *viewerOf(window);
  const float dx = static_cast<float>(x - v.lastX), dy = static_cast<float>(y - v.lastY);
  v.lastX = x;
  v.lastY = y;
  weftrender::OrbitCamera& c = v.view.camera;
  if (v.drag == Viewer::Drag::Orbit) {
    c.azimuth -= 0.008f * dx;
    c.elevation = std::clamp(c.elevation + 0.008f * dy, -1.5f, 1.5f);
  } else if (v.drag == Viewer::Drag::Pan) {
    const Eigen::Matrix4f m = c.view();
    const Eigen::Vector3f rightAxis = m.block<1, 3>(0, 0).transpose(), upAxis = m.block<1, 3>(1, 0).transpose();
    const float scale = 0.0015f * c.distance;
    c.target += scale * (-dx * rightAxis + dy * upAxis);
  } else if (v.drag == Viewer::Drag::Particle) {
    v.dragTo(x, y);
  }
}

void onScroll(GLFWwindow* window, double, double y) {
  Viewer& v = *viewerOf(window);
  v.view.camera.distance *= std::pow(0.9f, static_cast<float>(y));
}

/// Keeps the libraries the window loaded at run time (GLFW opens libGL and X11 extension
/// libraries, libglvnd the Mesa vendor library, Mesa its driver) in the process until it
/// ends: glfwTerminate would unload them, and unloading Mesa's LLVM-backed driver is not
/// safe. It also keeps their names in a leak report (LeakSanitizer can only name a module
/// still loaded at exit: tests/lsan.supp names them).
void keepGlLibrariesLoaded() {
  for (const char* name :
       {"libGL.so.1", "libGLX.so.0", "libGLdispatch.so.0", "libGLX_mesa.so.0", "libglapi.so.0", "swrast_dri.so",
        "/usr/lib/x86_64-linux-gnu/dri/swrast_dri.so", "libLLVM-15.so.1", "libX11-xcb.so.1", "libXcursor.so.1",
        "libXrandr.so.2", "libXinerama.so.1", "libXi.so.6", "libXxf86vm.so.1"}) {
    // RTLD_NOLOAD: only those already loaded; RTLD_NODELETE: never unloaded. The handle's
    // reference is kept on purpose (no dlclose).
    dlopen(name, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
  }
}

std::string glfwMessage() {
  const char* description = nullptr;
  glfwGetError(&description);
  return description ? description : "no reason given";
}

/// The readout of one pane, in its top left corner.
void drawReadout(weftrender::Renderer& renderer, const weftrender::Viewport& vp, const Readout& r, double realTime,
                 bool paused) {
  std::vector<std::string> lines;
  char line[256];
  std::snprintf(line, sizeof line, "%s  %s  dt %.3g s  %d thread%s", r.integrator.c_str(), r.precision.c_str(), r.dt,
                r.threads, r.threads == 1 ? "" : "s");
  lines.emplace_back(line);
  if (r.ok)
    std::snprintf(line, sizeof line, "%.3f ms/step  %lld steps/frame  x%.2f real time%s", r.msPerStep,
                  static_cast<long long>(r.steps), realTime, paused ? "  paused" : "");
  else
    std::snprintf(line, sizeof line, "%.3f ms/step  stopped (r resets)", r.msPerStep);
  lines.emplace_back(line);
  std::snprintf(line, sizeof line, "t %.3f s  energy %.5g J", r.time, r.energy);
  lines.emplace_back(line);
  std::string status = r.ok ? "stable" : "unstable: " + r.status;
  const std::size_t room = static_cast<std::size_t>(std::max(10, vp.width / (vp.width >= 720 ? 12 : 6) - 2));
  if (status.size() > room) status = status.substr(0, room - 3) + "...";
  const float scale = vp.width >= 720 ? 2.f : 1.f, top = static_cast<float>(vp.height) - 4 * scale;
  const float advance = 6 * scale, lineHeight = 9 * scale;
  std::vector<float> panel, text, statusText;
  std::size_t widest = status.size();
  for (const std::string& l : lines) widest = std::max(widest, l.size());
  weftrender::appendRectangle(0, top - 4 * lineHeight - 2 * scale, 8 * scale + static_cast<float>(widest) * advance,
                              static_cast<float>(vp.height), panel);
  for (std::size_t i = 0; i < lines.size(); ++i)
    weftrender::appendText(lines[i], 4 * scale, top - static_cast<float>(i) * lineHeight, scale, text);
  weftrender::appendText(status, 4 * scale, top - 3 * lineHeight, scale, statusText);
  renderer.drawOverlay(panel, {0.f, 0.f, 0.f, 0.55f}, vp);
  renderer.drawOverlay(text, {1.f, 1.f, 1.f, 1.f}, vp);
  renderer.drawOverlay(statusText,
                       r.ok ? Eigen::Vector4f(0.5f, 1.f, 0.5f, 1.f) : Eigen::Vector4f(1.f, 0.4f, 0.35f, 1.f), vp);
}

}  // namespace

int viewScene(const ViewOptions& o) {
  weft::SceneSpec spec = sceneFor(o.run);
  for (const std::string& u : unusedSceneSettings(o.run, spec, "view"))
    std::cerr << "weft view: note: " << u << " (not used)\n";
  if (o.screenshot) checkOutputFile(*o.screenshot, "--screenshot");
  const char* display = std::getenv("DISPLAY");
  const char* wayland = std::getenv("WAYLAND_DISPLAY");
  if ((!display || !*display) && (!wayland || !*wayland)) {
    std::cerr << "weft view: no display to open a window on (DISPLAY and WAYLAND_DISPLAY are not set); "
                 "`weft render` draws pictures without one, `xvfb-run -a weft view ...` gives a virtual one\n";
    return 2;
  }
  if (!glfwInit()) {
    std::cerr << "weft view: cannot open the display (" << glfwMessage() << ")\n";
    return 2;
  }
  struct Terminate {
    ~Terminate() { glfwTerminate(); }
  } terminate;
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_DEPTH_BITS, 24);
  glfwWindowHint(GLFW_STENCIL_BITS, 8);
  glfwWindowHint(GLFW_SAMPLES, 4);
  const std::string title = "weft view " + spec.name;
  GLFWwindow* window = glfwCreateWindow(o.width, o.height, title.c_str(), nullptr, nullptr);
  if (!window) {  // no multisampled visual (a virtual display): without
    glfwWindowHint(GLFW_SAMPLES, 0);
    window = glfwCreateWindow(o.width, o.height, title.c_str(), nullptr, nullptr);
  }
  if (!window) {
    std::cerr << "weft view: the display gives no OpenGL 3.3 core window (" << glfwMessage() << ")\n";
    return 2;
  }
  glfwMakeContextCurrent(window);
  keepGlLibrariesLoaded();
  glfwSwapInterval(o.frames ? 0 : 1);
  const weftrender::GlApi gl =
      weftrender::loadGl([](const char* name) { return reinterpret_cast<void*>(glfwGetProcAddress(name)); });
  std::optional<weftrender::Renderer> renderer(std::in_place, gl);  // destroyed before the window

  Viewer v;
  v.window = window;
  v.spec = spec;
  v.rightIntegrator = o.compare ? weft::parseIntegrator(*o.compare) : weft::IntegratorKind::SymplecticEuler;
  v.left = makePane(spec, nullptr);
  if (o.compare) v.split(true);
  v.drawer.emplace(v.left->drawer());
  v.leftSnapshot = v.left->snapshot(*v.drawer);
  v.view.camera.azimuth = weftrender::kDefaultAzimuth;
  v.view.camera.elevation = weftrender::kDefaultElevation;
  v.frame();
  glfwSetWindowUserPointer(window, &v);
  glfwSetKeyCallback(window, onKey);
  glfwSetMouseButtonCallback(window, onButton);
  glfwSetCursorPosCallback(window, onCursor);
  glfwSetScrollCallback(window, onScroll);
  std::cout << "weft view " << spec.name
            << ": drag to orbit (right button: pan, wheel: zoom), drag the cloth to pull it; space pause, n step, "
               "r reset, i / o integrator (left / right), [ ] dt, p precision, t threads, v split screen, f frame, "
               "q quit. It runs until closed: the scene's length ("
            << weft::sceneStepCount(spec) << " steps) bounds weft run and weft render, not the view\n";

  weftrender::DrawFrame frame;
  std::int64_t drawn = 0;
  const double frameSeconds = 1.0 / 60;
  while (!glfwWindowShouldClose(window)) {
    glfwPollEvents();
    // Steps for 1/60 s of simulated time per frame; live, at most ~30 ms of stepping per
    // pane and frame (the readout says how far from real time that is).
    const double dt = v.spec.simulation.dt;
    const auto wanted = std::max<std::int64_t>(1, std::llround(frameSeconds / dt));
    std::int64_t steps = wanted;
    if (!o.frames) {
      const double ms = std::max(v.left->msPerStep(), v.right ? v.right->msPerStep() : 0.0);
      if (ms > 0) steps = std::clamp<std::int64_t>(static_cast<std::int64_t>(30.0 / ms), 1, wanted);
    }
    if (!v.paused || v.stepOnce) {
      const std::int64_t n = v.stepOnce ? 1 : steps;
      v.left->advance(n);
      if (v.right) v.right->advance(n);
      v.stepOnce = false;
    }
    v.leftSnapshot = v.left->snapshot(*v.drawer);
    if (v.right) v.rightSnapshot = v.right->snapshot(*v.drawer);
    const double realTime = static_cast<double>(steps) / static_cast<double>(wanted);

    int fw = 0, fh = 0;
    glfwGetFramebufferSize(window, &fw, &fh);
    for (const bool rightPane : {false, true}) {
      if (rightPane && !v.right) continue;
      const weftrender::Viewport vp = v.paneViewport(rightPane);
      v.drawer->build(rightPane ? v.rightSnapshot : v.leftSnapshot, v.view.tubeRadius, frame);
      frame.groundHeight = v.view.groundHeight;
      renderer->draw(frame, v.view.camera, vp, v.view.radius, v.view.camera.azimuth);
      drawReadout(*renderer, vp, (rightPane ? v.right : v.left)->readout(), realTime, v.paused);
    }
    if (!v.message.empty() && std::chrono::duration<double>(Clock::now() - v.messageTime).count() < 2.0) {
      std::vector<float> text;
      weftrender::appendText(v.message, 8, 26, 2, text);
      renderer->drawOverlay(text, {0.1f, 0.1f, 0.1f, 1.f}, {0, 0, std::max(fw, 1), std::max(fh, 1)});
    }
    ++drawn;
    if (o.frames && drawn >= *o.frames) {
      if (o.screenshot) {
        std::vector<std::uint8_t> pixels(4ull * static_cast<std::size_t>(fw) * fh);
        gl.ReadBuffer(GL_BACK);
        gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
        gl.ReadPixels(0, 0, fw, fh, GL_RGBA, GL_UNSIGNED_BYTE, pixels.data());
        weftrender::writePng(*o.screenshot, weftrender::downsample(pixels.data(), fw, fh, 1));
      }
      const Readout r = v.left->readout();
      std::cout << "weft view: " << drawn << " frames, " << r.integrator << " at t " << r.time << " s, " << r.status
                << (o.screenshot ? ", screenshot " + *o.screenshot : std::string()) << "\n";
      break;
    }
    glfwSwapBuffers(window);
  }
  renderer.reset();
  glfwDestroyWindow(window);
  return 0;
}

#endif

}  // namespace weftcli
