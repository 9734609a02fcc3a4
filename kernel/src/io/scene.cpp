#include "weft/io/scene.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "builtin_meshes.hpp"
#include "json_reader.hpp"
#include "weft/io/mesh_import.hpp"
#include "weft/scene/builtin_scenes.hpp"
#include "weft/scene/rigid_scenes.hpp"

namespace weft {

using namespace io_detail;  // Json, Reader, fmt, shortDump (json_reader.hpp)

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
// Box pins of bodies up to this size are checked while reading (each a pass over the
// body's particles), those of larger bodies when the scene is assembled: so that reading
// a short file stays fast however large the bodies it asks for.
constexpr Index kMaxScannedParticles = Index(1) << 20;

/// ceil(duration / dt) (a hair less, so that 1 / 0.1 is 10 steps), at least 1, as a double:
/// no overflow whatever the values.
double durationStepCount(double duration, double dt) { return std::max(1.0, std::ceil(duration / dt * (1 - 1e-12))); }

}  // namespace

namespace {
// Heap bytes of an assembled Simulation per particle and per spring, by integrator, for
// double and float: measured with mallinfo2() after assembling and stepping the flag
// (256^2) and the rope (16384) with each integrator and solved for the two rates with 12
// bytes per triangle (three indices); the integrators differ in the state-sized buffers
// they keep (RK4 four stages, RK45 seven, implicit Euler its CG vectors and a 3x3 block
// per spring).
struct Rates {
  double particle, spring;
};
Rates memoryRates(IntegratorKind kind, bool isFloat) {
  switch (kind) {
    case IntegratorKind::ExplicitEuler:
    case IntegratorKind::SymplecticEuler:
      return isFloat ? Rates{66, 38} : Rates{122, 62};
    case IntegratorKind::Midpoint:
    case IntegratorKind::VelocityVerlet:
      return isFloat ? Rates{90, 38} : Rates{170, 62};
    case IntegratorKind::Rk4:
      return isFloat ? Rates{138, 38} : Rates{266, 62};
    case IntegratorKind::Rk45:
      return isFloat ? Rates{259, 38} : Rates{506, 62};
    case IntegratorKind::ImplicitEuler:
      return isFloat ? Rates{158, 82} : Rates{302, 142};
  }
  return {506, 142};  // the largest
}
constexpr double kBytesPerTriangle = 12;
// Resident memory a rigid body's share of the world takes while a pile of them collides
// (pairs, caches, manifolds, constraints), measured on the `pile` (1005 bodies: 6.5 MB).
constexpr double kBytesPerRigidBody = 6500;
}  // namespace

MemoryEstimate estimateSceneMemory(const SceneSpec& scene) {
  MemoryEstimate e;
  for (const BodySpec& body : scene.bodies) {
    switch (body.kind) {
      case BodyKind::ClothGrid: {
        const std::int64_t w = std::max<std::int64_t>(body.grid.width, 0),
                           h = std::max<std::int64_t>(body.grid.height, 0);
        e.particles += w * h;
        for (const Index n : expectedGridSpringCounts(body.grid)) e.springs += std::max<Index>(n, 0);
        e.triangles += 2 * std::max<std::int64_t>(w - 1, 0) * std::max<std::int64_t>(h - 1, 0);
        break;
      }
      case BodyKind::Rope: {
        const std::int64_t n = std::max<std::int64_t>(body.rope.particleCount, 0);
        e.particles += n;
        e.springs += std::max<std::int64_t>(n - 1, 0) + (body.rope.bendSprings ? std::max<std::int64_t>(n - 2, 0) : 0);
        break;
      }
      case BodyKind::ClothMesh:
        ++e.meshBodies;
        e.readsMeshes = true;
        break;
    }
  }
  e.rigidBodies = static_cast<std::int64_t>(scene.simulation.rigid.bodies.size());
  e.readsMeshes = e.readsMeshes || !scene.meshObstacles.empty();
  const Rates r = memoryRates(scene.simulation.integrator, scene.precision == Precision::Float);
  e.bytes = r.particle * static_cast<double>(e.particles) + r.spring * static_cast<double>(e.springs) +
            kBytesPerTriangle * static_cast<double>(e.triangles) +
            kBytesPerRigidBody * static_cast<double>(e.rigidBodies);
  return e;
}

std::int64_t sceneStepCount(const SceneSpec& scene) {
  if (scene.steps > 0) return scene.steps;
  if (scene.duration > 0 && scene.simulation.dt > 0) {
    // The reader caps the count at 2^40; a SceneSpec filled in C++ with a larger one saturates.
    const double n = durationStepCount(scene.duration, scene.simulation.dt);
    return n < 9.2e18 ? static_cast<std::int64_t>(n) : std::numeric_limits<std::int64_t>::max();
  }
  return 0;
}

// ---------------------------------------------------------------------------------------
// JSON reading: a strict walker that knows the path of every value it reads.
// ---------------------------------------------------------------------------------------

