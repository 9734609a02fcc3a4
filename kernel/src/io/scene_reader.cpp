// Scene files (docs/scenes.md): readSceneFile and parseScene, the top level of the schema
// (timing, integrator, precision, threads, force strategy, gravity) and its small
// sections (effects, integration, stability, output); bodies, collision and rigid_bodies
// are read by their own files (scene_internal.hpp). Every value is checked while the file
// is read (a range the kernel owns by its validator, once its section is read), and a
// SceneError names the source, the field path and the value.
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <string>
#include <system_error>
#include <vector>

#include "model/precision_limits.hpp"
#include "scene_internal.hpp"

namespace weft {

using namespace io_detail;  // Json, Reader, fmt, shortDump (json_reader.hpp); the sections (scene_internal.hpp)

const char* bodyKindName(BodyKind kind) {
  switch (kind) {
    case BodyKind::Rope:
      return "rope";
    case BodyKind::ClothGrid:
      return "cloth_grid";
    case BodyKind::ClothMesh:
      return "cloth_mesh";
  }
  return "unknown";
}

namespace {

constexpr std::int64_t kMaxSteps = std::int64_t(1) << 40;
constexpr std::int64_t kMaxSceneParticles = std::int64_t(1) << 27;  // ropes and grids of a scene, in all
constexpr std::size_t kMaxSceneFileBytes = std::size_t(16) << 20;   // a scene is a few KB

/// The `effects` section. Ranges are the kernel's (validateEffects); the file adds that a
/// repulsion it lists is on (radius and stiffness given, > 0).
ParticleEffects readEffects(const Reader& r, const Json& j, const std::string& f) {
  r.object(j, f, {"drag", "wind", "repulsion"});
  ParticleEffects e;
  e.drag = r.anyNumber(j, f, "drag", e.drag);
  if (j.contains("wind")) {
    const std::string fw = Reader::join(f, "wind");
    const Json& w = j["wind"];
    r.object(w, fw,
             {"velocity", "air_density", "drag_coefficient", "lift_coefficient", "particle_area", "gust_strength",
              "gust_scale", "gust_period", "gust_modes", "seed"});
    WindEffect& d = e.wind;
    d.enabled = true;
    d.velocity = r.vector(w, fw, "velocity", d.velocity);
    d.airDensity = r.anyNumber(w, fw, "air_density", d.airDensity);
    d.dragCoefficient = r.anyNumber(w, fw, "drag_coefficient", d.dragCoefficient);
    d.liftCoefficient = r.anyNumber(w, fw, "lift_coefficient", d.liftCoefficient);
    d.particleArea = r.anyNumber(w, fw, "particle_area", d.particleArea);
    d.gustStrength = r.anyNumber(w, fw, "gust_strength", d.gustStrength);
    d.gustScale = r.anyNumber(w, fw, "gust_scale", d.gustScale);
    d.gustPeriod = r.anyNumber(w, fw, "gust_period", d.gustPeriod);
    d.gustModes = r.anyInt(w, fw, "gust_modes", d.gustModes);
    d.seed = static_cast<std::uint64_t>(
        r.integer(w, fw, "seed", static_cast<std::int64_t>(d.seed), 0, std::numeric_limits<std::int64_t>::max()));
  }
  if (j.contains("repulsion")) {
    const std::string fr = Reader::join(f, "repulsion");
    const Json& rep = j["repulsion"];
    r.object(rep, fr, {"radius", "stiffness"});
    for (const char* key : {"radius", "stiffness"})
      if (!rep.contains(key))
        r.fail(Reader::join(fr, key),
               "is required: repulsion needs radius (m, > 0) and stiffness (N/m, > 0), got " + shortDump(rep));
    e.repulsion.radius = r.number(rep, fr, "radius", 0, 0, false, " m");
    e.repulsion.stiffness = r.number(rep, fr, "stiffness", 0, 0, false, " N/m");
  }
  r.kernelRules(j, f, f + ".", [&] { validateEffects(e, f.c_str()); });
  return e;
}

}  // namespace

namespace io_detail {

template <class S>
void requireScalarRange(const SimulationOptions& o,
                        const std::function<void(const std::string&, const std::string&)>& fail) {
  using Limits = detail::PrecisionLimits<S>;  // the kernel's rules (Simulation<S> and ModelBuilder<S>)
  const auto check = [&](const char* field, double value) {
    if (!Limits::representable(value))
      fail(field, std::string("must be within the range of ") + Limits::kName +
                      " precision (|value| <= " + fmt(Limits::kLargest) + "), got " + fmt(value));
  };
  // (dt > 0 is the kernel's rule read before; here, that the model's precision holds it.)
  if (o.dt > 0 && !Limits::timeStep(o.dt)) fail("dt", "must be " + Limits::timeStepRule() + ", got " + fmt(o.dt));
  check("gravity[0]", o.gravity.x);
  check("gravity[1]", o.gravity.y);
  check("gravity[2]", o.gravity.z);
  check("effects.drag", o.effects.drag);
  if (o.effects.wind.enabled) {
    const WindEffect& w = o.effects.wind;
    check("effects.wind.velocity[0]", w.velocity.x);
    check("effects.wind.velocity[1]", w.velocity.y);
    check("effects.wind.velocity[2]", w.velocity.z);
    check("effects.wind.air_density", w.airDensity);
    check("effects.wind.drag_coefficient", w.dragCoefficient);
    check("effects.wind.lift_coefficient", w.liftCoefficient);
    check("effects.wind.particle_area", w.particleArea);
    check("effects.wind.gust_strength", w.gustStrength);
  }
  if (o.effects.repulsion.enabled()) {
    check("effects.repulsion.radius", o.effects.repulsion.radius);
    check("effects.repulsion.stiffness", o.effects.repulsion.stiffness);
  }
}

template void requireScalarRange<float>(const SimulationOptions&,
                                        const std::function<void(const std::string&, const std::string&)>&);
template void requireScalarRange<double>(const SimulationOptions&,
                                         const std::function<void(const std::string&, const std::string&)>&);

std::string bodiesText(const SceneSpec& scene) {
  return std::to_string(scene.bodies.size()) + (scene.bodies.size() == 1 ? " body" : " bodies") +
         (scene.bodies.empty() ? std::string() : std::string(", the first a ") + bodyKindName(scene.bodies[0].kind));
}

/// Every key of every object in `j`, as field paths (the reader's names: "a.b", "a[0].b").
void collectKeys(const Json& j, const std::string& field, std::set<std::string>& keys) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it) {
      const std::string f = Reader::join(field, it.key());
      keys.insert(f);
      collectKeys(it.value(), f, keys);
    }
  } else if (j.is_array()) {
    for (size_t k = 0; k < j.size(); ++k) collectKeys(j[k], field + "[" + std::to_string(k) + "]", keys);
  }
}

}  // namespace io_detail

