// The `collision` and `self_collision` sections of a scene file (docs/scenes.md): the contact options and the
// obstacles, analytic (plane, sphere, capsule, box) into CollisionOptions, mesh obstacles
// into MeshObstacleSpecs whose files are read when the scene is assembled. Ranges of the
// options and shapes are the kernel's (validateCollision), reported with the file and the
// field path (Reader::kernelRules); surfaces are read by readSurface, also for mesh
// obstacles, which the kernel can check only once their files are loaded.
#include <algorithm>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "scene_internal.hpp"

namespace weft::io_detail {

void readSelfCollision(const Reader& r, const Json& j, const std::string& f, SelfCollisionOptions& o) {
  r.object(j, f, {"thickness", "friction", "iterations", "cull_flat_regions", "max_candidates_per_triangle"});
  o.enabled = true;
  o.cullFlatRegions = r.boolean(j, f, "cull_flat_regions", o.cullFlatRegions);
  o.thickness = r.anyNumber(j, f, "thickness", o.thickness);
  o.friction = r.anyNumber(j, f, "friction", o.friction);
  o.iterations = r.anyInt(j, f, "iterations", o.iterations);
  o.maxCandidatesPerTriangle = r.anyInt(j, f, "max_candidates_per_triangle", o.maxCandidatesPerTriangle);
  r.kernelRules(j, f, f + ".", [&] { validateSelfCollision(o, f.c_str()); });
}

void readCollision(const Reader& r, const Json& j, const std::string& f, const std::string& baseDirectory,
                   CollisionOptions& c, std::vector<MeshObstacleSpec>& meshes) {
  r.object(j, f,
           {"obstacles", "thickness", "continuous", "edges", "corners", "feature_angle", "epsilon", "resting_speed",
            "max_penetration", "max_halvings"});
  c.thickness = r.anyNumber(j, f, "thickness", c.thickness);
  c.continuous = r.boolean(j, f, "continuous", c.continuous);
  c.edges = r.boolean(j, f, "edges", c.edges);
  c.corners = r.boolean(j, f, "corners", c.corners);
  c.featureAngle = r.anyNumber(j, f, "feature_angle", c.featureAngle);
  c.epsilon = r.anyNumber(j, f, "epsilon", std::min(c.epsilon, 0.5 * c.thickness));
  c.restingSpeed = r.anyNumber(j, f, "resting_speed", c.restingSpeed);
  c.maxPenetration = r.anyNumber(j, f, "max_penetration", c.maxPenetration);
  c.maxHalvings = r.anyInt(j, f, "max_halvings", c.maxHalvings);
  r.kernelRules(j, f, f + ".", [&] { validateCollision(c, f.c_str()); });  // no obstacles yet
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
      m.meshFile = readMeshFile(r, e, fk, baseDirectory);
      m.obstacle.name =
          r.string(e, fk, "name", std::filesystem::path(e["mesh"].get<std::string>()).filename().string());
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
      o = Obstacle::sphere(r.vector(e, fk, "center", {}), r.anyNumber(e, fk, "radius", 0));
    } else if (type == "capsule") {
      r.object(e, fk, {"type", "a", "b", "radius", "restitution", "static_friction", "kinetic_friction"});
      require({"a", "b", "radius"});
      o = Obstacle::capsule(r.vector(e, fk, "a", {}), r.vector(e, fk, "b", {}), r.anyNumber(e, fk, "radius", 0));
    } else {
      r.object(e, fk,
               {"type", "center", "half_extents", "radius", "restitution", "static_friction", "kinetic_friction"});
      require({"center", "half_extents"});
      o = Obstacle::box(r.vector(e, fk, "center", {}), r.vector(e, fk, "half_extents", {}));
      o.radius = r.anyNumber(e, fk, "radius", 0);
    }
    readSurface(r, e, fk, o);
    // The shape's ranges are the kernel's, checked for this obstacle alone so that the
    // message names it by its place in the file (mesh obstacles are numbered apart).
    CollisionOptions alone;
    alone.obstacles = {o};
    r.kernelRules(e, fk, f + ".obstacles[0].", [&] { validateCollision(alone, f.c_str()); });
    c.obstacles.push_back(o);
  }
}

}  // namespace weft::io_detail
