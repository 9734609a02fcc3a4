// weft/scene/rigid_scenes.hpp — the rigid-body scenes, defined once for the tests, the
// benchmarks and the `weft` command (`weft run stack`).
//
// ball-on-brick  The lecture notes' case: a floor (static box, top at y = 0), a brick
//                (0.4 x 0.2 x 0.2 m, 2000 kg/m^3) lying on it and a ball (radius 0.1 m)
//                resting on the brick, all touching at the start; nothing may move.
// stack          `boxes` cubes of 0.5 m (500 kg/m^3) stacked exactly on a floor.
// pile           `bodies` convex bodies of four kinds (boxes, spheres, icosahedra and
//                tetrahedra, 0.1 to 0.2 m, chosen and jittered by a fixed-seed generator
//                that is the same on every machine) dropped from a grid into a bin
//                (floor and four walls, 4 m x 4 m, 1 m high).
// bullet         A 4 cm cube fired at `speed` m/s along +x at a plate 1 cm thin at x = 1 m,
//                dt = 1/60 s (3.3 m a step at 200 m/s): the tunnelling case.
// slope          A box (0.2 m cube) at rest on a static plane inclined by `degrees`, both
//                with friction coefficient `mu` (static and kinetic): it stays for
//                mu >= tan(angle) and slides at g (sin - mu cos) otherwise.
// hammock        (with a cloth) a 1 kg ball of radius 0.12 m dropped from 0.5 m above the
//                middle of a 1 m cloth pinned at its four corners (hammockCloth): the
//                cloth catches it and both come to rest.
// tablecloth-trick  (with a cloth) a table (static box, top at y = 0.75 m, 1.6 m x 1.2 m)
//                under a 1 m cloth (tableclothCloth) on which stand two 0.16 m boxes and a
//                ball of radius 0.07 m; the cloth's +x edge (tableclothGrip) is pulled
//                along +x (tableclothPull) for 1.4 m: fast (4 m/s) the cloth slides out
//                from under them and they stay; slowly (0.4 m/s) they come along.
// Each returns the bodies (RigidOptions::bodies, default solver settings) and
// rigidSceneTimeStep() the scenes' step.
#pragma once

#include <vector>

#include "weft/model/ropes_and_grids.hpp"
#include "weft/rigid/rigid_world.hpp"

namespace weft {

RigidOptions ballOnBrickScene();
RigidOptions stackScene(Index boxes = 10);
RigidOptions pileScene(Index bodies = 1000);
RigidOptions bulletScene(double speed = 200);
RigidOptions slopeScene(double degrees = 30, double mu = 0.7);
RigidOptions hammockBall();
/// The hammock's cloth: size x size particles, 1 m, horizontal at y = 0.5 around the
/// vertical axis; pins: its four corners (grid indices).
ClothGridSpec hammockCloth(Index size = 24);
std::vector<Index> hammockPins(Index size = 24);
RigidOptions tableclothBodies();
/// The tablecloth: size x size particles, 1 m, lying on the table (x in [-0.6, 0.4],
/// z in [-0.5, 0.5], one particle thickness above the top).
ClothGridSpec tableclothCloth(Index size = 32);
/// The particles of the cloth's +x edge, the pulled ones (grid indices).
std::vector<Index> tableclothGrip(Index size = 32);
/// The pull: along +x at `speed` m/s (> 0) from t = 0 until the edge has moved 1.4 m.
KinematicPath tableclothPull(double speed);
/// Top of the tablecloth scene's table, m.
constexpr double tableclothTableTop() { return 0.75; }

/// The scenes' fixed step, s (1/60).
constexpr double rigidSceneTimeStep() { return 1.0 / 60; }

}  // namespace weft