namespace {

/// Body-local particle positions at the start, for checking pins while reading: the exact
/// expressions of addRope / addClothGrid, so a box selects here what it selects when the
/// scene is assembled.
struct BodyGeometry {
  Index count = 0;
  std::function<Vec3d(Index)> position;
};

std::optional<BodyGeometry> ropeGeometry(const RopeSpec& s) {
  Vec3d d;
  if (!normalised(s.direction, d)) return std::nullopt;
  const double step = s.length / static_cast<double>(s.particleCount - 1);
  return BodyGeometry{s.particleCount, [s, d, step](Index i) {
                        const double t = step * static_cast<double>(i);
                        return Vec3d{s.origin.x + t * d.x, s.origin.y + t * d.y, s.origin.z + t * d.z};
                      }};
}

std::optional<BodyGeometry> gridGeometry(const ClothGridSpec& s) {
  Vec3d u, w;
  if (!normalised(s.rowAxis, u) || !normalised(s.columnAxis, w)) return std::nullopt;
  return BodyGeometry{
      s.width * s.height, [s, u, w](Index i) {
        const Index r = i / s.width, c = i % s.width;
        const double a = s.spacing * static_cast<double>(c), b = s.spacing * static_cast<double>(r);
        return Vec3d{s.origin.x + a * u.x + b * w.x, s.origin.y + a * u.y + b * w.y, s.origin.z + a * u.z + b * w.z};
      }};
}

bool inBox(const Vec3d& p, const std::pair<Vec3d, Vec3d>& box) {
  const auto& [lo, hi] = box;
  return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z;
}

/// The body-local particles a pin selects: its indices and every particle inside its box
/// (`position` gives body-local positions), sorted, each once.
std::vector<Index> pinSelection(const PinSpec& pin, Index count, const std::function<Vec3d(Index)>& position) {
  std::vector<Index> selected = pin.particles;
  if (pin.box)
    for (Index i = 0; i < count; ++i)
      if (inBox(position(i), *pin.box)) selected.push_back(i);
  std::sort(selected.begin(), selected.end());
  selected.erase(std::unique(selected.begin(), selected.end()), selected.end());
  return selected;
}

/// A particle in the selections of two kinematic pins (the simulation would refuse it).
struct MovedTwice {
  size_t pin;      // the later pin
  Index particle;  // body-local
  size_t earlier;  // the pin that already moves it
  std::string what() const {
    return "particle " + std::to_string(particle) + " is already moved by pins[" + std::to_string(earlier) +
           "]: a particle can follow one path only";
  }
};
/// `selections[q]` is pins[q]'s (see pinSelection).
std::optional<MovedTwice> movedTwice(const std::vector<PinSpec>& pins,
                                     const std::vector<std::vector<Index>>& selections) {
  std::vector<std::pair<Index, size_t>> moved;  // (particle, pin)
  for (size_t q = 0; q < pins.size(); ++q)
    if (pins[q].path)
      for (const Index i : selections[q]) moved.emplace_back(i, q);
  std::sort(moved.begin(), moved.end());
  for (size_t m = 1; m < moved.size(); ++m)
    if (moved[m].first == moved[m - 1].first) return MovedTwice{moved[m].second, moved[m].first, moved[m - 1].second};
  return std::nullopt;
}

std::string particleRange(Index count) {
  return "the body has " + std::to_string(count) + " particles, 0 .. " + std::to_string(count - 1);
}

/// Reads `pins`, one PinSpec per element (so pins[k] of the file is pins[k] of the spec,
/// and of assembly's messages). With the body's geometry (ropes and grids), indices are
/// checked here too, and so are boxes and kinematic pins that would move a particle twice
/// (for bodies up to kMaxScannedParticles); the rest is checked when assembled.
std::vector<PinSpec> readPins(const Reader& r, const Json& body, const std::string& field,
                              const BodyGeometry* geometry) {
  std::vector<PinSpec> pins;
  if (!body.contains("pins")) return pins;
  const std::string f = Reader::join(field, "pins");
  const Json& j = body["pins"];
  if (!j.is_array()) r.fail(f, std::string("must be an array, got ") + typeName(j) + " " + shortDump(j));
  const auto index = [&](const Json& v, const std::string& fv) {
    if (!v.is_number_integer() || v.get<std::int64_t>() < 0 || v.get<std::int64_t>() > (1ll << 31) - 1 ||
        (v.is_number_unsigned() && v.get<std::uint64_t>() > (1ull << 31) - 1))
      r.fail(fv, "must be a particle index (an integer >= 0), got " + shortDump(v));
    const Index i = static_cast<Index>(v.get<std::int64_t>());
    if (geometry && i >= geometry->count)
      r.fail(fv, "particle " + std::to_string(i) + " is not in the body (" + particleRange(geometry->count) + ")");
    return i;
  };
  for (size_t k = 0; k < j.size(); ++k) {
    const std::string fk = f + "[" + std::to_string(k) + "]";
    const Json& e = j[k];
    PinSpec p;
    if (e.is_number()) {  // a bare index: that particle, fixed
      p.particles.push_back(index(e, fk));
      pins.push_back(std::move(p));
      continue;
    }
    if (!e.is_object())
      r.fail(fk, std::string("must be a particle index or an object with particles, box, path; got ") + typeName(e) +
                     " " + shortDump(e));
    r.object(e, fk, {"particles", "box", "path"});
    if (e.contains("particles")) {
      const Json& list = e["particles"];
      const std::string fp = fk + ".particles";
      if (!list.is_array() || list.empty())
        r.fail(fp, std::string("must be a non-empty array of particle indices, got ") + typeName(list) + " " +
                       shortDump(list));
      for (size_t q = 0; q < list.size(); ++q)
        p.particles.push_back(index(list[q], fp + "[" + std::to_string(q) + "]"));
    }
    if (e.contains("box")) {
      const std::string fb = fk + ".box";
      r.object(e["box"], fb, {"min", "max"});
      if (!e["box"].contains("min") || !e["box"].contains("max"))
        r.fail(fb, "needs both min and max, got " + shortDump(e["box"]));
      const Vec3d lo = r.vector(e["box"], fb, "min", {}), hi = r.vector(e["box"], fb, "max", {});
      if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z))
        r.fail(fb, "min must be <= max in every coordinate, got min " + fmt(lo) + ", max " + fmt(hi));
      p.box = std::make_pair(lo, hi);
      if (geometry && geometry->count <= kMaxScannedParticles) {
        bool any = false;
        for (Index i = 0; i < geometry->count && !any; ++i) any = inBox(geometry->position(i), *p.box);
        if (!any)
          r.fail(fb, "selects no particle of the body: none is inside min " + fmt(lo) + ", max " + fmt(hi) +
                         " at the start (the body spans " + fmt(geometry->position(0)) + " .. " +
                         fmt(geometry->position(geometry->count - 1)) + ")");
      }
    }
    if (!e.contains("particles") && !e.contains("box")) r.fail(fk, "needs particles or box, got " + shortDump(e));
    if (e.contains("path")) p.path = readPath(r, e["path"], fk + ".path");
    pins.push_back(std::move(p));
  }
  if (geometry && geometry->count <= kMaxScannedParticles) {
    std::vector<std::vector<Index>> selections(pins.size());
    for (size_t q = 0; q < pins.size(); ++q)
      if (pins[q].path) selections[q] = pinSelection(pins[q], geometry->count, geometry->position);
    if (const auto twice = movedTwice(pins, selections))
      r.fail(f + "[" + std::to_string(twice->pin) + "]", twice->what());
  }
  return pins;
}

