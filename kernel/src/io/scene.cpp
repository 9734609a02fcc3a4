#include "weft/io/scene.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "weft/io/mesh_import.hpp"
#include "weft/scene/builtin_scenes.hpp"

namespace weft {

using Json = nlohmann::json;

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

std::int64_t sceneStepCount(const SceneSpec& scene) {
  if (scene.steps > 0) return scene.steps;
  if (scene.duration > 0 && scene.simulation.dt > 0)
    return static_cast<std::int64_t>(std::ceil(scene.duration / scene.simulation.dt * (1 - 1e-12)));
  return 0;
}

// ---------------------------------------------------------------------------------------
// JSON reading: a strict walker that knows the path of every value it reads.
// ---------------------------------------------------------------------------------------

namespace {

std::string shortDump(const Json& j) {
  std::string s = j.dump();
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return s;
}

const char* typeName(const Json& j) { return j.type_name(); }

class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw SceneError(source_ + ": " + field + ": " + what);
  }

  /// Checks that `j` is an object whose keys are all in `allowed`.
  void object(const Json& j, const std::string& field, std::initializer_list<const char*> allowed) const {
    if (!j.is_object()) fail(field, std::string("must be an object, got ") + typeName(j) + " " + shortDump(j));
    std::set<std::string> known(allowed.begin(), allowed.end());
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (known.count(it.key())) continue;
      std::string list;
      for (const char* k : allowed) list += (list.empty() ? "" : ", ") + std::string(k);
      fail(join(field, it.key()), "unknown key; allowed keys here: " + list);
    }
  }

  static std::string join(const std::string& field, const std::string& key) {
    return field.empty() ? key : field + "." + key;
  }

  double number(const Json& j, const std::string& field) const {
    if (!j.is_number()) fail(field, std::string("must be a number, got ") + typeName(j) + " " + shortDump(j));
    const double v = j.get<double>();
    if (!std::isfinite(v)) fail(field, "must be finite, got " + shortDump(j));
    return v;
  }
  double number(const Json& parent, const std::string& field, const char* key, double fallback, double low,
                bool lowInclusive, const char* unit) const {
    if (!parent.contains(key)) return fallback;
    const std::string f = join(field, key);
    const double v = number(parent[key], f);
    if (lowInclusive ? !(v >= low) : !(v > low)) {
      std::ostringstream msg;
      msg.precision(17);
      msg << "must be " << (lowInclusive ? ">= " : "> ") << low << unit << ", got " << v;
      fail(f, msg.str());
    }
    return v;
  }
  double anyNumber(const Json& parent, const std::string& field, const char* key, double fallback) const {
    return parent.contains(key) ? number(parent[key], join(field, key)) : fallback;
  }
  std::int64_t integer(const Json& parent, const std::string& field, const char* key, std::int64_t fallback,
                       std::int64_t low, std::int64_t high) const {
    if (!parent.contains(key)) return fallback;
    const Json& j = parent[key];
    const std::string f = join(field, key);
    if (!j.is_number_integer()) fail(f, std::string("must be an integer, got ") + typeName(j) + " " + shortDump(j));
    const bool isUnsigned = j.is_number_unsigned();
    if (isUnsigned && j.get<std::uint64_t>() > static_cast<std::uint64_t>(high))
      fail(f, "must be in [" + std::to_string(low) + ", " + std::to_string(high) + "], got " + shortDump(j));
    const std::int64_t v = j.get<std::int64_t>();
    if (v < low || v > high)
      fail(f, "must be in [" + std::to_string(low) + ", " + std::to_string(high) + "], got " + std::to_string(v));
    return v;
  }
  bool boolean(const Json& parent, const std::string& field, const char* key, bool fallback) const {
    if (!parent.contains(key)) return fallback;
    const Json& j = parent[key];
    if (!j.is_boolean())
      fail(join(field, key), std::string("must be true or false, got ") + typeName(j) + " " + shortDump(j));
    return j.get<bool>();
  }
  std::string string(const Json& parent, const std::string& field, const char* key, const std::string& fallback) const {
    if (!parent.contains(key)) return fallback;
    const Json& j = parent[key];
    if (!j.is_string())
      fail(join(field, key), std::string("must be a string, got ") + typeName(j) + " " + shortDump(j));
    return j.get<std::string>();
  }
  std::string choice(const Json& parent, const std::string& field, const char* key, const std::string& fallback,
                     std::initializer_list<const char*> allowed) const {
    const std::string v = string(parent, field, key, fallback);
    for (const char* a : allowed)
      if (v == a) return v;
    std::string list;
    for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    fail(join(field, key), "must be one of " + list + "; got '" + v + "'");
  }
  Vec3d vector(const Json& parent, const std::string& field, const char* key, const Vec3d& fallback) const {
    if (!parent.contains(key)) return fallback;
    const Json& j = parent[key];
    const std::string f = join(field, key);
    if (!j.is_array() || j.size() != 3)
      fail(f, std::string("must be an array of 3 numbers [x, y, z], got ") + typeName(j) + " " + shortDump(j));
    return {number(j[0], f + "[0]"), number(j[1], f + "[1]"), number(j[2], f + "[2]")};
  }
  SpringMaterial material(const Json& parent, const std::string& field, const char* key,
                          const SpringMaterial& fallback) const {
    if (!parent.contains(key)) return fallback;
    const std::string f = join(field, key);
    const Json& j = parent[key];
    object(j, f, {"stiffness", "damping"});
    SpringMaterial m = fallback;
    m.stiffness = number(j, f, "stiffness", m.stiffness, 0, true, " N/m");
    m.damping = number(j, f, "damping", m.damping, 0, true, " N s/m");
    return m;
  }

 private:
  std::string source_;
};

