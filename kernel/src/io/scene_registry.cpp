// The built-in scenes (`weft run flag`, ...): each a SceneSpec built here, so that a
// built-in scene and its JSON twin in tools/scenes/ go through the same assembly. The
// bodies and rigid bodies come from weft/scene (builtin_scenes.hpp, rigid_scenes.hpp);
// this file sets their time step, duration, pins, effects and obstacles.
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "builtin_meshes.hpp"
#include "weft/io/scene.hpp"
#include "weft/scene/builtin_scenes.hpp"
#include "weft/scene/rigid_scenes.hpp"

namespace weft {

std::vector<std::string> builtinSceneNames() {
  return {"flag",         "rope",      "flag-wind",        "hanging-cloth",   "drape", "drape-mesh",
          "rope-on-pegs", "fast-ball", "ball-on-brick",    "stack",           "pile",  "bullet",
          "slope",        "hammock",   "tablecloth-trick", "tablecloth-slow", "fold",  "two-cloths",
          "twist",        "flag-pole"};
}

SceneSpec builtinSceneSpec(const std::string& name, Index size) {
  SceneSpec scene;
  scene.name = name;
  scene.steps = 2000;
  // Rigid bodies only (weft/scene/rigid_scenes.hpp), 1/60 s steps: 10 s, the pile 5 s,
  // the bullet 0.5 s. --size is the number of boxes (stack) or bodies (pile).
  const auto rigidOnly = [&](RigidOptions rigid, double seconds) {
    scene.simulation.rigid = std::move(rigid);
    scene.simulation.dt = rigidSceneTimeStep();
    scene.steps = static_cast<std::int64_t>(std::lround(seconds / scene.simulation.dt));
    return scene;
  };
  const auto count = [&](Index fallback) { return size > 0 ? size : fallback; };
  // Scenes of a fixed layout have nothing --size could set: a size is refused, not ignored.
  if (size > 0 && (name == "ball-on-brick" || name == "bullet" || name == "slope"))
    throw SceneError(name + ": the scene has a fixed layout, so a size does not apply (got " + std::to_string(size) +
                     "; the sized scenes are the cloths, the ropes, stack and pile)");
  if (name == "ball-on-brick") return rigidOnly(ballOnBrickScene(), 10);
  if (name == "stack") return rigidOnly(stackScene(count(10)), 10);
  if (name == "pile") return rigidOnly(pileScene(count(1000)), 5);
  if (name == "bullet") return rigidOnly(bulletScene(200), 0.5);
  if (name == "slope") return rigidOnly(slopeScene(30, 0.3), 2);
  // One cloth grid or rope; its side or particle count is --size (at least 2) or the
  // scene's default; the time step is the default for that size.
  BodySpec body;
  const auto side = [&](Index fallback) {
    const Index n = count(fallback);
    if (n < 2) throw SceneError(name + ": size must be >= 2, got " + std::to_string(n));
    return n;
  };
  const auto cloth = [&](const char* bodyName, const ClothGridSpec& grid, Index n) {
    body.kind = BodyKind::ClothGrid;
    body.name = bodyName;
    body.grid = grid;
    scene.simulation.dt = defaultTimeStep(BuiltinScene::Flag, n);
  };
  // The gusty wind of flag-wind and flag-pole: along +x, gusts of 2 m/s.
  const auto gustyWind = [&] {
    WindEffect& w = scene.simulation.effects.wind;
    w.enabled = true;
    w.velocity = {6, 0, 1};
    w.gustStrength = 2;
    w.gustScale = 1.5;
    w.gustPeriod = 0.8;
  };
  const auto rope = [&](Index n) {
    body.kind = BodyKind::Rope;
    body.name = "rope";
    body.rope = ropeSpec(n);
    scene.simulation.dt = defaultTimeStep(BuiltinScene::Rope, n);
  };
  if (name == "flag" || name == "flag-wind" || name == "hanging-cloth") {
    const Index n = side(defaultSceneSize(BuiltinScene::Flag));
    cloth("cloth", flagSpec(n), n);
    const Index last = n - 1;
    if (name != "flag") {  // hanging in the x-y plane from its top-left corner
      body.grid.origin = {0, 1, 0};
      body.grid.rowAxis = {1, 0, 0};
      body.grid.columnAxis = {0, -1, 0};
    }
    if (name == "flag") {
      // Horizontal, pinned at the two corners of row 0 (weft::makeFlag).
      body.pins.push_back({{0, last}, std::nullopt, std::nullopt});
    } else if (name == "flag-wind") {
      // Hanging from a pole along its left edge (column 0), in the x-y plane, in a gusty
      // wind blowing along +x: it streams out and flutters. The gusts fold its free corner
      // over onto itself, so self-collision is on (without it the flag ends its 2000 steps
      // with 55 pairs of its triangles through each other).
      PinSpec pole;
      for (Index r = 0; r < n; ++r) pole.particles.push_back(r * n);
      body.pins.push_back(pole);
      gustyWind();
      scene.simulation.effects.drag = 1e-4;
      scene.simulation.selfCollision.enabled = true;
    } else {
      // Hanging from a bar along its top edge (row 0), in the x-y plane; the bar turns
      // half a turn about the vertical through its middle in the first second, then holds:
      // the cloth twists and swings. Repulsion keeps the twisting folds apart.
      PinSpec bar;
      for (Index c = 0; c < n; ++c) bar.particles.push_back(c);
      KinematicPath path;
      path.center = {0.5, 1, 0};
      path.axis = {0, 1, 0};
      path.angularVelocity = 3.14159265358979323846;
      path.startTime = 0;
      path.endTime = 1;
      bar.path = path;
      body.pins.push_back(bar);
      scene.simulation.effects.drag = 1e-3;
      scene.simulation.effects.repulsion.radius = 0.5 * body.grid.spacing;
      scene.simulation.effects.repulsion.stiffness = 200;
    }
  } else if (name == "hammock") {
    // A 1 kg ball dropped into a cloth pinned at its four corners (size x size, default 24;
    // weft/scene/rigid_scenes.hpp): particles and the body push each other; 6 s.
    const Index n = side(24);
    cloth("cloth", hammockCloth(n), n);
    body.pins.push_back({hammockPins(n), std::nullopt, std::nullopt});
    scene.steps = static_cast<std::int64_t>(std::ceil(6.0 / scene.simulation.dt));
    scene.simulation.effects.drag = 0.03;  // a heavy, damped fabric: the ball comes to rest
    scene.simulation.rigid = hammockBall();
  } else if (name == "tablecloth-trick" || name == "tablecloth-slow") {
    // Two boxes and a ball on a 1 m cloth (size x size, default 32) on a table; the
    // cloth's +x edge is pulled along +x (weft/scene/rigid_scenes.hpp): at 4 m/s it slides
    // out from under them and they stay (1 s); at 0.4 m/s they come along (2 s).
    const bool fast = name == "tablecloth-trick";
    const Index n = side(32);
    cloth("cloth", tableclothCloth(n), n);
    body.pins.push_back({tableclothGrip(n), std::nullopt, tableclothPull(fast ? 4.0 : 0.4)});
    scene.simulation.integrator = IntegratorKind::SymplecticEuler;
    scene.steps = static_cast<std::int64_t>(std::ceil((fast ? 1.0 : 2.0) / scene.simulation.dt));
    scene.simulation.rigid = tableclothBodies();
    // The fast pull snaps the cloth off the table, and trailing from the grip it folds onto
    // itself (158 pairs of its triangles through each other at the end unless self-collision
    // keeps them apart); the slow one carries the bodies along on a cloth that never folds.
    scene.simulation.selfCollision.enabled = fast;
  } else if (name == "rope") {
    rope(side(defaultSceneSize(BuiltinScene::Rope)));
    body.pins.push_back({{0}, std::nullopt, std::nullopt});
  } else if (name == "drape" || name == "drape-mesh") {
    // A free 1 m cloth (size x size, default 32) falling from 0.5 m, a floor at y = -0.4; 2 s.
    // drape: onto a sphere of radius 0.3 m at the origin. drape-mesh: onto a torus lying
    // flat around the origin (major radius 0.3 m, tube 0.1 m: 1536 triangles), imported
    // from the OBJ file embedded in the library (tools/scenes/meshes/torus.obj, in cm).
    const Index n = side(32);
    cloth("cloth", flagSpec(n), n);
    body.grid.origin = {-0.5, 0.5, -0.5};
    scene.steps = static_cast<std::int64_t>(std::ceil(2.0 / scene.simulation.dt));
    scene.simulation.effects.drag = 1e-3;
    if (name == "drape") scene.simulation.collision.obstacles.push_back(Obstacle::sphere({0, 0, 0}, 0.3));
    scene.simulation.collision.obstacles.push_back(Obstacle::plane({0, -0.4, 0}, {0, 1, 0}));
    if (name == "drape-mesh") {
      MeshObstacleSpec torus;
      torus.obstacle.name = "torus";
      torus.meshFile = "torus.obj";
      torus.meshContents = std::string(builtinTorusObj());
      torus.scale = 0.01;
      scene.meshObstacles.push_back(std::move(torus));
    }
  } else if (name == "fold" || name == "two-cloths" || name == "twist" || name == "flag-pole") {
    // Cloth against itself (self-collision on, weft/collide/self_collision.hpp).
    scene.simulation.selfCollision.enabled = true;
    scene.simulation.effects.drag = 1e-3;
    if (name == "fold") {
      // A free 1 m cloth (size x size, default 32) held upright and leaning (its lower edge
      // 0.2 m above the floor at y = 0), let go: it lands in folds on itself; 2.5 s.
      const Index n = side(32);
      cloth("cloth", flagSpec(n), n);
      body.grid.origin = {-0.5, 1.2, -0.2};
      body.grid.rowAxis = {1, 0, 0};
      body.grid.columnAxis = {0, -0.96, 0.28};
      scene.simulation.collision.obstacles.push_back(Obstacle::plane({0, 0, 0}, {0, 1, 0}));
      scene.steps = static_cast<std::int64_t>(std::ceil(2.5 / scene.simulation.dt));
    } else if (name == "two-cloths") {
      // Two free 1 m cloths (size x size each, default 24) dropped onto a sphere (radius
      // 0.3 m at the origin; a floor at y = -0.4): one at 0.5 m, the other 0.15 m above it
      // and turned 45 degrees about the vertical, 6 mm thick against the lower one's 4 mm; 2.5 s.
      const Index n = side(24);
      cloth("lower", flagSpec(n), n);
      body.grid.origin = {-0.5, 0.5, -0.5};
      BodySpec upper = body;
      upper.name = "upper";
      const double c = std::sqrt(0.5);
      upper.grid.rowAxis = {c, 0, c};
      upper.grid.columnAxis = {-c, 0, c};
      upper.grid.origin = {0, 0.65, -c};     // centred above the sphere: origin + (row + column) / 2 = (0, 0.65, 0)
      upper.selfCollisionThickness = 0.006;  // a thicker cloth onto a thinner one: 5 mm kept between them
      scene.bodies.push_back(upper);
      scene.simulation.collision.obstacles.push_back(Obstacle::sphere({0, 0, 0}, 0.3));
      scene.simulation.collision.obstacles.push_back(Obstacle::plane({0, -0.4, 0}, {0, 1, 0}));
      scene.steps = static_cast<std::int64_t>(std::ceil(2.5 / scene.simulation.dt));
    } else if (name == "twist") {
      // A 1 m square cloth (size x size, default 32), horizontal at y = 0.5, held along its
      // two edges x = 0 and x = 1 by bars that turn about the x axis in opposite directions
      // at half a turn per second while closing in at 0.1 m/s each, for 3 s (three turns
      // of one bar against the other), then hold: the classic wringing test; 4 s.
      const Index n = side(32);
      cloth("cloth", flagSpec(n), n);
      body.grid.origin = {0, 0.5, 0};
      body.grid.rowAxis = {1, 0, 0};
      body.grid.columnAxis = {0, 0, 1};
      for (const int end : {0, 1}) {
        PinSpec bar;
        for (Index r = 0; r < n; ++r) bar.particles.push_back(r * n + (end == 0 ? 0 : n - 1));
        KinematicPath path;
        path.center = {static_cast<double>(end), 0.5, 0.5};
        path.axis = {1, 0, 0};
        path.angularVelocity = (end == 0 ? 1 : -1) * 3.14159265358979323846;
        path.velocity = {end == 0 ? 0.1 : -0.1, 0, 0};
        path.startTime = 0;
        path.endTime = 3;
        bar.path = path;
        body.pins.push_back(bar);
      }
      scene.steps = static_cast<std::int64_t>(std::ceil(4.0 / scene.simulation.dt));
    } else {
      // flag-pole: the flag of flag-wind (size x size, default 32) on a pole (a capsule of
      // radius 2.5 cm along its left edge) in the same gusty wind; from 0.5 s to 2.5 s the
      // pole turns (3 rad/s about its axis, carrying the pinned edge): the flag wraps
      // around it; 4 s.
      const Index n = side(32);
      cloth("flag", flagSpec(n), n);
      body.grid.origin = {0, 1, 0};
      body.grid.rowAxis = {1, 0, 0};
      body.grid.columnAxis = {0, -1, 0};
      PinSpec pole;
      for (Index r = 0; r < n; ++r) pole.particles.push_back(r * n);
      KinematicPath turn;
      turn.center = {-0.03, 0, 0};
      turn.axis = {0, 1, 0};
      turn.angularVelocity = 3;
      turn.startTime = 0.5;
      turn.endTime = 2.5;
      pole.path = turn;
      body.pins.push_back(pole);
      gustyWind();
      scene.simulation.collision.obstacles.push_back(Obstacle::capsule({-0.03, -0.2, 0}, {-0.03, 1.2, 0}, 0.025));
      scene.steps = static_cast<std::int64_t>(std::ceil(4.0 / scene.simulation.dt));
    }
  } else if (name == "rope-on-pegs") {
    // A free 1 m rope (size particles, default 64) falling from 0.3 m across three pegs
    // (capsules along z, radius 3 cm, at x = 0.2, 0.5, 0.8, y = 0), a floor at y = -0.6; 2 s.
    rope(side(defaultSceneSize(BuiltinScene::Rope)));
    body.rope.origin = {0, 0.3, 0};
    scene.steps = static_cast<std::int64_t>(std::ceil(2.0 / scene.simulation.dt));
    for (const double x : {0.2, 0.5, 0.8})
      scene.simulation.collision.obstacles.push_back(Obstacle::capsule({x, 0, -0.2}, {x, 0, 0.2}, 0.03));
    scene.simulation.collision.obstacles.push_back(Obstacle::plane({0, -0.6, 0}, {0, 1, 0}));
  } else if (name == "fast-ball") {
    // The tunnelling case: a small soft cloth (size x size particles, default 4, 5 cm) fired
    // at 100 m/s along +x at a wall of one triangle in the plane x = 1, dt = 1/60 s (1.7 m
    // per step); 1 s.
    const Index n = side(4);
    cloth("ball", flagSpec(n), n);
    body.grid.spacing = 0.05 / static_cast<double>(n - 1);
    body.grid.origin = {0, 0, -0.025};
    body.grid.columnAxis = {0, 1, 0};
    body.grid.rowAxis = {0, 0, 1};
    body.grid.totalMass = 0.05;
    body.grid.structural = {2, 0.01};
    body.grid.shear = {1, 0.005};
    body.grid.bend = {0.5, 0.002};
    body.velocity = {100, 0, 0};
    scene.simulation.dt = 1.0 / 60;
    scene.steps = 60;
    MeshObstacle wall;
    wall.name = "wall";
    wall.mesh.vertices = {{1, -10, -10}, {1, 10, -10}, {1, 0, 20}};
    wall.mesh.triangles = {{0, 1, 2}};
    scene.simulation.collision.meshes.push_back(wall);
  } else {
    std::string list;
    for (const std::string& s : builtinSceneNames()) list += (list.empty() ? "" : ", ") + s;
    throw SceneError("scene must be a built-in scene (" + list + ") or a .json scene file; got '" + name + "'");
  }
  scene.bodies.push_back(body);
  return scene;
}

}  // namespace weft