/// Total mass from total_mass or particle_mass (the other one's key), checked to give
/// particles of a finite, non-zero mass.
double readMass(const Reader& r, const Json& j, const std::string& f, double fallback, Index particles) {
  double total = r.number(j, f, "total_mass", fallback, 0, false, " kg");
  if (j.contains("particle_mass")) {
    if (j.contains("total_mass"))
      r.fail(f, "give total_mass or particle_mass, not both (total_mass " + shortDump(j["total_mass"]) +
                    ", particle_mass " + shortDump(j["particle_mass"]) + ")");
    total = r.number(j, f, "particle_mass", 0, 0, false, " kg") * static_cast<double>(particles);
    if (!std::isfinite(total))
      r.fail(Reader::join(f, "particle_mass"), "times " + std::to_string(particles) +
                                                   " particles is not a finite mass, got " +
                                                   shortDump(j["particle_mass"]));
  } else if (!(total / static_cast<double>(particles) > 0)) {
    r.fail(Reader::join(f, "total_mass"),
           "spread over " + std::to_string(particles) + " particles gives particles of mass 0, got " + fmt(total));
  }
  return total;
}

/// The mesh file must exist and be a readable regular file; checked here so that the
/// message names the scene file and the field. (Its contents are read when the scene is
/// assembled.)
void checkMeshFile(const Reader& r, const Json& j, const std::string& f, const std::string& path) {
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  std::string problem;
  if (status.type() == std::filesystem::file_type::not_found)
    problem = "no such file";
  else if (error)
    problem = error.message();
  else if (std::filesystem::is_directory(status))
    problem = "is a directory";
  else if (!std::filesystem::is_regular_file(status))
    problem = "is not a regular file";
  else if (!std::ifstream(path, std::ios::binary))
    problem = std::strerror(errno);
  if (problem.empty()) return;
  const std::string given = j["mesh"].get<std::string>();
  r.fail(Reader::join(f, "mesh"), "cannot read the mesh file " + shortDump(j["mesh"]) +
                                      (given != path ? " (" + shortDump(Json(path)) + ")" : std::string()) + ": " +
                                      problem);
}

