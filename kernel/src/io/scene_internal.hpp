// scene_internal.hpp — what the files of weft::io's scenes share (private to weft::io, not
// installed; the API is weft/io/scene.hpp).
//
// The scene file's schema is read section by section: the top level, effects,
// integration, stability and output in scene_reader.cpp, bodies in scene_bodies.cpp, their
// pins in scene_pins.cpp, collision in scene_collision.cpp, rigid_bodies in
// scene_rigid.cpp. Pins are resolved to particles by the same code when a file is read and
// when a SceneSpec is assembled (scene_assembly.cpp), so that both select the same
// particles and refuse the same pins with the same words.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "json_reader.hpp"
#include "weft/io/scene.hpp"

namespace weft::io_detail {

/// ceil(duration / dt) (a hair less, so that 1 / 0.1 is 10 steps), at least 1, as a double:
/// no overflow whatever the values.
inline double durationStepCount(double duration, double dt) {
  return std::max(1.0, std::ceil(duration / dt * (1 - 1e-12)));
}

// ---------------------------------------------------------------------------------------
// Sections of the file (each `field` is the section's path in the file, for messages)
// ---------------------------------------------------------------------------------------

/// bodies[k] (scene_bodies.cpp); mesh paths are resolved against `baseDirectory`.
BodySpec readBody(const Reader& r, const Json& j, const std::string& field, const std::string& baseDirectory);

/// The `collision` section (scene_collision.cpp): options, analytic obstacles into `c`,
/// mesh obstacles (read at assembly) into `meshes`.
/// The `self_collision` section: its presence turns self-collision on.
void readSelfCollision(const Reader& r, const Json& j, const std::string& field, SelfCollisionOptions& o);
void readCollision(const Reader& r, const Json& j, const std::string& field, const std::string& baseDirectory,
                   CollisionOptions& c, std::vector<MeshObstacleSpec>& meshes);

/// The `rigid_bodies` section (scene_rigid.cpp).
RigidOptions readRigidBodies(const Reader& r, const Json& j, const std::string& field);

/// A kinematic path: {velocity, angular_velocity, axis, center, start, end} (scene_pins.cpp).
KinematicPath readPath(const Reader& r, const Json& j, const std::string& field);

/// j["mesh"] (at `field`.mesh, a cloth_mesh body's or a mesh obstacle's), resolved against
/// `baseDirectory` unless absolute. The file must exist and be a readable regular file:
/// checked while reading so that the message names the scene file and the field; its
/// contents are read when the scene is assembled. (scene_bodies.cpp)
std::string readMeshFile(const Reader& r, const Json& j, const std::string& field, const std::string& baseDirectory);

/// A surface that touches (an obstacle, a mesh obstacle, a rigid body): restitution in
/// [0, 1], friction coefficients mu_k <= mu_s; kinetic_friction defaults to the smaller of
/// its default and static_friction.
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

// ---------------------------------------------------------------------------------------
// Pins (scene_pins.cpp): read with the body, resolved to particles again at assembly
// ---------------------------------------------------------------------------------------

/// Body-local particle positions at the start, for checking pins while reading: the exact
/// expressions of addRope / addClothGrid, so a box selects here what it selects when the
/// scene is assembled.
struct BodyGeometry {
  Index count = 0;
  std::function<Vec3d(Index)> position;
};
/// Nothing when the direction (axes) cannot be normalised.
std::optional<BodyGeometry> ropeGeometry(const RopeSpec& s);
std::optional<BodyGeometry> gridGeometry(const ClothGridSpec& s);

/// Reads `pins` of the body `body` at `field`, one PinSpec per element (so pins[k] of the
/// file is pins[k] of the spec, and of assembly's messages). With the body's geometry
/// (ropes and grids), indices are checked here too, and so are boxes and pins that
/// contradict each other (PinConflict; for bodies up to a million particles); the rest is
/// checked when assembled.
std::vector<PinSpec> readPins(const Reader& r, const Json& body, const std::string& field,
                              const BodyGeometry* geometry);

/// The body-local particles a pin selects: its indices and every particle inside its box
/// (`position` gives body-local positions), sorted, each once.
std::vector<Index> pinSelection(const PinSpec& pin, Index count, const std::function<Vec3d(Index)>& position);

/// Two pins of a body that contradict or repeat each other over one particle: a particle
/// listed by index twice (most likely a typo for another index), moved by two kinematic
/// pins, or named by index in a fixed pin and moved by another (the simulation would move
/// it and ignore the index). A path over a particle of a fixed pin's box is no conflict:
/// the path takes precedence (the top edge fixed, a corner of it moved).
struct PinConflict {
  enum class Kind { ListedTwice, MovedTwice, FixedAndMoved };
  Kind kind;
  size_t pin;      // the later pin
  Index particle;  // body-local
  size_t earlier;  // the earlier pin
  std::string what() const;
};
/// `selections[q]` is pins[q]'s (see pinSelection); only the kinematic pins' are read. The
/// first conflict in pin order.
std::optional<PinConflict> pinConflict(const std::vector<PinSpec>& pins,
                                       const std::vector<std::vector<Index>>& selections);

/// "the body has 16 particles, 0 .. 15"
std::string particleRange(Index count);

// ---------------------------------------------------------------------------------------
// Rules of the scene as a whole (scene_reader.cpp), checked when reading and assembling
// ---------------------------------------------------------------------------------------

/// Scene-wide values the step converts to S must be within S's range (1e39 is a double
/// but no float): checked while reading for the file's precision, and when assembling for
/// the one asked for, rather than left to become infinities in the step or an exception of
/// the simulation's. `fail(field, what)` does not return. (float and double)
template <class S>
void requireScalarRange(const SimulationOptions& o,
                        const std::function<void(const std::string&, const std::string&)>& fail);

/// "1 body, the first a rope", "3 bodies, ..."
std::string bodiesText(const SceneSpec& scene);

}  // namespace weft::io_detail
