// What a scene will take, asked before it is assembled: its step count (sceneStepCount)
// and its particles, springs, triangles and heap (estimateSceneMemory), so that the
// command line can refuse or warn about a scene before building it.
#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>

#include "mesh_readers.hpp"
#include "scene_internal.hpp"

namespace weft {

namespace {
// Heap bytes of an assembled Simulation per particle and per spring, by integrator, for
// double and float. The spring rate is the Model's arrays (two indices, rest length,
// stiffness, damping and a class byte: 21 bytes in float, 33 in double), plus implicit
// Euler's 3x3 block per spring; the particle rate was then solved from mallinfo2() after
// assembling and stepping the 256^2 flag with each integrator (2026-11-26), with 12 bytes per
// triangle (three indices). The integrators differ in the state-sized buffers they keep
// (RK4 four, RK45 seven, implicit Euler its CG vectors).
struct Rates {
  double particle, spring;
};
Rates memoryRates(IntegratorKind kind, bool isFloat) {
  switch (kind) {
    case IntegratorKind::ExplicitEuler:
    case IntegratorKind::SymplecticEuler:
      return isFloat ? Rates{66, 21} : Rates{127, 33};
    case IntegratorKind::Midpoint:
    case IntegratorKind::VelocityVerlet:
      return isFloat ? Rates{90, 21} : Rates{175, 33};
    case IntegratorKind::Rk4:
      return isFloat ? Rates{114, 21} : Rates{223, 33};
    case IntegratorKind::Rk45:
      return isFloat ? Rates{258, 21} : Rates{511, 33};
    case IntegratorKind::ImplicitEuler:
      // With the block-Jacobi preconditioner; the others (and auto, which holds the
      // multigrid beside it) add preconditionerBytesPerParticle. Each spring's 3x3 block is kept (six values); a
      // model that is not a grid also keeps a per-spring product (three values more,
      // not in this rate, which was measured on the flag).
      return isFloat ? Rates{158, 93} : Rates{302, 170};
    case IntegratorKind::Projective:
      // The global matrix's factor dominates: ~76 entries a particle at 128^2, growing
      // slowly with the size, kept as float values and row indices by columns and by rows
      // (12 bytes an entry with 16-bit indices, up to 65536 particles; 16 beyond), and in
      // double while it is made: that is the peak.
      // Peaks of `weft run flag --integrator projective --steps 3` with 16-bit indices
      // (2026-11-27): 48.4 / 181.5 MiB at 128^2 / 256^2 in double, 45.9 / 173.8 in float
      // (62 and 228 in double with 32-bit indices). The fill per particle grows with the
      // size, so the rates put the estimate between: 51.8 / 172.8 MiB in double, 49.0 /
      // 161.2 in float (the factor is double in both precisions; the float spring rate is
      // the smaller one of the Model's arrays).
      return isFloat ? Rates{2000, 62} : Rates{1900, 110};
  }
  return {2000, 154};  // the largest
}
// Implicit Euler's preconditioners beyond block-Jacobi, per particle. Peaks of `weft run flag
// --integrator implicit --cg-preconditioner P --steps 1 --threads 1` against block-Jacobi's
// (2026-11-27, AMD EPYC; bench/results/2026-11-27-epyc-implicit-memory-estimate.txt): the
// multigrid hierarchy (its levels in double in both precisions) 6.6 / 24.8 MiB more at
// 128^2 / 256^2 in double (about 420 / 400 bytes a particle; the same in float); the
// projective preconditioner's factor (projective dynamics' solver) 26.6 / 133.9 MiB more
// (about 1700 / 2140 bytes a particle, its fill growing with the size; 25.3 / 138.8 in
// float).
double preconditionerBytesPerParticle(const SimulationOptions& options) {
  if (options.integrator != IntegratorKind::ImplicitEuler) return 0;
  switch (options.integration.preconditioner) {
    case Preconditioner::Multigrid:
      return 410;
    case Preconditioner::Auto:  // the multigrid beside block-Jacobi's inverses (6 values a particle:
      return 410 + 48;          // 48 bytes in double, 24 in float, where this is 24 high)
    case Preconditioner::Projective:
      return 1950;
    case Preconditioner::Jacobi:
    case Preconditioner::BlockJacobi:
      break;
  }
  return 0;
}
// While the model is built, the builder's arrays (in double: 7 values and a pin flag per
// particle, 33 bytes per spring, 12 per triangle) and the Model's particle arrays and state
// (8 values of the precision) are alive at once, and the Model's first spring array and
// triangles are made beside them (the builder's particle arrays are freed before the
// springs are converted, so this slightly overcounts): for a cloth of mostly springs this, not the
// Simulation, can be the run's peak (the 256^2 flag in float: 21.8 MB by this count, 20.7
// MB measured).
double builderBytes(double particles, double springs, double triangles, bool isFloat) {
  return (57.0 + 8.0 * (isFloat ? 4 : 8)) * particles + 33.0 * springs + 24.0 * triangles;
}
constexpr double kBytesPerTriangle = 12;
// With self-collision: the triangles' BVH, the pair-query buffers and the candidate lists,
// measured on `fold` at 32² after its first step (1.9 MB for 1922 triangles, rounded up),
// and the expansion's record of each triangle (64 bytes) since.
// A folded cloth lists more candidates than a flat one, so this is the floor of a run.
constexpr double kBytesPerSelfCollisionTriangle = 1064;
// What a cloth folded on itself adds to that: `twist` (32^2, 1922 triangles, 2 threads)
// peaked at 26.8 MiB at its end against 14.1 estimated from the rate above (2026-12-01, AMD
// EPYC). Its self-collision held then 59,700 candidate pairs (31 a triangle) and 11.7 MB:
// their primitive pairs 4.0 MB, the pair query's buffers 3.1 MB, the response's contacts
// and shares 1.6 and 2.3 MB, the pairs 0.5 MB. Candidates are a local count (the triangles
// within the thickness of each), so the rate is per triangle. Since the primitive pairs are
// 2 bytes a candidate (a mask) instead of 20 each, twist peaks at 23.2 MiB (4.9 kB a
// triangle past the first figure) and at 48^2 at 37.6 MiB (4.8 kB); 5.5 kB leaves a margin of
// 13-15 % (the peak varies by about 1 MiB from run to run with the threads' buffers).
constexpr double kBytesPerFoldedTriangle = 5500;
// Resident memory a rigid body's share of the world takes once a pile of them has landed
// (pairs, caches, manifolds, constraints: their buffers are reserved for 16 pairs a piece
// and become resident as the contacts fill them), measured on the `pile` (1005 bodies):
// 6.5 MB after its first step, while the bodies fall apart from each other, and 8.7 MB more
// once they have landed (3,000 touching pairs, 5,100 contacts, from about its 60th step; the
// solver's 576-byte constraints kept once, the warm start's 64-byte points beside them).
// A scene whose bodies never touch is estimated high; one that piles up is not estimated low.
constexpr double kBytesPerRigidBody = 15600;

/// Whether assimp reads the mesh file `name` (weft reads PLY, STL and OBJ itself; a name
/// without one of their extensions is counted as assimp's, the larger estimate).
bool readByAssimp(const std::string& name) { return io_detail::ownFormatByName(name) == nullptr; }
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
        e.readsMeshes = e.readsMeshes || readByAssimp(body.meshFile);
        break;
    }
  }
  e.rigidBodies = static_cast<std::int64_t>(scene.simulation.rigid.bodies.size());
  for (const MeshObstacleSpec& m : scene.meshObstacles) e.readsMeshes = e.readsMeshes || readByAssimp(m.meshFile);
  const bool isFloat = scene.precision == Precision::Float;
  const Rates r = memoryRates(scene.simulation.integrator, isFloat);
  const double particles = static_cast<double>(e.particles), springs = static_cast<double>(e.springs),
               triangles = static_cast<double>(e.triangles);
  // With obstacles or self-collision: x and v at the step's start, put back on a failure.
  const double stepBackup =
      scene.simulation.collision.any() || scene.simulation.selfCollision.enabled ? 6.0 * (isFloat ? 4 : 8) : 0.0;
  // With rigid bodies that particles touch: x and v at the step's start, for the coupling.
  const double couplingBackup =
      e.rigidBodies > 0 && scene.simulation.rigid.particleContacts && particles > 0 ? 6.0 * (isFloat ? 4 : 8) : 0.0;
  const double simulation =
      (r.particle + preconditionerBytesPerParticle(scene.simulation) + stepBackup + couplingBackup) * particles +
      r.spring * springs + kBytesPerTriangle * triangles +
      (scene.simulation.selfCollision.enabled ? kBytesPerSelfCollisionTriangle * triangles : 0.0) +
      kBytesPerRigidBody * static_cast<double>(e.rigidBodies);
  const double building = builderBytes(particles, springs, triangles, isFloat);
  e.bytes = std::max(simulation, building);
  // (The folded lists grow during the run: beside the Simulation, not the builder.)
  e.foldedBytes = std::max(
      simulation + (scene.simulation.selfCollision.enabled ? kBytesPerFoldedTriangle * triangles : 0.0), building);
  return e;
}

std::int64_t sceneStepCount(const SceneSpec& scene) {
  if (scene.steps > 0) return scene.steps;
  if (scene.duration > 0 && scene.simulation.dt > 0) {
    // The reader caps the count at 2^40; a SceneSpec filled in C++ with a larger one saturates.
    const double n = io_detail::durationStepCount(scene.duration, scene.simulation.dt);
    return n < 9.2e18 ? static_cast<std::int64_t>(n) : std::numeric_limits<std::int64_t>::max();
  }
  return 0;
}

}  // namespace weft