KinematicPath readPath(const Reader& r, const Json& j, const std::string& f) {
  r.object(j, f, {"velocity", "angular_velocity", "axis", "center", "start", "end"});
  KinematicPath p;
  p.velocity = r.vector(j, f, "velocity", p.velocity);
  p.angularVelocity = r.anyNumber(j, f, "angular_velocity", 0);
  p.axis = r.vector(j, f, "axis", p.axis);
  p.center = r.vector(j, f, "center", p.center);
  p.startTime = r.number(j, f, "start", 0, 0, true, " s");
  if (j.contains("end")) {
    p.endTime = r.number(j["end"], Reader::join(f, "end"));
    if (!(p.endTime >= p.startTime))
      r.fail(Reader::join(f, "end"),
             "must be >= start (" + std::to_string(p.startTime) + " s), got " + std::to_string(p.endTime));
  }
  if (p.angularVelocity != 0 && !(p.axis.x != 0 || p.axis.y != 0 || p.axis.z != 0))
    r.fail(Reader::join(f, "axis"), "must be non-zero when angular_velocity is not 0");
  return p;
}

std::vector<PinSpec> readPins(const Reader& r, const Json& body, const std::string& field) {
  std::vector<PinSpec> pins;
  if (!body.contains("pins")) return pins;
  const std::string f = Reader::join(field, "pins");
  const Json& j = body["pins"];
  if (!j.is_array()) r.fail(f, std::string("must be an array, got ") + typeName(j) + " " + shortDump(j));
  PinSpec loose;  // bare indices: one fixed pin set
  for (size_t k = 0; k < j.size(); ++k) {
    const std::string fk = f + "[" + std::to_string(k) + "]";
    const Json& e = j[k];
    if (e.is_number()) {
      if (!e.is_number_integer() || e.get<std::int64_t>() < 0 || e.get<std::int64_t>() > (1ll << 31) - 1)
        r.fail(fk, "a pinned particle must be a non-negative integer index, got " + shortDump(e));
      loose.particles.push_back(static_cast<Index>(e.get<std::int64_t>()));
      continue;
    }
    r.object(e, fk, {"particles", "box", "path"});
    PinSpec p;
    if (e.contains("particles")) {
      const Json& list = e["particles"];
      if (!list.is_array())
        r.fail(fk + ".particles", std::string("must be an array of indices, got ") + shortDump(list));
      for (size_t q = 0; q < list.size(); ++q) {
        const Json& v = list[q];
        if (!v.is_number_integer() || v.get<std::int64_t>() < 0 || v.get<std::int64_t>() > (1ll << 31) - 1)
          r.fail(fk + ".particles[" + std::to_string(q) + "]",
                 "must be a non-negative integer index, got " + shortDump(v));
        p.particles.push_back(static_cast<Index>(v.get<std::int64_t>()));
      }
    }
    if (e.contains("box")) {
      const std::string fb = fk + ".box";
      r.object(e["box"], fb, {"min", "max"});
      if (!e["box"].contains("min") || !e["box"].contains("max")) r.fail(fb, "needs both min and max");
      const Vec3d lo = r.vector(e["box"], fb, "min", {}), hi = r.vector(e["box"], fb, "max", {});
      if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) r.fail(fb, "min must be <= max in every coordinate");
      p.box = std::make_pair(lo, hi);
    }
    if (!e.contains("particles") && !e.contains("box")) r.fail(fk, "needs particles or box");
    if (e.contains("path")) p.path = readPath(r, e["path"], fk + ".path");
    pins.push_back(std::move(p));
  }
  if (!loose.particles.empty()) pins.insert(pins.begin(), std::move(loose));
  return pins;
}

