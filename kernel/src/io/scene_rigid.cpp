// The `rigid_bodies` section of a scene file (docs/scenes.md): solver settings and bodies
// made of convex pieces. Ranges are the kernel's (validateRigidOptions), reported with the
// file and the field path (Reader::kernelRules); the reader adds its own caps on counts.
#include <cmath>
#include <stdexcept>
#include <string>

#include "scene_internal.hpp"
#include "weft/rigid/rigid_world.hpp"

namespace weft::io_detail {

namespace {

Eigen::Vector3d eigen(const Vec3d& v) { return {v.x, v.y, v.z}; }

/// An orientation: {"axis": [x, y, z], "degrees": a} (a rotation by a about axis), or
/// {"quaternion": [w, x, y, z]}. A quaternion is used exactly as written, not renormalised:
/// the bits written are the bits stepped, so a file can hold a generator's orientations
/// (tools/scenes/pile.json), which no axis and angle in decimal reproduce exactly.
Eigen::Quaterniond readRotation(const Reader& r, const Json& parent, const std::string& field, const char* key) {
  if (!parent.contains(key)) return Eigen::Quaterniond::Identity();
  const std::string f = Reader::join(field, key);
  const Json& j = parent[key];
  r.object(j, f, {"axis", "degrees", "quaternion"});
  if (j.contains("quaternion")) {
    if (j.contains("axis") || j.contains("degrees"))
      r.fail(f, "give either quaternion or axis and degrees, not both; got " + shortDump(j));
    const std::string fq = Reader::join(f, "quaternion");
    const Json& list = j["quaternion"];
    if (!list.is_array() || list.size() != 4)
      r.fail(fq,
             std::string("must be an array of 4 numbers [w, x, y, z], got ") + typeName(list) + " " + shortDump(list));
    double c[4];
    for (std::size_t k = 0; k < 4; ++k) c[k] = r.number(list[k], fq + "[" + std::to_string(k) + "]");
    // A loose tolerance (17 significant digits carry a unit quaternion to ~1e-16) that
    // still catches a quaternion that is not a rotation, which the kernel would
    // renormalise silently.
    const double norm = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2] + c[3] * c[3]);
    if (!(std::abs(norm - 1) <= 1e-6))
      r.fail(fq, "must be a unit quaternion (norm 1 within 1e-6), got " + shortDump(list) + " of norm " + fmt(norm));
    return Eigen::Quaterniond(c[0], c[1], c[2], c[3]);
  }
  if (!j.contains("axis"))
    r.fail(Reader::join(f, "axis"), "is required: the rotation axis [x, y, z] (or give a quaternion [w, x, y, z])");
  const Vec3d axis = r.direction(j, f, "axis", {0, 1, 0});
  const double degrees = r.anyNumber(j, f, "degrees", 0);
  const Eigen::Vector3d a = eigen(axis).normalized();
  return Eigen::Quaterniond(Eigen::AngleAxisd(degrees * 3.14159265358979323846 / 180, a));
}