SceneSpec parseScene(const std::string& text, const std::string& source, const std::string& baseDirectory) {
  Json root;
  JsonPathTracker tracker(source, text);
  try {
    root = Json::parse(
        text, [&tracker](int depth, Json::parse_event_t event, Json& parsed) { return tracker(depth, event, parsed); });
  } catch (const Json::exception& e) {
    // nlohmann's message carries the line/column or byte of the problem, the tracker the field.
    const std::string at = tracker.path();
    throw SceneError(source + ": " + (at.empty() ? std::string() : at + ": ") + "malformed JSON: " + e.what());
  }
  const Reader r(source);
  r.object(root, "",
           {"name", "bodies", "integrator", "dt", "steps", "duration", "precision", "threads", "force_strategy",
            "gravity", "effects", "collision", "self_collision", "rigid_bodies", "integration", "stability", "output"});
  SceneSpec scene;
  scene.name = r.string(root, "", "name", "scene");
  // Cloth and ropes (`bodies`), rigid bodies (`rigid_bodies`), or both.
  if (!root.contains("bodies") && !root.contains("rigid_bodies"))
    r.fail("bodies", "is required (or rigid_bodies): a non-empty array of bodies");
  static const Json kNoBodies = Json::array();
  const Json& bodies = root.contains("bodies") ? root["bodies"] : kNoBodies;
  if (root.contains("bodies") && (!bodies.is_array() || bodies.empty()))
    r.fail("bodies", std::string("must be a non-empty array, got ") + typeName(bodies) + " " + shortDump(bodies));
  std::int64_t particles = 0;
  for (size_t k = 0; k < bodies.size(); ++k) {
    const std::string f = "bodies[" + std::to_string(k) + "]";
    scene.bodies.push_back(readBody(r, bodies[k], f, baseDirectory));
    const BodySpec& b = scene.bodies.back();
    particles += b.kind == BodyKind::Rope        ? b.rope.particleCount
                 : b.kind == BodyKind::ClothGrid ? static_cast<std::int64_t>(b.grid.width) * b.grid.height
                                                 : 0;
    if (particles > kMaxSceneParticles)
      r.fail(f, "the scene's ropes and grids have more than 2^27 particles in all (" + std::to_string(particles) +
                    " up to this body)");
  }

  SimulationOptions& o = scene.simulation;
  // The names of integrators and force strategies are the kernel's (parseIntegrator,
  // parseForceStrategy).
  const std::string integrator = r.string(root, "", "integrator", "rk4");
  r.kernelRules(root, "", "", [&] { o.integrator = parseIntegrator(integrator); });
  if (!root.contains("dt")) r.fail("dt", "is required: the fixed time step in seconds (> 0)");
  o.dt = r.number(root, "", "dt", 0, 0, false, " s");
  if (root.contains("steps") && root.contains("duration"))
    r.fail("steps", "give steps or duration, not both (steps " + shortDump(root["steps"]) + ", duration " +
                        shortDump(root["duration"]) + ")");
  if (!root.contains("steps") && !root.contains("duration"))
    r.fail("steps", "is required (or duration): how long to run");
  scene.steps = r.integer(root, "", "steps", 0, 1, kMaxSteps);
  scene.duration = r.number(root, "", "duration", 0, 0, false, " s");
  if (scene.duration > 0 && !(durationStepCount(scene.duration, o.dt) <= static_cast<double>(kMaxSteps)))
    r.fail("duration",
           "asks for more than 2^40 steps (" + shortDump(root["duration"]) + " s at dt = " + fmt(o.dt) + " s)");
  scene.precision =
      r.choice(root, "", "precision", "double", {"float", "double"}) == "float" ? Precision::Float : Precision::Double;
  o.threads = static_cast<int>(r.integer(root, "", "threads", 0, 0, 1024));
  const std::string strategy = r.string(root, "", "force_strategy", "auto");
  r.kernelRules(root, "", "", [&] { o.forceStrategy = parseForceStrategy(strategy); },
                {{"force strategy", "force_strategy"}});
  if (o.forceStrategy == ForceStrategy::GridStencil &&
      !(scene.bodies.size() == 1 && scene.bodies[0].kind == BodyKind::ClothGrid))
    r.fail("force_strategy", "grid-stencil needs a scene of a single cloth_grid body, got " + bodiesText(scene));
  o.gravity = r.vector(root, "", "gravity", o.gravity);
  if (root.contains("effects")) o.effects = readEffects(r, root["effects"], "effects");
  if (root.contains("collision"))
    readCollision(r, root["collision"], "collision", baseDirectory, o.collision, scene.meshObstacles);
  if (root.contains("self_collision")) readSelfCollision(r, root["self_collision"], "self_collision", o.selfCollision);
  for (size_t k = 0; k < scene.bodies.size(); ++k)
    if (scene.bodies[k].selfCollisionThickness && !o.selfCollision.enabled)
      r.fail("bodies[" + std::to_string(k) + "].self_collision_thickness",
             "needs a self_collision section (the thickness is self-collision's), got none");
  if (root.contains("rigid_bodies")) o.rigid = readRigidBodies(r, root["rigid_bodies"], "rigid_bodies");
  if (root.contains("integration")) {
    const Json& j = root["integration"];
    const std::string f = "integration";
    r.object(j, f,
             {"adaptive", "rtol", "atol", "min_substep", "max_substeps", "cg_tolerance", "cg_max_iterations",
              "cg_preconditioner", "projective_iterations"});
    IntegratorOptions& io = o.integration;
    io.adaptive = r.boolean(j, f, "adaptive", io.adaptive);
    io.relativeTolerance = r.anyNumber(j, f, "rtol", io.relativeTolerance);
    io.absoluteTolerance = r.anyNumber(j, f, "atol", io.absoluteTolerance);
    io.minSubstep = r.anyNumber(j, f, "min_substep", io.minSubstep);
    io.maxSubsteps = static_cast<Index>(r.integer(j, f, "max_substeps", io.maxSubsteps, 1, kMaxIterationCap));
    io.linearTolerance = r.anyNumber(j, f, "cg_tolerance", io.linearTolerance);
    io.maxLinearIterations =
        static_cast<Index>(r.integer(j, f, "cg_max_iterations", io.maxLinearIterations, 1, kMaxIterationCap));
    // (The names are the kernel's, as for the integrator.)
    const std::string preconditioner = r.string(j, f, "cg_preconditioner", preconditionerName(io.preconditioner));
    r.kernelRules(j, f, "", [&] { io.preconditioner = parsePreconditioner(preconditioner); },
                  {{"preconditioner", "cg_preconditioner"}});
    io.projectiveIterations =
        static_cast<int>(r.integer(j, f, "projective_iterations", io.projectiveIterations, 1, 10000));
    // Ranges are the kernel's; the integer counts keep the file's cap of 2^30.
    r.kernelRules(j, f, "IntegratorOptions.", [&] { validateIntegratorOptions(io); },
                  {{"relativeTolerance", "rtol"},
                   {"absoluteTolerance", "atol"},
                   {"linearTolerance", "cg_tolerance"},
                   {"maxLinearIterations", "cg_max_iterations"},
                   {"projectiveIterations", "projective_iterations"}});
  }
  if (root.contains("stability")) {
    const Json& j = root["stability"];
    r.object(j, "stability", {"enabled", "max_stretch"});
    o.stability.enabled = r.boolean(j, "stability", "enabled", o.stability.enabled);
    o.stability.maxStretch = r.anyNumber(j, "stability", "max_stretch", o.stability.maxStretch);
    r.kernelRules(j, "stability", "stability.", [&] { validateStabilityOptions(o.stability); });
  }
  if (scene.precision == Precision::Float)
    requireScalarRange<float>(o, [&r](const std::string& field, const std::string& what) { r.fail(field, what); });
  if (root.contains("output")) {
    const Json& j = root["output"];
    r.object(j, "output", {"directory", "format", "every"});
    if (j.contains("directory")) scene.output.directory = r.pathString(j, "output", "directory");
    scene.output.format = r.choice(j, "output", "format", "obj", {"obj", "ply", "cache", "gltf"});
    scene.output.every = r.integer(j, "output", "every", 1, 1, std::numeric_limits<std::int64_t>::max());
  }
  collectKeys(root, "", scene.givenKeys);
  return scene;
}

SceneSpec readSceneFile(const std::string& path) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) throw SceneError(path + ": is a directory, not a scene file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(path + ": cannot open the scene file: " + std::strerror(errno));
  // Read in chunks up to a cap: the path may be a pipe (weft run <(...)) or, by mistake,
  // something endless like /dev/zero.
  std::string text;
  std::vector<char> buffer(1 << 16);
  while (in.read(buffer.data(), static_cast<std::streamsize>(buffer.size())) || in.gcount() > 0) {
    text.append(buffer.data(), static_cast<size_t>(in.gcount()));
    if (text.size() > kMaxSceneFileBytes)
      throw SceneError(path + ": is larger than " + std::to_string(kMaxSceneFileBytes >> 20) +
                       " MiB: not a scene file");
  }
  if (in.bad()) throw SceneError(path + ": cannot read the scene file");
  const std::filesystem::path p(path);
  const std::string base = p.has_parent_path() ? p.parent_path().string() : std::string(".");
  return parseScene(text, path, base);
}

}  // namespace weft