BodySpec readBody(const Reader& r, const Json& j, const std::string& f, const std::string& baseDirectory) {
  if (!j.is_object()) r.fail(f, std::string("must be an object, got ") + typeName(j) + " " + shortDump(j));
  BodySpec b;
  const std::string type = r.choice(j, f, "type", "", {"rope", "cloth_grid", "cloth_mesh"});
  b.name = r.string(j, f, "name", type);
  const std::string fm = Reader::join(f, "materials");
  if (type == "rope") {
    b.kind = BodyKind::Rope;
    r.object(j, f,
             {"type", "name", "particles", "origin", "direction", "length", "total_mass", "particle_mass", "materials",
              "bend_springs", "pins"});
    RopeSpec& s = b.rope;
    s.particleCount = static_cast<Index>(r.integer(j, f, "particles", s.particleCount, 2, 1 << 24));
    s.origin = r.vector(j, f, "origin", s.origin);
    s.direction = r.vector(j, f, "direction", s.direction);
    s.length = r.number(j, f, "length", s.length, 0, false, " m");
    s.totalMass = r.number(j, f, "total_mass", s.totalMass, 0, false, " kg");
    if (j.contains("particle_mass")) {
      if (j.contains("total_mass")) r.fail(f, "give total_mass or particle_mass, not both");
      s.totalMass = r.number(j, f, "particle_mass", 0, 0, false, " kg") * s.particleCount;
    }
    s.bendSprings = r.boolean(j, f, "bend_springs", s.bendSprings);
    if (j.contains("materials")) {
      r.object(j["materials"], fm, {"structural", "bend"});
      s.structural = r.material(j["materials"], fm, "structural", s.structural);
      s.bend = r.material(j["materials"], fm, "bend", s.bend);
    }
  } else if (type == "cloth_grid") {
    b.kind = BodyKind::ClothGrid;
    r.object(j, f,
             {"type", "name", "width", "height", "origin", "row_axis", "column_axis", "spacing", "total_mass",
              "particle_mass", "materials", "shear_springs", "bend_springs", "pins"});
    ClothGridSpec& s = b.grid;
    s.width = static_cast<Index>(r.integer(j, f, "width", s.width, 2, 1 << 15));
    s.height = static_cast<Index>(r.integer(j, f, "height", s.height, 2, 1 << 15));
    if (static_cast<std::int64_t>(s.width) * s.height > (1 << 26))
      r.fail(f, "width x height must be <= 2^26 particles, got " + std::to_string(s.width) + " x " +
                    std::to_string(s.height));
    s.origin = r.vector(j, f, "origin", s.origin);
    s.rowAxis = r.vector(j, f, "row_axis", s.rowAxis);
    s.columnAxis = r.vector(j, f, "column_axis", s.columnAxis);
    s.spacing = r.number(j, f, "spacing", 1.0 / (s.width - 1), 0, false, " m");
    s.totalMass = r.number(j, f, "total_mass", s.totalMass, 0, false, " kg");
    if (j.contains("particle_mass")) {
      if (j.contains("total_mass")) r.fail(f, "give total_mass or particle_mass, not both");
      s.totalMass = r.number(j, f, "particle_mass", 0, 0, false, " kg") * s.width * s.height;
    }
    s.shearSprings = r.boolean(j, f, "shear_springs", s.shearSprings);
    s.bendSprings = r.boolean(j, f, "bend_springs", s.bendSprings);
    if (j.contains("materials")) {
      r.object(j["materials"], fm, {"structural", "shear", "bend"});
      s.structural = r.material(j["materials"], fm, "structural", s.structural);
      s.shear = r.material(j["materials"], fm, "shear", s.shear);
      s.bend = r.material(j["materials"], fm, "bend", s.bend);
    }
  } else {
    b.kind = BodyKind::ClothMesh;
    r.object(j, f,
             {"type", "name", "mesh", "weld_tolerance", "scale", "translate", "total_mass", "areal_density",
              "materials", "bend_springs", "pins"});
    if (!j.contains("mesh")) r.fail(Reader::join(f, "mesh"), "is required: the path of the mesh file");
    const std::string mesh = r.string(j, f, "mesh", "");
    if (mesh.empty()) r.fail(Reader::join(f, "mesh"), "must not be empty");
    const std::filesystem::path p(mesh);
    b.meshFile = p.is_absolute() ? mesh : (std::filesystem::path(baseDirectory) / p).lexically_normal().string();
    b.clean.weldTolerance = r.number(j, f, "weld_tolerance", b.clean.weldTolerance, 0, true, " m");
    ClothMeshSpec& s = b.mesh;
    s.scale = r.number(j, f, "scale", s.scale, 0, false, "");
    s.translate = r.vector(j, f, "translate", s.translate);
    s.totalMass = r.number(j, f, "total_mass", s.totalMass, 0, false, " kg");
    s.arealDensity = r.number(j, f, "areal_density", s.arealDensity, 0, false, " kg/m^2");
    if (j.contains("total_mass") && j.contains("areal_density"))
      r.fail(f, "give total_mass or areal_density, not both");
    s.bendSprings = r.boolean(j, f, "bend_springs", s.bendSprings);
    if (j.contains("materials")) {
      r.object(j["materials"], fm, {"structural", "bend"});
      s.structural = r.material(j["materials"], fm, "structural", s.structural);
      s.bend = r.material(j["materials"], fm, "bend", s.bend);
    }
  }
  b.pins = readPins(r, j, f);
  return b;
}