RigidShapeDesc readShape(const Reader& r, const Json& e, const std::string& f) {
  if (!e.is_object()) r.fail(f, std::string("must be an object, got ") + typeName(e) + " " + shortDump(e));
  if (!e.contains("type")) r.fail(Reader::join(f, "type"), "is required: box, sphere or hull");
  const std::string type = r.choice(e, f, "type", "", {"box", "sphere", "hull"});
  RigidShapeDesc s;
  if (type == "box") {
    r.object(e, f, {"type", "half_extents", "offset", "rotation"});
    if (!e.contains("half_extents")) r.fail(Reader::join(f, "half_extents"), "is required for a box");
    s.kind = RigidShapeDesc::Kind::Box;
    s.halfExtents = eigen(r.vector(e, f, "half_extents", {}));
  } else if (type == "sphere") {
    r.object(e, f, {"type", "radius", "offset", "rotation"});
    if (!e.contains("radius")) r.fail(Reader::join(f, "radius"), "is required for a sphere");
    s.kind = RigidShapeDesc::Kind::Sphere;
    s.radius = r.anyNumber(e, f, "radius", 0);
  } else {
    r.object(e, f, {"type", "points", "offset", "rotation"});
    const std::string fp = Reader::join(f, "points");
    if (!e.contains("points")) r.fail(fp, "is required for a hull: an array of at least 4 points [x, y, z]");
    const Json& list = e["points"];
    if (!list.is_array() || list.size() < 4)
      r.fail(fp, std::string("must be an array of at least 4 points [x, y, z], got ") + typeName(list) + " " +
                     shortDump(list));
    if (list.size() > 100000) r.fail(fp, "has more than 100000 points (" + std::to_string(list.size()) + ")");
    s.kind = RigidShapeDesc::Kind::Hull;
    for (std::size_t k = 0; k < list.size(); ++k) {
      const Json& p = list[k];
      const std::string fk = fp + "[" + std::to_string(k) + "]";
      if (!p.is_array() || p.size() != 3)
        r.fail(fk, std::string("must be an array of 3 numbers [x, y, z], got ") + typeName(p) + " " + shortDump(p));
      s.points.emplace_back(r.number(p[0], fk + "[0]"), r.number(p[1], fk + "[1]"), r.number(p[2], fk + "[2]"));
    }
  }
  s.offset = eigen(r.vector(e, f, "offset", {0, 0, 0}));
  s.rotation = readRotation(r, e, f, "rotation");
  return s;
}

}  // namespace

