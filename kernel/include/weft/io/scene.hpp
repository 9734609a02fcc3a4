// weft/io/scene.hpp — a scene described once: bodies, materials, pins, effects,
// integrator, time step, duration and output; from C++ or from a JSON file.
//
// Design note
// -----------
// A SceneSpec is plain data. assembleScene() turns it into a Model, an initial State and
// the SimulationOptions of exactly the effects the scene lists (an effect it does not list
// is not constructed, so it costs nothing in the step), resolving pins to particle
// indices and moving pins to SimulationOptions::kinematicPins. readSceneFile() fills a
// SceneSpec from JSON (field by field in docs/scenes.md): strict — unknown keys are
// rejected with the list of allowed keys, wrong types, non-finite numbers and values out
// of range name the file, the field path (e.g. bodies[0].materials.bend.stiffness) and
// the value. Every check happens before anything is simulated or written.
//
// Built-in scenes (flag, rope, flag-wind, hanging-cloth) are SceneSpecs too
// (builtinSceneSpec), so `weft run flag-wind` and `weft run tools/scenes/flag-wind.json`
// go through the same code.
//
// Part of the weft::io library (it reads meshes with assimp and JSON with nlohmann-json);
// the kernel itself (weft::weft) needs neither.
#pragma once

#include <cstdint>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "weft/model/cloth_mesh.hpp"
#include "weft/model/ropes_and_grids.hpp"
#include "weft/model/triangle_mesh.hpp"
#include "weft/scene/simulation.hpp"