BodySpec readBody(const Reader& r, const Json& j, const std::string& f, const std::string& baseDirectory) {
  if (!j.is_object()) r.fail(f, std::string("must be an object, got ") + typeName(j) + " " + shortDump(j));
  BodySpec b;
  if (!j.contains("type")) r.fail(Reader::join(f, "type"), "is required: rope, cloth_grid or cloth_mesh");
  const std::string type = r.choice(j, f, "type", "", {"rope", "cloth_grid", "cloth_mesh"});
  b.name = r.string(j, f, "name", type);
  const std::string fm = Reader::join(f, "materials");
  std::optional<BodyGeometry> geometry;
  if (type == "rope") {
    b.kind = BodyKind::Rope;
    r.object(j, f,
             {"type", "name", "particles", "origin", "direction", "length", "total_mass", "particle_mass", "materials",
              "bend_springs", "pins", "velocity"});
    RopeSpec& s = b.rope;
    s.particleCount = static_cast<Index>(r.integer(j, f, "particles", s.particleCount, 2, 1 << 24));
    s.origin = r.vector(j, f, "origin", s.origin);
    s.direction = r.direction(j, f, "direction", s.direction);
    s.length = r.number(j, f, "length", s.length, 0, false, " m");
    s.totalMass = readMass(r, j, f, s.totalMass, s.particleCount);
    s.bendSprings = r.boolean(j, f, "bend_springs", s.bendSprings);
    if (j.contains("materials")) {
      r.object(j["materials"], fm, {"structural", "bend"});
      s.structural = r.material(j["materials"], fm, "structural", s.structural);
      s.bend = r.material(j["materials"], fm, "bend", s.bend);
    }
    geometry = ropeGeometry(s);
    if (!finite(geometry->position(s.particleCount - 1)))
      r.fail(f, "the rope's far end " + fmt(geometry->position(s.particleCount - 1)) +
                    " is not finite: origin, direction or length is too large");
  } else if (type == "cloth_grid") {
    b.kind = BodyKind::ClothGrid;
    r.object(j, f,
             {"type", "name", "width", "height", "origin", "row_axis", "column_axis", "spacing", "total_mass",
              "particle_mass", "materials", "shear_springs", "bend_springs", "pins", "velocity"});
    ClothGridSpec& s = b.grid;
    s.width = static_cast<Index>(r.integer(j, f, "width", s.width, 2, 1 << 15));
    s.height = static_cast<Index>(r.integer(j, f, "height", s.height, 2, 1 << 15));
    if (static_cast<std::int64_t>(s.width) * s.height > (1 << 26))
      r.fail(f, "width x height must be <= 2^26 particles, got " + std::to_string(s.width) + " x " +
                    std::to_string(s.height));
    s.origin = r.vector(j, f, "origin", s.origin);
    s.rowAxis = r.direction(j, f, "row_axis", s.rowAxis);
    s.columnAxis = r.direction(j, f, "column_axis", s.columnAxis);
    {
      // The test addClothGrid applies, on the normalised axes.
      Vec3d u, w;
      normalised(s.rowAxis, u);
      normalised(s.columnAxis, w);
      const double cx = u.y * w.z - u.z * w.y, cy = u.z * w.x - u.x * w.z, cz = u.x * w.y - u.y * w.x;
      if (!(std::sqrt(cx * cx + cy * cy + cz * cz) > 1e-6))
        r.fail(Reader::join(f, "column_axis"),
               "must not be parallel to row_axis, got " + fmt(s.columnAxis) + " and row_axis " + fmt(s.rowAxis));
    }
    s.spacing = r.number(j, f, "spacing", 1.0 / (s.width - 1), 0, false, " m");
    s.totalMass = readMass(r, j, f, s.totalMass, s.width * s.height);
    s.shearSprings = r.boolean(j, f, "shear_springs", s.shearSprings);
    s.bendSprings = r.boolean(j, f, "bend_springs", s.bendSprings);
    if (j.contains("materials")) {
      r.object(j["materials"], fm, {"structural", "shear", "bend"});
      s.structural = r.material(j["materials"], fm, "structural", s.structural);
      s.shear = r.material(j["materials"], fm, "shear", s.shear);
      s.bend = r.material(j["materials"], fm, "bend", s.bend);
    }
    geometry = gridGeometry(s);
    for (const Index corner : {s.width - 1, s.width * (s.height - 1), s.width * s.height - 1})
      if (!finite(geometry->position(corner)))
        r.fail(f, "the grid's corner " + fmt(geometry->position(corner)) +
                      " is not finite: origin, spacing or size is too large");
  } else {
    b.kind = BodyKind::ClothMesh;
    r.object(j, f,
             {"type", "name", "mesh", "weld_tolerance", "scale", "translate", "total_mass", "areal_density",
              "materials", "bend_springs", "pins", "velocity"});
    if (!j.contains("mesh")) r.fail(Reader::join(f, "mesh"), "is required: the path of the mesh file");
    const std::string mesh = r.pathString(j, f, "mesh");
    const std::filesystem::path p(mesh);
    b.meshFile = p.is_absolute() ? mesh : (std::filesystem::path(baseDirectory) / p).lexically_normal().string();
    checkMeshFile(r, j, f, b.meshFile);
    b.clean.weldTolerance = r.number(j, f, "weld_tolerance", b.clean.weldTolerance, 0, true, " m");
    ClothMeshSpec& s = b.mesh;
    s.scale = r.number(j, f, "scale", s.scale, 0, false, "");
    s.translate = r.vector(j, f, "translate", s.translate);
    if (j.contains("total_mass") && j.contains("areal_density"))
      r.fail(f, "give total_mass or areal_density, not both (total_mass " + shortDump(j["total_mass"]) +
                    ", areal_density " + shortDump(j["areal_density"]) + ")");
    s.totalMass = r.number(j, f, "total_mass", s.totalMass, 0, false, " kg");
    s.arealDensity = r.number(j, f, "areal_density", s.arealDensity, 0, false, " kg/m^2");
    s.bendSprings = r.boolean(j, f, "bend_springs", s.bendSprings);
    if (j.contains("materials")) {
      r.object(j["materials"], fm, {"structural", "bend"});
      s.structural = r.material(j["materials"], fm, "structural", s.structural);
      s.bend = r.material(j["materials"], fm, "bend", s.bend);
    }
  }
  b.velocity = r.vector(j, f, "velocity", b.velocity);
  b.pins = readPins(r, j, f, geometry ? &*geometry : nullptr);
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
    for (const char* key : {"radius", "stiffness"})
      if (!rep.contains(key))
        r.fail(Reader::join(fr, key),
               "is required: repulsion needs radius (m, >= 1e-9) and stiffness (N/m, > 0), got " + shortDump(rep));
    e.repulsion.radius = r.number(rep, fr, "radius", 0, 1e-9, true, " m");
    e.repulsion.stiffness = r.number(rep, fr, "stiffness", 0, 0, false, " N/m");
  }
  return e;
}

/// An obstacle's surface: restitution in [0, 1], friction coefficients mu_k <= mu_s.
template <class T>
void readSurface(const Reader& r, const Json& j, const std::string& f, T& o) {
  o.restitution = r.number(j, f, "restitution", o.restitution, 0, true, "");
  if (o.restitution > 1) r.fail(Reader::join(f, "restitution"), "must be <= 1, got " + shortDump(j["restitution"]));
  o.staticFriction = r.number(j, f, "static_friction", o.staticFriction, 0, true, "");
  o.kineticFriction = r.number(j, f, "kinetic_friction", std::min(o.kineticFriction, o.staticFriction), 0, true, "");
  if (o.kineticFriction > o.staticFriction)
    r.fail(Reader::join(f, "kinetic_friction"),
           "must be <= static_friction (" + fmt(o.staticFriction) + "), got " + fmt(o.kineticFriction));
}

