// weft/scene/builtin_scenes.hpp — the scenes every test, benchmark and the `weft`
// command use, defined once so that a benchmark measures exactly what a test checks.
//
// flag  A size x size cloth grid, 1 m x 1 m, 0.5 kg, lying horizontal (x-z plane) at
//       y = 0 and pinned at the two corners of row 0; structural, shear and bend
//       springs; it falls and swings under gravity.
// rope  A chain of n particles, 1 m, 0.1 kg, horizontal along x and pinned at particle 0,
//       with bend springs; it swings down like a pendulum.
//
// Spring stiffness is per spring (N/m), so a finer grid of the same cloth is stiffer per
// unit mass: the stable time step scales like 1/size. defaultTimeStep() follows that.
#pragma once

#include <string>
#include <vector>

#include "weft/model/ropes_and_grids.hpp"
#include "weft/scene/simulation.hpp"

namespace weft {

enum class BuiltinScene { Flag, Rope };
const char* builtinSceneName(BuiltinScene scene);
/// Parses "flag" or "rope"; throws std::invalid_argument naming the value otherwise.
BuiltinScene parseBuiltinScene(const std::string& name);

ClothGridSpec flagSpec(Index size);
RopeSpec ropeSpec(Index particleCount);

/// The flag scene: model, initial state. size >= 2.
template <class S>
ModelAndState<S> makeFlag(Index size = 64);
/// The rope scene. particleCount >= 2.
template <class S>
ModelAndState<S> makeRope(Index particleCount = 64);
template <class S>
ModelAndState<S> makeBuiltinScene(BuiltinScene scene, Index size);

/// Default size of each scene (grid side for flag, particles for rope).
Index defaultSceneSize(BuiltinScene scene);
/// A time step (s) at which every integrator but explicit Euler is stable for the scene
/// at this size (RK4 with a wide margin).
double defaultTimeStep(BuiltinScene scene, Index size);

}  // namespace weft
