// The `bodies` section of a scene file (docs/scenes.md): ropes, cloth grids and cloth
// meshes, each with its geometry, mass, materials, initial velocity and pins. Geometry
// that would give particles no finite position or no mass is refused here, naming the
// field; mesh files are checked to be readable here and read when the scene is assembled.
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <system_error>

#include "model/precision_limits.hpp"
#include "scene_internal.hpp"

namespace weft::io_detail {

namespace {

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

/// The body's `materials`: structural and bend springs, and shear springs where the body
/// has them (`shear`, grids).
/// `shear` is null for bodies without shear springs; a material given for a family the
/// body leaves out (shear_springs or bend_springs false) would not be used and is refused.
void readMaterials(const Reader& r, const Json& body, const std::string& f, SpringMaterial& structural,
                   SpringMaterial* shear, bool shearSprings, SpringMaterial& bend, bool bendSprings) {
  if (!body.contains("materials")) return;
  const std::string fm = Reader::join(f, "materials");
  const Json& j = body["materials"];
  if (shear)
    r.object(j, fm, {"structural", "shear", "bend"});
  else
    r.object(j, fm, {"structural", "bend"});
  const auto familyOff = [&](const char* family, bool on, const char* flag) {
    if (j.contains(family) && !on)
      r.fail(Reader::join(fm, family), std::string("is for ") + family + " springs, and " + flag +
                                           " is false: drop the material or turn the springs on");
  };
  if (shear) familyOff("shear", shearSprings, "shear_springs");
  familyOff("bend", bendSprings, "bend_springs");
  structural = r.material(j, fm, "structural", structural);
  if (shear) *shear = r.material(j, fm, "shear", *shear);
  bend = r.material(j, fm, "bend", bend);
}

}  // namespace

std::string readMeshFile(const Reader& r, const Json& j, const std::string& f, const std::string& baseDirectory) {
  const std::string mesh = r.pathString(j, f, "mesh");
  const std::filesystem::path p(mesh);
  const std::string path =
      p.is_absolute() ? mesh : (std::filesystem::path(baseDirectory) / p).lexically_normal().string();
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
  if (problem.empty()) return path;
  r.fail(Reader::join(f, "mesh"), "cannot read the mesh file " + shortDump(j["mesh"]) +
                                      (mesh != path ? " (" + shortDump(Json(path)) + ")" : std::string()) + ": " +
                                      problem);
}

/// The kernel's shortest spacing between particles (in double; a float scene's tighter limit
/// is the kernel's, at assembly): `spacing` as laid out, `key` the field, `what` how the
/// spacing follows from it ("" when it is the field's value).
void requireSpacing(const Reader& r, const std::string& f, const char* key, double spacing, const std::string& what) {
  using Limits = detail::PrecisionLimits<double>;  // (the kernel's rule; float's is checked at assembly)
  if (!Limits::spacing(spacing))
    r.fail(Reader::join(f, key), (what.empty() ? std::string() : what + " = " + fmt(spacing) + " m: ") + "must be " +
                                     Limits::spacingRule() + (what.empty() ? ", got " + fmt(spacing) : std::string()));
}

BodySpec readBody(const Reader& r, const Json& j, const std::string& f, const std::string& baseDirectory) {
  if (!j.is_object()) r.fail(f, std::string("must be an object, got ") + typeName(j) + " " + shortDump(j));
  BodySpec b;
  if (!j.contains("type")) r.fail(Reader::join(f, "type"), "is required: rope, cloth_grid or cloth_mesh");
  const std::string type = r.choice(j, f, "type", "", {"rope", "cloth_grid", "cloth_mesh"});
  b.name = r.string(j, f, "name", type);
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
    requireSpacing(r, f, "length", s.length / static_cast<double>(s.particleCount - 1), "length / (particles - 1)");
    s.totalMass = readMass(r, j, f, s.totalMass, s.particleCount);
    s.bendSprings = r.boolean(j, f, "bend_springs", s.bendSprings);
    readMaterials(r, j, f, s.structural, nullptr, false, s.bend, s.bendSprings);
    geometry = ropeGeometry(s);
    if (!finite(geometry->position(s.particleCount - 1)))
      r.fail(f, "the rope's far end " + fmt(geometry->position(s.particleCount - 1)) +
                    " is not finite: origin, direction or length is too large");
  } else if (type == "cloth_grid") {
    b.kind = BodyKind::ClothGrid;
    r.object(j, f,
             {"type", "name", "width", "height", "origin", "row_axis", "column_axis", "spacing", "total_mass",
              "particle_mass", "materials", "shear_springs", "bend_springs", "pins", "velocity",
              "self_collision_thickness"});
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
    requireSpacing(r, f, "spacing", s.spacing, "");
    s.totalMass = readMass(r, j, f, s.totalMass, s.width * s.height);
    s.shearSprings = r.boolean(j, f, "shear_springs", s.shearSprings);
    s.bendSprings = r.boolean(j, f, "bend_springs", s.bendSprings);
    readMaterials(r, j, f, s.structural, &s.shear, s.shearSprings, s.bend, s.bendSprings);
    geometry = gridGeometry(s);
    for (const Index corner : {s.width - 1, s.width * (s.height - 1), s.width * s.height - 1})
      if (!finite(geometry->position(corner)))
        r.fail(f, "the grid's corner " + fmt(geometry->position(corner)) +
                      " is not finite: origin, spacing or size is too large");
  } else {
    b.kind = BodyKind::ClothMesh;
    r.object(j, f,
             {"type", "name", "mesh", "weld_tolerance", "scale", "translate", "total_mass", "areal_density",
              "materials", "bend_springs", "pins", "velocity", "self_collision_thickness"});
    if (!j.contains("mesh")) r.fail(Reader::join(f, "mesh"), "is required: the path of the mesh file");
    b.meshFile = readMeshFile(r, j, f, baseDirectory);
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
    readMaterials(r, j, f, s.structural, nullptr, false, s.bend, s.bendSprings);
  }
  b.velocity = r.vector(j, f, "velocity", b.velocity);
  if (b.kind != BodyKind::Rope && j.contains("self_collision_thickness"))
    b.selfCollisionThickness = r.number(j, f, "self_collision_thickness", 0.0, 0, false, " m");
  b.pins = readPins(r, j, f, geometry ? &*geometry : nullptr);
  return b;
}

}  // namespace weft::io_detail