/// The `collision` section: options, analytic obstacles into `c`, mesh obstacles (read at
/// assembly) into `meshes`.
void readCollision(const Reader& r, const Json& j, const std::string& f, const std::string& baseDirectory,
                   CollisionOptions& c, std::vector<MeshObstacleSpec>& meshes) {
  r.object(j, f,
           {"obstacles", "thickness", "continuous", "edges", "feature_angle", "epsilon", "resting_speed",
            "max_penetration", "max_halvings"});
  c.thickness = r.number(j, f, "thickness", c.thickness, 0, false, " m");
  c.continuous = r.boolean(j, f, "continuous", c.continuous);
  c.edges = r.boolean(j, f, "edges", c.edges);
  c.featureAngle = r.number(j, f, "feature_angle", c.featureAngle, 0, true, " degrees");
  if (c.featureAngle > 180)
    r.fail(Reader::join(f, "feature_angle"), "must be <= 180 degrees, got " + shortDump(j["feature_angle"]));
  c.epsilon = r.number(j, f, "epsilon", std::min(c.epsilon, 0.5 * c.thickness), 0, false, " m");
  if (!(c.epsilon < c.thickness))
    r.fail(Reader::join(f, "epsilon"), "must be < thickness (" + fmt(c.thickness) + " m), got " + fmt(c.epsilon));
  c.restingSpeed = r.number(j, f, "resting_speed", c.restingSpeed, 0, true, " m/s");
  c.maxPenetration = r.number(j, f, "max_penetration", c.maxPenetration, 0, true, " m");
  c.maxHalvings = static_cast<int>(r.integer(j, f, "max_halvings", c.maxHalvings, 0, 30));
  if (!j.contains("obstacles")) r.fail(Reader::join(f, "obstacles"), "is required: a non-empty array of obstacles");
  const std::string fo = Reader::join(f, "obstacles");
  const Json& list = j["obstacles"];
  if (!list.is_array() || list.empty())
    r.fail(fo, std::string("must be a non-empty array, got ") + typeName(list) + " " + shortDump(list));
  for (size_t k = 0; k < list.size(); ++k) {
    const std::string fk = fo + "[" + std::to_string(k) + "]";
    const Json& e = list[k];
    if (!e.is_object()) r.fail(fk, std::string("must be an object, got ") + typeName(e) + " " + shortDump(e));
    if (!e.contains("type")) r.fail(Reader::join(fk, "type"), "is required: plane, sphere, capsule, box or mesh");
    const std::string type = r.choice(e, fk, "type", "", {"plane", "sphere", "capsule", "box", "mesh"});
    const auto require = [&](std::initializer_list<const char*> needed) {
      for (const char* key : needed)
        if (!e.contains(key)) r.fail(Reader::join(fk, key), "is required for a " + type + " obstacle");
    };
    if (type == "mesh") {
      r.object(e, fk,
               {"type", "name", "mesh", "weld_tolerance", "scale", "translate", "path", "restitution",
                "static_friction", "kinetic_friction"});
      require({"mesh"});
      MeshObstacleSpec m;
      const std::string mesh = r.pathString(e, fk, "mesh");
      const std::filesystem::path p(mesh);
      m.meshFile = p.is_absolute() ? mesh : (std::filesystem::path(baseDirectory) / p).lexically_normal().string();
      checkMeshFile(r, e, fk, m.meshFile);
      m.obstacle.name = r.string(e, fk, "name", p.filename().string());
      m.clean.weldTolerance = r.number(e, fk, "weld_tolerance", m.clean.weldTolerance, 0, true, " m");
      m.scale = r.number(e, fk, "scale", m.scale, 0, false, "");
      m.translate = r.vector(e, fk, "translate", m.translate);
      if (e.contains("path")) m.obstacle.path = readPath(r, e["path"], Reader::join(fk, "path"));
      readSurface(r, e, fk, m.obstacle);
      meshes.push_back(std::move(m));
      continue;
    }
    Obstacle o;
    if (type == "plane") {
      r.object(e, fk, {"type", "point", "normal", "restitution", "static_friction", "kinetic_friction"});
      require({"point", "normal"});
      o = Obstacle::plane(r.vector(e, fk, "point", {}), r.direction(e, fk, "normal", {}));
    } else if (type == "sphere") {
      r.object(e, fk, {"type", "center", "radius", "restitution", "static_friction", "kinetic_friction"});
      require({"center", "radius"});
      o = Obstacle::sphere(r.vector(e, fk, "center", {}), r.number(e, fk, "radius", 0, 0, false, " m"));
    } else if (type == "capsule") {
      r.object(e, fk, {"type", "a", "b", "radius", "restitution", "static_friction", "kinetic_friction"});
      require({"a", "b", "radius"});
      o = Obstacle::capsule(r.vector(e, fk, "a", {}), r.vector(e, fk, "b", {}),
                            r.number(e, fk, "radius", 0, 0, false, " m"));
    } else {
      r.object(e, fk,
               {"type", "center", "half_extents", "radius", "restitution", "static_friction", "kinetic_friction"});
      require({"center", "half_extents"});
      o = Obstacle::box(r.vector(e, fk, "center", {}), r.vector(e, fk, "half_extents", {}));
      const Vec3d& h = o.halfExtents;
      if (!(h.x > 0 && h.y > 0 && h.z > 0))
        r.fail(Reader::join(fk, "half_extents"), "must be > 0 m in every axis, got " + fmt(h));
      o.radius = r.number(e, fk, "radius", 0, 0, true, " m");
      const double smallest = std::min({h.x, h.y, h.z});
      if (o.radius > smallest)
        r.fail(Reader::join(fk, "radius"), "(the rounding of the edges) must be <= the smallest half extent (" +
                                               fmt(smallest) + " m), got " + fmt(o.radius));
    }
    readSurface(r, e, fk, o);
    c.obstacles.push_back(o);
  }
}

/// Scene-wide values the step converts to S must be within S's range (1e39 is a double
/// but no float): checked while reading for the file's precision, and when assembling for
/// the one asked for, rather than left to become infinities in the step or an exception of
/// the simulation's. `fail(field, what)` does not return.
template <class S>
void requireScalarRange(const SimulationOptions& o,
                        const std::function<void(const std::string&, const std::string&)>& fail) {
  const double big = static_cast<double>(std::numeric_limits<S>::max());
  const auto check = [&](const char* field, double value) {
    if (!(std::abs(value) <= big))
      fail(field, std::string("must be within the range of ") + (sizeof(S) == sizeof(float) ? "float" : "double") +
                      " precision (|value| <= " + fmt(big) + "), got " + fmt(value));
  };
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

/// "1 body", "3 bodies", ...
std::string bodiesText(const SceneSpec& scene) {
  return std::to_string(scene.bodies.size()) + (scene.bodies.size() == 1 ? " body" : " bodies") +
         (scene.bodies.empty() ? std::string() : std::string(", the first a ") + bodyKindName(scene.bodies[0].kind));
}

}  // namespace