ParticleEffects readEffects(const Reader& r, const Json& j, const std::string& f) {
  r.object(j, f, {"drag", "wind", "repulsion"});
  ParticleEffects e;
  e.drag = r.number(j, f, "drag", 0, 0, true, " N s/m");
  if (j.contains("wind")) {
    const std::string fw = Reader::join(f, "wind");
    const Json& w = j["wind"];
    r.object(w, fw,
             {"velocity", "air_density", "drag_coefficient", "lift_coefficient", "particle_area", "gust_strength",
              "gust_scale", "gust_period", "gust_modes", "seed"});
    WindEffect& d = e.wind;
    d.enabled = true;
    d.velocity = r.vector(w, fw, "velocity", d.velocity);
    d.airDensity = r.number(w, fw, "air_density", d.airDensity, 0, false, " kg/m^3");
    d.dragCoefficient = r.number(w, fw, "drag_coefficient", d.dragCoefficient, 0, true, "");
    d.liftCoefficient = r.number(w, fw, "lift_coefficient", d.liftCoefficient, 0, true, "");
    d.particleArea = r.number(w, fw, "particle_area", d.particleArea, 0, true, " m^2");
    d.gustStrength = r.number(w, fw, "gust_strength", d.gustStrength, 0, true, " m/s");
    d.gustScale = r.number(w, fw, "gust_scale", d.gustScale, 0, false, " m");
    d.gustPeriod = r.number(w, fw, "gust_period", d.gustPeriod, 0, false, " s");
    d.gustModes = static_cast<int>(r.integer(w, fw, "gust_modes", d.gustModes, 1, 64));
    d.seed = static_cast<std::uint64_t>(
        r.integer(w, fw, "seed", static_cast<std::int64_t>(d.seed), 0, std::numeric_limits<std::int64_t>::max()));
  }
  if (j.contains("repulsion")) {
    const std::string fr = Reader::join(f, "repulsion");
    const Json& rep = j["repulsion"];
    r.object(rep, fr, {"radius", "stiffness"});
    if (!rep.contains("radius") || !rep.contains("stiffness")) r.fail(fr, "needs radius and stiffness");
    e.repulsion.radius = r.number(rep, fr, "radius", 0, 1e-9, true, " m");
    e.repulsion.stiffness = r.number(rep, fr, "stiffness", 0, 0, false, " N/m");
  }
  return e;
}

}  // namespace