RigidOptions readRigidBodies(const Reader& r, const Json& j, const std::string& f) {
  r.object(j, f,
           {"bodies",
            "narrow_phase",
            "ofg_faces",
            "substeps",
            "velocity_iterations",
            "position_iterations",
            "speculative_distance",
            "continuous",
            "linear_slop",
            "penetration_rate",
            "max_push_velocity",
            "restitution_threshold",
            "static_speed",
            "max_pairs",
            "particle_contacts",
            "particle_supports",
            "particle_thickness",
            "time_of_impact",
            "rollback_penetration",
            "max_halvings",
            "redo_deep_steps"});
  RigidOptions o;
  const std::string method = r.choice(j, f, "narrow_phase", "witness", {"exact", "ofg", "witness"});
  o.narrowPhase.method = method == "exact" ? NarrowPhaseMethod::Exact
                         : method == "ofg" ? NarrowPhaseMethod::Ofg
                                           : NarrowPhaseMethod::Witness;
  o.narrowPhase.ofgFaces = static_cast<int>(r.integer(j, f, "ofg_faces", o.narrowPhase.ofgFaces, 1, kMaxOfgFaces));
  o.substeps = r.anyInt(j, f, "substeps", o.substeps);
  o.velocityIterations = static_cast<int>(r.integer(j, f, "velocity_iterations", o.velocityIterations, 1, 1000));
  o.positionIterations = static_cast<int>(r.integer(j, f, "position_iterations", o.positionIterations, 0, 1000));
  o.speculativeDistance = r.anyNumber(j, f, "speculative_distance", o.speculativeDistance);
  o.continuous = r.boolean(j, f, "continuous", o.continuous);
  o.linearSlop = r.anyNumber(j, f, "linear_slop", o.linearSlop);
  o.penetrationRate = r.anyNumber(j, f, "penetration_rate", o.penetrationRate);
  o.maxPushVelocity = r.anyNumber(j, f, "max_push_velocity", o.maxPushVelocity);
  o.restitutionThreshold = r.anyNumber(j, f, "restitution_threshold", o.restitutionThreshold);
  o.staticSpeed = r.anyNumber(j, f, "static_speed", o.staticSpeed);
  o.maxPairs = static_cast<Index>(r.integer(j, f, "max_pairs", 0, 0, Index(1) << 28));
  o.particleContacts = r.boolean(j, f, "particle_contacts", o.particleContacts);
  o.particleSupports = r.boolean(j, f, "particle_supports", o.particleSupports);
  if (j.contains("particle_supports") && o.particleSupports && !o.particleContacts)
    r.fail(Reader::join(f, "particle_supports"),
           "needs particle_contacts (supports are particle contacts that carry bodies), and particle_contacts is "
           "false: drop particle_supports or turn particle_contacts on");
  o.timeOfImpact = r.choice(j, f, "time_of_impact", "speculative", {"speculative", "rollback"}) == "rollback"
                       ? RigidTimeOfImpact::Rollback
                       : RigidTimeOfImpact::Speculative;
  o.rollbackPenetration = r.anyNumber(j, f, "rollback_penetration", o.rollbackPenetration);
  o.maxHalvings = r.anyInt(j, f, "max_halvings", o.maxHalvings);
  o.redoDeepSteps = r.boolean(j, f, "redo_deep_steps", o.redoDeepSteps);
  o.particleThickness = r.anyNumber(j, f, "particle_thickness", o.particleThickness);
  const std::string fb = Reader::join(f, "bodies");
  if (!j.contains("bodies")) r.fail(fb, "is required: a non-empty array of rigid bodies");
  const Json& list = j["bodies"];
  if (!list.is_array() || list.empty())
    r.fail(fb, std::string("must be a non-empty array, got ") + typeName(list) + " " + shortDump(list));
  if (list.size() > 1000000) r.fail(fb, "has more than 10^6 bodies (" + std::to_string(list.size()) + ")");
  for (std::size_t k = 0; k < list.size(); ++k) {
    const std::string fk = fb + "[" + std::to_string(k) + "]";
    const Json& e = list[k];
    r.object(e, fk,
             {"name", "motion", "shapes", "density", "mass", "position", "orientation", "velocity", "angular_velocity",
              "static_friction", "kinetic_friction", "restitution", "path"});
    RigidBodyDesc b;
    b.name = r.string(e, fk, "name", "body" + std::to_string(k));
    const std::string motion = r.choice(e, fk, "motion", "dynamic", {"static", "kinematic", "dynamic"});
    b.motion = motion == "static"      ? BodyMotion::Static
               : motion == "kinematic" ? BodyMotion::Kinematic
                                       : BodyMotion::Dynamic;
    const std::string fs = Reader::join(fk, "shapes");
    if (!e.contains("shapes")) r.fail(fs, "is required: a non-empty array of convex pieces");
    const Json& shapes = e["shapes"];
    if (!shapes.is_array() || shapes.empty())
      r.fail(fs, std::string("must be a non-empty array, got ") + typeName(shapes) + " " + shortDump(shapes));
    for (std::size_t s = 0; s < shapes.size(); ++s)
      b.shapes.push_back(readShape(r, shapes[s], fs + "[" + std::to_string(s) + "]"));
    b.density = r.anyNumber(e, fk, "density", b.density);
    b.mass = r.anyNumber(e, fk, "mass", 0);
    b.position = eigen(r.vector(e, fk, "position", {0, 0, 0}));
    b.orientation = readRotation(r, e, fk, "orientation");
    b.velocity = eigen(r.vector(e, fk, "velocity", {0, 0, 0}));
    b.angularVelocity = eigen(r.vector(e, fk, "angular_velocity", {0, 0, 0}));
    readSurface(r, e, fk, b);
    // (The kernel refuses a velocity or mass on a body that is not dynamic; its density is
    // refused here, where a given one can be told from the default.)
    if (b.motion != BodyMotion::Dynamic && e.contains("density"))
      r.fail(Reader::join(fk, "density"),
             "is for dynamic bodies only (motion is " + motion +
                 (b.motion == BodyMotion::Static ? ": a static body does not move)"
                                                 : ": a kinematic body moves by its path)"));
    if (e.contains("path")) {
      if (b.motion != BodyMotion::Kinematic)
        r.fail(Reader::join(fk, "path"), "is for kinematic bodies only (motion is " + motion + ")");
      b.path = readPath(r, e["path"], Reader::join(fk, "path"));
    }
    o.bodies.push_back(std::move(b));
  }
  // Ranges are the kernel's own rules (and hull building's), named by their fields here.
  r.kernelRules(j, f, "rigid.",
                [&] {
                  validateRigidOptions(o);
                  (void)buildRigidModel(o.bodies);
                },
                {{"narrowPhase.ofgFaces", "ofg_faces"}});
  return o;
}

}  // namespace weft::io_detail