SceneSpec parseScene(const std::string& text, const std::string& source, const std::string& baseDirectory) {
  Json root;
  JsonPathTracker tracker(source);
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
            "gravity", "effects", "collision", "rigid_bodies", "integration", "stability", "output"});
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
  const std::string integrator =
      r.choice(root, "", "integrator", "rk4", {"euler", "symplectic", "midpoint", "rk4", "verlet", "rk45", "implicit"});
  o.integrator = parseIntegrator(integrator);
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
  o.forceStrategy = parseForceStrategy(
      r.choice(root, "", "force_strategy", "auto", {"auto", "gather", "coloured", "colored", "grid-stencil", "grid"}));
  if (o.forceStrategy == ForceStrategy::GridStencil &&
      !(scene.bodies.size() == 1 && scene.bodies[0].kind == BodyKind::ClothGrid))
    r.fail("force_strategy", "grid-stencil needs a scene of a single cloth_grid body, got " + bodiesText(scene));
  o.gravity = r.vector(root, "", "gravity", o.gravity);
  if (root.contains("effects")) o.effects = readEffects(r, root["effects"], "effects");
  if (root.contains("collision"))
    readCollision(r, root["collision"], "collision", baseDirectory, o.collision, scene.meshObstacles);
  if (root.contains("rigid_bodies")) o.rigid = readRigidBodies(r, root["rigid_bodies"], "rigid_bodies");
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
      r.fail("integration.cg_tolerance", "must be < 1, got " + shortDump(j["cg_tolerance"]));
    io.maxLinearIterations =
        static_cast<Index>(r.integer(j, f, "cg_max_iterations", io.maxLinearIterations, 1, 1 << 30));
  }
  if (root.contains("stability")) {
    const Json& j = root["stability"];
    r.object(j, "stability", {"enabled", "max_stretch"});
    o.stability.enabled = r.boolean(j, "stability", "enabled", o.stability.enabled);
    o.stability.maxStretch = r.anyNumber(j, "stability", "max_stretch", o.stability.maxStretch);
  }
  if (scene.precision == Precision::Float)
    requireScalarRange<float>(o, [&r](const std::string& field, const std::string& what) { r.fail(field, what); });
  if (root.contains("output")) {
    const Json& j = root["output"];
    r.object(j, "output", {"directory", "format", "every"});
    if (j.contains("directory")) scene.output.directory = r.pathString(j, "output", "directory");
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

// ---------------------------------------------------------------------------------------
// Built-in scenes
// ---------------------------------------------------------------------------------------

std::vector<std::string> builtinSceneNames() {
  return {"flag",         "rope",      "flag-wind",        "hanging-cloth",  "drape", "drape-mesh",
          "rope-on-pegs", "fast-ball", "ball-on-brick",    "stack",          "pile",  "bullet",
          "slope",        "hammock",   "tablecloth-trick", "tablecloth-slow"};
}

SceneSpec builtinSceneSpec(const std::string& name, Index size) {
  SceneSpec scene;
  scene.name = name;
  scene.steps = 2000;
  // Rigid bodies only (weft/scene/rigid_scenes.hpp), 1/60 s steps: 10 s, the pile 5 s,
  // the bullet 0.5 s. --size is the number of boxes (stack) or bodies (pile).
  const auto rigidOnly = [&](RigidOptions rigid, double seconds) {
    scene.simulation.rigid = std::move(rigid);
    scene.simulation.dt = rigidSceneTimeStep();
    scene.steps = static_cast<std::int64_t>(std::lround(seconds / scene.simulation.dt));
    return scene;
  };
  const auto count = [&](Index fallback) { return size > 0 ? size : fallback; };
  if (name == "ball-on-brick") return rigidOnly(ballOnBrickScene(), 10);
  if (name == "stack") return rigidOnly(stackScene(count(10)), 10);
  if (name == "pile") return rigidOnly(pileScene(count(1000)), 5);
  if (name == "bullet") return rigidOnly(bulletScene(200), 0.5);
  if (name == "slope") return rigidOnly(slopeScene(30, 0.3), 2);
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
  } else if (name == "hammock") {
    // A 1 kg ball dropped into a cloth pinned at its four corners (size x size, default 24;
    // weft/scene/rigid_scenes.hpp): particles and the body push each other; 6 s.
    const Index n = size > 0 ? size : 24;
    if (n < 2) throw SceneError(name + ": size must be >= 2, got " + std::to_string(n));
    body.kind = BodyKind::ClothGrid;
    body.name = "cloth";
    body.grid = hammockCloth(n);
    body.pins.push_back({hammockPins(n), std::nullopt, std::nullopt});
    scene.simulation.dt = defaultTimeStep(BuiltinScene::Flag, n);
    scene.steps = static_cast<std::int64_t>(std::ceil(6.0 / scene.simulation.dt));
    scene.simulation.effects.drag = 0.03;  // a heavy, damped fabric: the ball comes to rest
    scene.simulation.rigid = hammockBall();
  } else if (name == "tablecloth-trick" || name == "tablecloth-slow") {
    // Two boxes and a ball on a 1 m cloth (size x size, default 32) on a table; the
    // cloth's +x edge is pulled along +x (weft/scene/rigid_scenes.hpp): at 4 m/s it slides
    // out from under them and they stay (1 s); at 0.4 m/s they come along (2 s).
    const bool fast = name == "tablecloth-trick";
    const Index n = size > 0 ? size : 32;
    if (n < 2) throw SceneError(name + ": size must be >= 2, got " + std::to_string(n));
    body.kind = BodyKind::ClothGrid;
    body.name = "cloth";
    body.grid = tableclothCloth(n);
    body.pins.push_back({tableclothGrip(n), std::nullopt, tableclothPull(fast ? 4.0 : 0.4)});
    scene.simulation.integrator = IntegratorKind::SymplecticEuler;
    scene.simulation.dt = defaultTimeStep(BuiltinScene::Flag, n);
    scene.steps = static_cast<std::int64_t>(std::ceil((fast ? 1.0 : 2.0) / scene.simulation.dt));
    scene.simulation.rigid = tableclothBodies();
  } else if (name == "rope") {
    const Index n = size > 0 ? size : defaultSceneSize(BuiltinScene::Rope);
    if (n < 2) throw SceneError(name + ": size must be >= 2, got " + std::to_string(n));
    body.kind = BodyKind::Rope;
    body.name = "rope";
    body.rope = ropeSpec(n);
    body.pins.push_back({{0}, std::nullopt, std::nullopt});
    scene.simulation.dt = defaultTimeStep(BuiltinScene::Rope, n);
  } else if (name == "drape" || name == "drape-mesh") {
    // A free 1 m cloth (size x size, default 32) falling from 0.5 m, a floor at y = -0.4; 2 s.
    // drape: onto a sphere of radius 0.3 m at the origin. drape-mesh: onto a torus lying
    // flat around the origin (major radius 0.3 m, tube 0.1 m: 1536 triangles), imported
    // from the OBJ file embedded in the library (tools/scenes/meshes/torus.obj, in cm).
    const Index n = size > 0 ? size : 32;
    if (n < 2) throw SceneError(name + ": size must be >= 2, got " + std::to_string(n));
    body.kind = BodyKind::ClothGrid;
    body.name = "cloth";
    body.grid = flagSpec(n);
    body.grid.origin = {-0.5, 0.5, -0.5};
    scene.simulation.dt = defaultTimeStep(BuiltinScene::Flag, n);
    scene.steps = static_cast<std::int64_t>(std::ceil(2.0 / scene.simulation.dt));
    scene.simulation.effects.drag = 1e-3;
    if (name == "drape") scene.simulation.collision.obstacles.push_back(Obstacle::sphere({0, 0, 0}, 0.3));
    scene.simulation.collision.obstacles.push_back(Obstacle::plane({0, -0.4, 0}, {0, 1, 0}));
    if (name == "drape-mesh") {
      MeshObstacleSpec torus;
      torus.obstacle.name = "torus";
      torus.meshFile = "torus.obj";
      torus.meshContents = std::string(builtinTorusObj());
      torus.scale = 0.01;
      scene.meshObstacles.push_back(std::move(torus));
    }
  } else if (name == "rope-on-pegs") {
    // A free 1 m rope (size particles, default 64) falling from 0.3 m across three pegs
    // (capsules along z, radius 3 cm, at x = 0.2, 0.5, 0.8, y = 0), a floor at y = -0.6; 2 s.
    const Index n = size > 0 ? size : defaultSceneSize(BuiltinScene::Rope);
    if (n < 2) throw SceneError(name + ": size must be >= 2, got " + std::to_string(n));
    body.kind = BodyKind::Rope;
    body.name = "rope";
    body.rope = ropeSpec(n);
    body.rope.origin = {0, 0.3, 0};
    scene.simulation.dt = defaultTimeStep(BuiltinScene::Rope, n);
    scene.steps = static_cast<std::int64_t>(std::ceil(2.0 / scene.simulation.dt));
    for (const double x : {0.2, 0.5, 0.8})
      scene.simulation.collision.obstacles.push_back(Obstacle::capsule({x, 0, -0.2}, {x, 0, 0.2}, 0.03));
    scene.simulation.collision.obstacles.push_back(Obstacle::plane({0, -0.6, 0}, {0, 1, 0}));
  } else if (name == "fast-ball") {
    // The tunnelling case: a small soft cloth (size x size particles, default 4, 5 cm) fired
    // at 100 m/s along +x at a wall of one triangle in the plane x = 1, dt = 1/60 s (1.7 m
    // per step); 1 s.
    const Index n = size > 0 ? size : 4;
    if (n < 2) throw SceneError(name + ": size must be >= 2, got " + std::to_string(n));
    body.kind = BodyKind::ClothGrid;
    body.name = "ball";
    body.grid = flagSpec(n);
    body.grid.spacing = 0.05 / static_cast<double>(n - 1);
    body.grid.origin = {0, 0, -0.025};
    body.grid.columnAxis = {0, 1, 0};
    body.grid.rowAxis = {0, 0, 1};
    body.grid.totalMass = 0.05;
    body.grid.structural = {2, 0.01};
    body.grid.shear = {1, 0.005};
    body.grid.bend = {0.5, 0.002};
    body.velocity = {100, 0, 0};
    scene.simulation.dt = 1.0 / 60;
    scene.steps = 60;
    MeshObstacle wall;
    wall.name = "wall";
    wall.mesh.vertices = {{1, -10, -10}, {1, 10, -10}, {1, 0, 20}};
    wall.mesh.triangles = {{0, 1, 2}};
    scene.simulation.collision.meshes.push_back(wall);
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
  if (scene.bodies.empty() && scene.simulation.rigid.bodies.empty())
    throw SceneError(scene.name + ": bodies: the scene has no bodies (and no rigid bodies)");
  requireScalarRange<S>(scene.simulation, [&](const std::string& field, const std::string& what) {
    throw SceneError(scene.name + ": " + field + ": " + what);
  });
  AssembledScene<S> out;
  ModelBuilder<S> builder;
  for (size_t k = 0; k < scene.bodies.size(); ++k) {
    const BodySpec& b = scene.bodies[k];
    const std::string field = scene.name + ": bodies[" + std::to_string(k) + "]";
    const Index first = builder.particleCount();
    out.firstParticle.push_back(first);
    TriangleMesh mesh;
    if (b.kind == BodyKind::ClothMesh) {
      MeshReport report;
      try {
        mesh = loadCleanMesh(b.meshFile, b.clean, &report);  // its messages name the file
      } catch (const std::exception& e) {
        throw SceneError(field + ".mesh: " + e.what());
      }
      out.meshReports.push_back(b.meshFile + ": " + report.summary());
    }
    try {
      switch (b.kind) {
        case BodyKind::Rope:
          addRope(builder, b.rope);
          break;
        case BodyKind::ClothGrid:
          addClothGrid(builder, b.grid);
          break;
        case BodyKind::ClothMesh:
          addClothMesh(builder, mesh, b.mesh);
          break;
      }
    } catch (const std::exception& e) {
      throw SceneError(field + " (" + b.name + "): " + e.what());
    }
    const Index count = builder.particleCount() - first;
    const auto position = [&builder, first](Index i) { return builder.position(first + i); };
    std::vector<std::vector<Index>> selections;
    for (size_t q = 0; q < b.pins.size(); ++q) {
      const PinSpec& pin = b.pins[q];
      const std::string pf = field + ".pins[" + std::to_string(q) + "]";
      for (const Index i : pin.particles)
        if (i < 0 || i >= count)
          throw SceneError(pf + ": particle " + std::to_string(i) + " is not in the body (" + particleRange(count) +
                           ")");
      if (pin.box && pinSelection(PinSpec{{}, pin.box, std::nullopt}, count, position).empty())
        throw SceneError(pf + ".box: selects no particle of the body: none is inside min " + fmt(pin.box->first) +
                         ", max " + fmt(pin.box->second) + " at the start");
      selections.push_back(pinSelection(pin, count, position));
      for (const Index i : selections.back()) builder.pin(first + i);
      if (pin.path) {
        KinematicPins kinematic;
        for (const Index i : selections.back()) kinematic.particles.push_back(first + i);
        kinematic.path = *pin.path;
        out.options.kinematicPins.push_back(std::move(kinematic));
      }
    }
    if (const auto twice = movedTwice(b.pins, selections))
      throw SceneError(field + ".pins[" + std::to_string(twice->pin) + "]: " + twice->what());
  }
  try {
    out.built = builder.build();
  } catch (const std::exception& e) {
    throw SceneError(scene.name + ": " + e.what());
  }
  if (scene.simulation.forceStrategy == ForceStrategy::GridStencil && !out.built.model.grid())
    throw SceneError(scene.name + ": force_strategy: grid-stencil needs a scene of a single cloth_grid body, got " +
                     bodiesText(scene));
  for (size_t k = 0; k < scene.bodies.size(); ++k) {  // initial velocities of the free particles
    const Vec3d& v = scene.bodies[k].velocity;
    if (v.x == 0 && v.y == 0 && v.z == 0) continue;
    if (!(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z)))
      throw SceneError(scene.name + ": bodies[" + std::to_string(k) + "].velocity: must be finite, got " + fmt(v));
    const double big = static_cast<double>(std::numeric_limits<S>::max());
    if (!(std::abs(v.x) <= big && std::abs(v.y) <= big && std::abs(v.z) <= big))
      throw SceneError(scene.name + ": bodies[" + std::to_string(k) + "].velocity: must be within the range of " +
                       (sizeof(S) == sizeof(float) ? "float" : "double") + " precision (|value| <= " + fmt(big) +
                       "), got " + fmt(v));
    const Index end = k + 1 < scene.bodies.size() ? out.firstParticle[k + 1] : out.built.model.particleCount();
    for (Index i = out.firstParticle[k]; i < end; ++i)
      if (!out.built.model.isPinned(i)) {
        out.built.state.v(i, 0) = static_cast<S>(v.x);
        out.built.state.v(i, 1) = static_cast<S>(v.y);
        out.built.state.v(i, 2) = static_cast<S>(v.z);
      }
  }
  std::vector<KinematicPins> pins = std::move(out.options.kinematicPins);
  out.options = scene.simulation;  // its own kinematicPins (C++ scenes, global indices) first
  for (KinematicPins& p : pins) out.options.kinematicPins.push_back(std::move(p));
  for (size_t k = 0; k < scene.meshObstacles.size(); ++k) {
    const MeshObstacleSpec& m = scene.meshObstacles[k];
    const std::string field = scene.name + ": mesh obstacle " + std::to_string(k) +
                              (m.obstacle.name.empty() ? std::string() : " (" + m.obstacle.name + ")");
    MeshObstacle obstacle = m.obstacle;
    MeshReport report;
    try {
      if (!(std::isfinite(m.scale) && m.scale > 0))
        throw std::invalid_argument("scale must be finite and > 0, got " + fmt(m.scale));
      if (!finite(m.translate)) throw std::invalid_argument("translate must be finite, got " + fmt(m.translate));
      obstacle.mesh = m.meshContents.empty() ? loadCleanMesh(m.meshFile, m.clean, &report)
                                             : loadCleanMeshFromMemory(m.meshContents, m.meshFile, m.clean, &report);
      for (Vec3d& p : obstacle.mesh.vertices) {
        p = {m.scale * p.x + m.translate.x, m.scale * p.y + m.translate.y, m.scale * p.z + m.translate.z};
        if (!finite(p))
          throw std::invalid_argument("a vertex scaled and translated is not finite: " + fmt(p) +
                                      " (scale or translate too large)");
      }
    } catch (const std::exception& e) {
      throw SceneError(field + ": " + e.what());
    }
    out.meshReports.push_back(m.meshFile + " (obstacle): " + report.summary());
    out.options.collision.meshes.push_back(std::move(obstacle));
  }
  try {
    validateCollision(out.options.collision, "collision");
    validateRigidOptions(out.options.rigid);
  } catch (const std::exception& e) {
    throw SceneError(scene.name + ": " + e.what());
  }
  return out;
}

template AssembledScene<float> assembleScene(const SceneSpec&);
template AssembledScene<double> assembleScene(const SceneSpec&);

}  // namespace weft