SceneSpec parseScene(const std::string& text, const std::string& source, const std::string& baseDirectory) {
  Json root;
  try {
    root = Json::parse(text);
  } catch (const Json::exception& e) {
    // nlohmann's message carries the line/column or byte of the problem.
    throw SceneError(source + ": malformed JSON: " + e.what());
  }
  const Reader r(source);
  r.object(root, "(top level)",
           {"name", "bodies", "integrator", "dt", "steps", "duration", "precision", "threads", "force_strategy",
            "gravity", "effects", "integration", "stability", "output"});
  SceneSpec scene;
  scene.name = r.string(root, "", "name", "scene");
  if (!root.contains("bodies")) r.fail("bodies", "is required: a non-empty array of bodies");
  const Json& bodies = root["bodies"];
  if (!bodies.is_array() || bodies.empty())
    r.fail("bodies", std::string("must be a non-empty array, got ") + typeName(bodies) + " " + shortDump(bodies));
  for (size_t k = 0; k < bodies.size(); ++k)
    scene.bodies.push_back(readBody(r, bodies[k], "bodies[" + std::to_string(k) + "]", baseDirectory));

  SimulationOptions& o = scene.simulation;
  const std::string integrator =
      r.choice(root, "", "integrator", "rk4", {"euler", "symplectic", "midpoint", "rk4", "verlet", "rk45", "implicit"});
  o.integrator = parseIntegrator(integrator);
  if (!root.contains("dt")) r.fail("dt", "is required: the fixed time step in seconds (> 0)");
  o.dt = r.number(root, "", "dt", 0, 0, false, " s");
  scene.steps = r.integer(root, "", "steps", 0, 1, std::int64_t(1) << 40);
  scene.duration = r.number(root, "", "duration", 0, 0, false, " s");
  if (root.contains("steps") && root.contains("duration")) r.fail("steps", "give steps or duration, not both");
  if (!root.contains("steps") && !root.contains("duration"))
    r.fail("steps", "is required (or duration): how long to run");
  if (sceneStepCount(scene) > (std::int64_t(1) << 40))
    r.fail("duration", "asks for more than 2^40 steps at dt = " + std::to_string(o.dt) + " s");
  scene.precision =
      r.choice(root, "", "precision", "double", {"float", "double"}) == "float" ? Precision::Float : Precision::Double;
  o.threads = static_cast<int>(r.integer(root, "", "threads", 0, 0, 1024));
  o.forceStrategy = parseForceStrategy(
      r.choice(root, "", "force_strategy", "auto", {"auto", "gather", "coloured", "colored", "grid-stencil", "grid"}));
  o.gravity = r.vector(root, "", "gravity", o.gravity);
  if (root.contains("effects")) o.effects = readEffects(r, root["effects"], "effects");
  if (root.contains("integration")) {
    const Json& j = root["integration"];
    const std::string f = "integration";
    r.object(j, f, {"adaptive", "rtol", "atol", "min_substep", "max_substeps", "cg_tolerance", "cg_max_iterations"});
    IntegratorOptions& io = o.integration;
    io.adaptive = r.boolean(j, f, "adaptive", io.adaptive);
    io.relativeTolerance = r.number(j, f, "rtol", io.relativeTolerance, 0, true, "");
    io.absoluteTolerance = r.number(j, f, "atol", io.absoluteTolerance, 0, false, "");
    io.minSubstep = r.number(j, f, "min_substep", io.minSubstep, 0, false, " s");
    io.maxSubsteps = static_cast<Index>(r.integer(j, f, "max_substeps", io.maxSubsteps, 1, 1 << 30));
    io.linearTolerance = r.number(j, f, "cg_tolerance", io.linearTolerance, 0, true, "");
    if (!(io.linearTolerance < 1))
      r.fail("integration.cg_tolerance", "must be < 1, got " + std::to_string(io.linearTolerance));
    io.maxLinearIterations =
        static_cast<Index>(r.integer(j, f, "cg_max_iterations", io.maxLinearIterations, 1, 1 << 30));
  }
  if (root.contains("stability")) {
    const Json& j = root["stability"];
    r.object(j, "stability", {"enabled", "max_stretch"});
    o.stability.enabled = r.boolean(j, "stability", "enabled", o.stability.enabled);
    o.stability.maxStretch = r.anyNumber(j, "stability", "max_stretch", o.stability.maxStretch);
  }
  if (root.contains("output")) {
    const Json& j = root["output"];
    r.object(j, "output", {"directory", "format", "every"});
    scene.output.directory = r.string(j, "output", "directory", "");
    if (j.contains("directory") && scene.output.directory.empty()) r.fail("output.directory", "must not be empty");
    scene.output.format = r.choice(j, "output", "format", "obj", {"obj", "ply", "cache"});
    scene.output.every = r.integer(j, "output", "every", 1, 1, std::numeric_limits<std::int64_t>::max());
  }
  return scene;
}

