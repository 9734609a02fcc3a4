// tests/fuzz/fuzz_scene.cpp — a libFuzzer target for the scene reader (run by tools/fuzz.sh).
//
// Every input is read as a scene file (weft::parseScene). A SceneError, or a
// std::invalid_argument, is the reader doing its job; anything else escaping, a crash, a
// sanitizer report (the build has AddressSanitizer and UndefinedBehaviorSanitizer) or a
// timeout is a finding.
//
// A scene the reader accepts must then be usable: when it is small (no mesh bodies, which
// read files, and at most kMaxParticles particles, so that one input takes milliseconds)
// it is assembled in float and in double, a Simulation is built from it and stepped once,
// with the work of that step capped. Assembly may still refuse it with a SceneError (a
// value out of float's range, say), but the Simulation must accept whatever the reader
// and assembly let through: its std::invalid_argument would be a check the reader misses,
// with a message that names no file or field, so it escapes here and counts as a finding.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

#include "weft/io/scene.hpp"
#include "weft/weft.hpp"

#ifndef WEFT_SOURCE_DIR
#error "WEFT_SOURCE_DIR must name the repository (mesh paths resolve against tools/scenes/)"
#endif

namespace {

constexpr std::int64_t kMaxParticles = 4096;

bool smallAndFileFree(const weft::SceneSpec& scene) {
  std::int64_t particles = 0;
  for (const weft::BodySpec& b : scene.bodies) {
    if (b.kind == weft::BodyKind::ClothMesh) return false;
    particles +=
        b.kind == weft::BodyKind::Rope ? b.rope.particleCount : static_cast<std::int64_t>(b.grid.width) * b.grid.height;
  }
  std::size_t points = 0;  // rigid bodies: a few, of small hulls, so that one input takes milliseconds
  for (const weft::RigidBodyDesc& b : scene.simulation.rigid.bodies)
    for (const weft::RigidShapeDesc& shape : b.shapes) points += shape.points.size() + 1;
  return particles <= kMaxParticles && points <= 4096 && scene.simulation.rigid.substeps <= 16 &&
         scene.simulation.rigid.velocityIterations <= 64 && scene.simulation.rigid.positionIterations <= 64;
}

template <class S>
void assembleAndStep(const weft::SceneSpec& spec) {
  std::optional<weft::AssembledScene<S>> scene;
  try {
    scene.emplace(weft::assembleScene<S>(spec));
  } catch (const weft::SceneError&) {
    return;
  }
  weft::SimulationOptions options = scene->options;
  options.threads = 1;
  // The scene may ask for up to 2^30 substeps or CG iterations per step, or 10^4 projective
  // dynamics iterations (each a solve: 50 s for one step of a 64 x 64 cloth under the
  // sanitizers, a timeout CI's fuzzing found): legitimate, but not in milliseconds.
  options.integration.maxSubsteps = std::min<weft::Index>(options.integration.maxSubsteps, 64);
  options.integration.maxLinearIterations = std::min<weft::Index>(options.integration.maxLinearIterations, 64);
  options.integration.projectiveIterations = std::min(options.integration.projectiveIterations, 2);
  // Likewise the halvings of the rollback and the self-collision passes.
  options.collision.maxHalvings = std::min(options.collision.maxHalvings, 2);
  options.selfCollision.iterations = std::min(options.selfCollision.iterations, 4);
  weft::Simulation<S> sim(std::move(scene->built), options);  // must not throw: see above
  // A body that starts inside an obstacle, beyond its contact layer, is pushed out in the
  // first step: with self-collision on, the whole cloth is then tested against itself over
  // that motion (0.75 s for one step of a 32 x 32 cloth starting 0.45 m inside a plane, in
  // Release with the caps above; found by this target). Legitimate, not in milliseconds:
  // such a scene is built, not stepped.
  if (sim.contactSolver() && sim.contactReport().maxPenetration > options.collision.thickness) return;
  sim.step();  // never throws; may fail (a status)
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  weft::SceneSpec spec;
  try {
    spec = weft::parseScene(text, "fuzz.json", WEFT_SOURCE_DIR "/tools/scenes");
  } catch (const weft::SceneError&) {
    return 0;
  } catch (const std::invalid_argument&) {
    return 0;
  }
  // What the reader promises about an accepted scene.
  if ((spec.bodies.empty() && spec.simulation.rigid.bodies.empty()) || weft::sceneStepCount(spec) < 1 ||
      !(spec.simulation.dt > 0))
    __builtin_trap();
  if (smallAndFileFree(spec)) {
    assembleAndStep<float>(spec);
    assembleAndStep<double>(spec);
  }
  return 0;
}
