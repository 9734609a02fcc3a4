// assembleScene: a SceneSpec (from a file, a built-in scene or C++) made into a model, an
// initial state and the simulation's options: bodies built, pins resolved to particles
// (kinematic pins moved to SimulationOptions::kinematicPins), initial velocities set, mesh
// bodies and mesh obstacles loaded. What the reader could not check (the precision asked
// for, mesh files' contents, a SceneSpec filled in C++) is checked here, naming the scene
// and the field.
#include <cmath>
#include <exception>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "scene_internal.hpp"
#include "weft/io/mesh_import.hpp"

namespace weft {

using namespace io_detail;  // fmt, finite (json_reader.hpp); pins, requireScalarRange, bodiesText (scene_internal.hpp)

namespace {

/// The cleaning options of a mesh the scene scales by `scale`: the weld tolerance is given in
/// metres, as the scene's lengths are, and the mesh is cleaned before it is scaled, in its
/// file's units. (A scale that is not a positive number is refused where it is used.)
MeshCleanOptions inFileUnits(MeshCleanOptions clean, double scale) {
  if (!(std::isfinite(scale) && scale > 0)) return clean;
  const double tolerance = clean.weldTolerance / scale;
  if (!std::isfinite(tolerance))
    throw std::invalid_argument("weld_tolerance " + fmt(clean.weldTolerance) + " m / scale " + fmt(scale) +
                                " must be finite: the weld tolerance in the file's units overflows");
  clean.weldTolerance = tolerance;
  return clean;
}

}  // namespace

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
        mesh = loadCleanMesh(b.meshFile, inFileUnits(b.clean, b.mesh.scale), &report);  // its messages name the file
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
        double reach = 0;  // the farthest pinned particle from the path's centre
        for (const Index i : selections.back()) {
          const Vec3d p = position(i);
          reach =
              std::max(reach, std::hypot(p.x - pin.path->center.x, p.y - pin.path->center.y, p.z - pin.path->center.z));
        }
        if (!kinematicSpinWithinLimit(*pin.path, reach))
          throw SceneError(pf + ".path.angular_velocity: must be " +
                           kinematicSpinRule(reach, "the farthest particle it pins") + ", got " +
                           fmt(pin.path->angularVelocity));
        KinematicPins kinematic;
        for (const Index i : selections.back()) kinematic.particles.push_back(first + i);
        kinematic.path = *pin.path;
        out.options.kinematicPins.push_back(std::move(kinematic));
      }
    }
    if (const auto conflict = pinConflict(b.pins, selections))
      throw SceneError(field + ".pins[" + std::to_string(conflict->pin) + "]: " + conflict->what());
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
    // (At most the speed of light: within the range of float too.)
    if (!detail::speedWithinLimit(v.x, v.y, v.z))
      throw SceneError(scene.name + ": bodies[" + std::to_string(k) + "].velocity: must be " + detail::speedRule() +
                       ", got " + fmt(v));
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
      const MeshCleanOptions clean = inFileUnits(m.clean, m.scale);
      obstacle.mesh = m.meshContents.empty() ? loadCleanMesh(m.meshFile, clean, &report)
                                             : loadCleanMeshFromMemory(m.meshContents, m.meshFile, clean, &report);
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
  // Thicknesses per cloth: each body's own for its particles, the section's for the others.
  const auto bodyEnd = [&](size_t k) {
    return k + 1 < scene.bodies.size() ? out.firstParticle[k + 1] : out.built.model.particleCount();
  };
  const auto bodyField = [&](size_t k) {
    return "bodies[" + std::to_string(k) + "]" +
           (scene.bodies[k].name.empty() ? std::string() : " (" + scene.bodies[k].name + ")") +
           ".self_collision_thickness";
  };
  // (Without self-collision a body's thickness has no use: a scene file is refused for it
  // when read, a SceneSpec with the pass turned off ignores it.)
  for (size_t k = 0; k < scene.bodies.size() && out.options.selfCollision.enabled; ++k) {
    if (!scene.bodies[k].selfCollisionThickness) continue;
    const double t = *scene.bodies[k].selfCollisionThickness;
    if (!(std::isfinite(t) && t > 0))
      throw SceneError(scene.name + ": " + bodyField(k) + ": must be finite and > 0 (m), got " + fmt(t));
    std::vector<double>& perParticle = out.options.selfCollision.particleThickness;
    if (perParticle.empty())
      perParticle.assign(static_cast<size_t>(out.built.model.particleCount()), out.options.selfCollision.thickness);
    for (Index i = out.firstParticle[k]; i < bodyEnd(k); ++i) perParticle[static_cast<size_t>(i)] = t;
  }
  const auto thicknessField = [&](Index particle) {
    for (size_t k = 0; k < scene.bodies.size(); ++k)
      if (particle >= out.firstParticle[k] && particle < bodyEnd(k))
        return scene.bodies[k].selfCollisionThickness ? bodyField(k) : std::string("self_collision.thickness");
    return std::string("self_collision.thickness");
  };
  try {
    validateCollision(out.options.collision, "collision");
    validateCollisionReach(out.options.collision, std::numeric_limits<S>::epsilon(),
                           sizeof(S) == sizeof(float) ? "float" : "double", "collision");
    validateRigidOptions(out.options.rigid);
    if (out.options.selfCollision.enabled)
      validateSelfCollision(out.options.selfCollision, out.built.model, out.built.state.x, "self_collision",
                            thicknessField);
  } catch (const std::exception& e) {
    throw SceneError(scene.name + ": " + e.what());
  }
  return out;
}

template AssembledScene<float> assembleScene(const SceneSpec&);
template AssembledScene<double> assembleScene(const SceneSpec&);

}  // namespace weft