SceneSpec readSceneFile(const std::string& path) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) throw SceneError(path + ": is a directory, not a scene file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(path + ": cannot open the scene file: " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw SceneError(path + ": cannot read the scene file");
  const std::filesystem::path p(path);
  const std::string base = p.has_parent_path() ? p.parent_path().string() : std::string(".");
  return parseScene(text.str(), path, base);
}

// ---------------------------------------------------------------------------------------
// Built-in scenes
// ---------------------------------------------------------------------------------------

std::vector<std::string> builtinSceneNames() { return {"flag", "rope", "flag-wind", "hanging-cloth"}; }

SceneSpec builtinSceneSpec(const std::string& name, Index size) {
  SceneSpec scene;
  scene.name = name;
  scene.steps = 2000;
  BodySpec body;
  if (name == "flag" || name == "flag-wind" || name == "hanging-cloth") {
    const Index n = size > 0 ? size : defaultSceneSize(BuiltinScene::Flag);
    if (n < 2) throw SceneError(name + ": size must be >= 2, got " + std::to_string(n));
    body.kind = BodyKind::ClothGrid;
    body.name = "cloth";
    body.grid = flagSpec(n);
    scene.simulation.dt = defaultTimeStep(BuiltinScene::Flag, n);
    const Index last = n - 1;
    if (name == "flag") {
      // Horizontal, pinned at the two corners of row 0 (weft::makeFlag).
      body.pins.push_back({{0, last}, std::nullopt, std::nullopt});
    } else if (name == "flag-wind") {
      // Hanging from a pole along its left edge (column 0), in the x-y plane, in a gusty
      // wind blowing along +x: it streams out and flutters.
      body.grid.origin = {0, 1, 0};
      body.grid.rowAxis = {1, 0, 0};
      body.grid.columnAxis = {0, -1, 0};
      PinSpec pole;
      for (Index r = 0; r < n; ++r) pole.particles.push_back(r * n);
      body.pins.push_back(pole);
      WindEffect& w = scene.simulation.effects.wind;
      w.enabled = true;
      w.velocity = {6, 0, 1};
      w.gustStrength = 2;
      w.gustScale = 1.5;
      w.gustPeriod = 0.8;
      scene.simulation.effects.drag = 1e-4;
    } else {
      // Hanging from a bar along its top edge (row 0), in the x-y plane; the bar turns
      // half a turn about the vertical through its middle in the first second, then holds:
      // the cloth twists and swings. Repulsion keeps the twisting folds apart.
      body.grid.origin = {0, 1, 0};
      body.grid.rowAxis = {1, 0, 0};
      body.grid.columnAxis = {0, -1, 0};
      PinSpec bar;
      for (Index c = 0; c < n; ++c) bar.particles.push_back(c);
      KinematicPath path;
      path.center = {0.5, 1, 0};
      path.axis = {0, 1, 0};
      path.angularVelocity = 3.14159265358979323846;
      path.startTime = 0;
      path.endTime = 1;
      bar.path = path;
      body.pins.push_back(bar);
      scene.simulation.effects.drag = 1e-3;
      scene.simulation.effects.repulsion.radius = 0.5 * body.grid.spacing;
      scene.simulation.effects.repulsion.stiffness = 200;
    }
  } else if (name == "rope") {
    const Index n = size > 0 ? size : defaultSceneSize(BuiltinScene::Rope);
    if (n < 2) throw SceneError(name + ": size must be >= 2, got " + std::to_string(n));
    body.kind = BodyKind::Rope;
    body.name = "rope";
    body.rope = ropeSpec(n);
    body.pins.push_back({{0}, std::nullopt, std::nullopt});
    scene.simulation.dt = defaultTimeStep(BuiltinScene::Rope, n);
  } else {
    std::string list;
    for (const std::string& s : builtinSceneNames()) list += (list.empty() ? "" : ", ") + s;
    throw SceneError("scene must be a built-in scene (" + list + ") or a .json scene file; got '" + name + "'");
  }
  scene.bodies.push_back(body);
  return scene;
}