namespace weft {

/// A bad scene: the message names the file (or "scene"), the field and the value.
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Precision { Float, Double };

/// A set of a body's particles, optionally moved along a path (a kinematic pin).
/// Particles are selected by body-local index and/or by an axis-aligned box (every
/// particle of the body inside [boxMin, boxMax] at the start).
struct PinSpec {
  std::vector<Index> particles;
  std::optional<std::pair<Vec3d, Vec3d>> box;  // (min, max), m
  std::optional<KinematicPath> path;           // absent: fixed
};

enum class BodyKind { Rope, ClothGrid, ClothMesh };
const char* bodyKindName(BodyKind kind);

struct BodySpec {
  BodyKind kind = BodyKind::ClothGrid;
  std::string name;
  RopeSpec rope;         // kind == Rope
  ClothGridSpec grid;    // kind == ClothGrid
  std::string meshFile;  // kind == ClothMesh: PLY, STL, OBJ (weft's readers) or a format assimp reads (3DS, glTF, ...)
  ClothMeshSpec mesh;    // kind == ClothMesh
  MeshCleanOptions clean;  // kind == ClothMesh
  std::vector<PinSpec> pins;
  Vec3d velocity{0, 0, 0};  // initial velocity of the body's free particles, m/s
  // A cloth's own thickness against itself and other cloths (m, > 0; self_collision's
  // thickness when absent): SelfCollisionOptions::particleThickness for its particles.
  std::optional<double> selfCollisionThickness;
};

/// A triangle mesh obstacle read from a mesh file when the scene is assembled: the file is
/// loaded with loadCleanMesh (welded by `clean`), scaled by `scale` and moved by
/// `translate` (like a cloth_mesh body), and becomes `obstacle.mesh`; the rest of
/// `obstacle` (name, path, restitution, friction) is used as given.
struct MeshObstacleSpec {
  MeshObstacle obstacle;     // its mesh is filled at assembly
  std::string meshFile;      // as meshFile above (a scene file's paths are resolved against its directory)
  std::string meshContents;  // not empty: the file's contents, in memory (built-in scenes); meshFile names it
  MeshCleanOptions clean;    // weld tolerance
  double scale = 1;          // > 0
  Vec3d translate{0, 0, 0};  // m
};

struct OutputSpec {
  std::string directory;       // empty: no frames
  std::string format = "obj";  // obj | ply | cache | gltf
  std::int64_t every = 1;      // a frame every this many steps (>= 1)
};

struct SceneSpec {
  std::string name = "scene";
  std::vector<BodySpec> bodies;
  SimulationOptions simulation;                 // integrator, dt, threads, strategy, gravity, effects, collision, ...
  std::vector<MeshObstacleSpec> meshObstacles;  // appended to simulation.collision.meshes at assembly
  Precision precision = Precision::Double;
  std::int64_t steps = 0;  // > 0: run this many steps
  double duration = 0;     // otherwise: ceil(duration / dt) steps (one of the two is required)
  OutputSpec output;
  /// The keys a scene file wrote, as field paths ("integration.rtol",
  /// "bodies[0].materials.bend"), whatever their values; empty for a built-in scene or a
  /// SceneSpec filled in C++. `weft run` names the ones its run does not use, so that a
  /// setting written into the file is never silently left out, even at its default value.
  std::set<std::string> givenKeys;
};

/// Steps the scene asks for (steps, or duration / dt rounded up).
std::int64_t sceneStepCount(const SceneSpec& scene);

/// What a scene will take, asked before it is assembled: its particle, spring and triangle
/// counts (cloth grids and ropes from their specs; cloth meshes are not read here and not
/// counted: `meshBodies` says how many were left out) and the heap they need at the peak,
/// in bytes, at its precision and integrator: the larger of what the assembled Simulation
/// holds (bytes per particle, spring and triangle measured for weft's own arrays: heap in
/// use after assembling and one step, which is exactly linear in the three counts) and what
/// building the model holds for a moment (the builder's double arrays beside the Model's).
/// Rigid bodies are counted as a pile that has landed (their contacts' buffers full).
/// Self-collision's candidate and contact lists grow as a cloth folds on itself or is
/// wrung, which cannot be known before the run: `bytes` counts them for a cloth as it
/// starts (smooth, few candidates) and `foldedBytes` for a cloth folded as tightly as the
/// built-in `twist` at its end (about 31 candidate pairs a triangle, 5.5 kB a triangle
/// more beside the Simulation; the larger of that and what building the model holds), an
/// upper figure for a run that folds. Without self-collision both are the same.
/// A test keeps `bytes` within 25 % of the peak resident memory of the built-in scenes
/// (after their first step; the pile after it has landed) and `foldedBytes` above the
/// peak of a run that wrings its cloth.
struct MemoryEstimate {
  std::int64_t particles = 0, springs = 0, triangles = 0;
  std::int64_t rigidBodies = 0;
  std::int64_t meshBodies = 0;  // cloth_mesh bodies, not counted
  bool readsMeshes = false;     // a cloth mesh or mesh obstacle in a format assimp reads (not PLY, STL, OBJ)
  double bytes = 0;
  double foldedBytes = 0;  // >= bytes: with self-collision, once the cloth has folded on itself
};
MemoryEstimate estimateSceneMemory(const SceneSpec& scene);

/// Reads a JSON scene file; mesh paths are relative to the file's directory.
/// Throws SceneError.
SceneSpec readSceneFile(const std::string& path);
/// Parses JSON text; `source` names it in errors, `baseDirectory` resolves mesh paths.
SceneSpec parseScene(const std::string& text, const std::string& source = "scene",
                     const std::string& baseDirectory = ".");

/// The built-in scenes: flag, rope, flag-wind, hanging-cloth, and with obstacles drape (a
/// cloth falling onto a sphere), drape-mesh (onto a torus imported from an OBJ file
/// embedded in the library: tools/scenes/meshes/torus.obj), rope-on-pegs (a rope falling
/// across three capsules) and fast-ball (a small cloth fired at 100 m/s at a wall one
/// triangle thin, dt = 1/60 s).
/// `size`: the grid side or rope particles, the boxes of stack or the bodies of pile; 0 =
/// the default. Throws SceneError for an unknown name, listing the known ones, and for a
/// size given to a scene of a fixed layout (ball-on-brick, bullet, slope).
SceneSpec builtinSceneSpec(const std::string& name, Index size = 0);
std::vector<std::string> builtinSceneNames();

template <class S>
struct AssembledScene {
  ModelAndState<S> built;
  SimulationOptions options;             // with kinematicPins resolved
  std::vector<Index> firstParticle;      // per body
  std::vector<std::string> meshReports;  // one line per mesh body and mesh obstacle: what cleaning found
};

/// Builds the model, the state and the options (mesh obstacles loaded into
/// options.collision.meshes). Throws SceneError (bad values, unreadable meshes, pins
/// selecting nothing, collision options the simulation would refuse).
template <class S>
AssembledScene<S> assembleScene(const SceneSpec& scene);

extern template AssembledScene<float> assembleScene(const SceneSpec&);
extern template AssembledScene<double> assembleScene(const SceneSpec&);

}  // namespace weft