// ---------------------------------------------------------------------------------------
// Assembly
// ---------------------------------------------------------------------------------------

template <class S>
AssembledScene<S> assembleScene(const SceneSpec& scene) {
  if (scene.bodies.empty()) throw SceneError(scene.name + ": bodies: the scene has no bodies");
  AssembledScene<S> out;
  ModelBuilder<S> builder;
  for (size_t k = 0; k < scene.bodies.size(); ++k) {
    const BodySpec& b = scene.bodies[k];
    const std::string field = scene.name + ": bodies[" + std::to_string(k) + "] (" + b.name + ")";
    const Index first = builder.particleCount();
    out.firstParticle.push_back(first);
    try {
      switch (b.kind) {
        case BodyKind::Rope:
          addRope(builder, b.rope);
          break;
        case BodyKind::ClothGrid:
          addClothGrid(builder, b.grid);
          break;
        case BodyKind::ClothMesh: {
          MeshReport report;
          const TriangleMesh mesh = loadCleanMesh(b.meshFile, b.clean, &report);
          addClothMesh(builder, mesh, b.mesh);
          out.meshReports.push_back(b.meshFile + ": " + report.summary());
          break;
        }
      }
    } catch (const std::exception& e) {
      throw SceneError(field + ": " + e.what());
    }
    const Index count = builder.particleCount() - first;
    for (size_t q = 0; q < b.pins.size(); ++q) {
      const PinSpec& pin = b.pins[q];
      const std::string pf = field + ": pins[" + std::to_string(q) + "]";
      std::vector<Index> selected;
      for (const Index i : pin.particles) {
        if (i < 0 || i >= count)
          throw SceneError(pf + ": particle " + std::to_string(i) + " is not in the body (it has " +
                           std::to_string(count) + " particles)");
        selected.push_back(first + i);
      }
      if (pin.box) {
        const auto& [lo, hi] = *pin.box;
        for (Index i = first; i < first + count; ++i) {
          const Vec3d p = builder.position(i);
          if (p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z)
            selected.push_back(i);
        }
        if (selected.size() == pin.particles.size()) throw SceneError(pf + ": box selects no particle of the body");
      }
      std::sort(selected.begin(), selected.end());
      selected.erase(std::unique(selected.begin(), selected.end()), selected.end());
      for (const Index i : selected) builder.pin(i);
      if (pin.path) {
        KinematicPins moved;
        moved.particles = selected;
        moved.path = *pin.path;
        out.options.kinematicPins.push_back(std::move(moved));
      }
    }
  }
  try {
    out.built = builder.build();
  } catch (const std::exception& e) {
    throw SceneError(scene.name + ": " + e.what());
  }
  std::vector<KinematicPins> pins = std::move(out.options.kinematicPins);
  out.options = scene.simulation;  // its own kinematicPins (C++ scenes, global indices) first
  for (KinematicPins& p : pins) out.options.kinematicPins.push_back(std::move(p));
  return out;
}

template AssembledScene<float> assembleScene(const SceneSpec&);
template AssembledScene<double> assembleScene(const SceneSpec&);

}  // namespace weft
