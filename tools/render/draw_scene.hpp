// tools/render/draw_scene.hpp — what `weft render` and `weft view` draw of a simulation:
// triangle meshes with normals and a colour per side, built from the particles, the
// obstacles and the rigid bodies at one moment. No OpenGL here (renderer.hpp draws it).
//
// Design note
// -----------
// A SceneDrawer is made once per scene from its Model, its collision options and its
// rigid model: it keeps each shape's triangles in the shape's own frame (an icosphere for
// spheres, a capsule of rings, a box, a hull's faces as fans with flat normals, a mesh
// obstacle's vertices at time 0 with smooth normals) and which particles make each cloth
// and each rope. A SceneSnapshot is what moves: the particle positions (float), the time
// (moving mesh obstacles follow their KinematicPath) and every rigid piece's pose. build()
// turns a snapshot into a DrawFrame by transforming the kept shapes and computing the
// cloth's area-weighted vertex normals; a rope's structural springs become tubes.
//
// Cloth is drawn two-sided: its front (the side its triangles' normals point to) and its
// back have colours of their own, and the renderer lights whichever side faces the eye.
// Each cloth body (AssembledScene::firstParticle) has its own pair of colours.
//
// The camera frames framedBounds(): the particles, the moving and kinematic bodies and the
// bounded obstacles; static bodies too unless one is much larger than the rest (a floor
// slab of 10 m under a 1 m stack), and analytic planes never (they are drawn as the
// ground grid when they face up). A static slab under everything (a floor body) becomes the
// ground grid too (findFloors).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "camera.hpp"
#include "weft/collide/obstacles.hpp"
#include "weft/rigid/rigid_world.hpp"
#include "weft/scene/simulation.hpp"

namespace weftrender {

/// One mesh to draw.
struct DrawMesh {
  std::vector<float> positions;                                     // (n x 3) vertex positions, world, m
  std::vector<float> normals;                                       // (n x 3) unit normals of the front side
  std::vector<std::uint32_t> indices;                               // triangles, counter-clockwise seen from the front
  Eigen::Vector3f front{0.6f, 0.6f, 0.6f}, back{0.6f, 0.6f, 0.6f};  // linear RGB of each side
  bool castsShadow = true;
};

struct DrawFrame {
  std::vector<DrawMesh> meshes;
  std::optional<float> groundHeight;  // y of the ground grid, m (none: no grid)
  Bounds framed;                      // what the camera should frame at this moment
};

/// The moving part of a scene at one time.
struct SceneSnapshot {
  double time = 0;                 // s
  std::vector<float> x;            // (n x 3) particle positions, row by row, m
  std::vector<weft::Pose> pieces;  // world pose of every rigid piece
};

class SceneDrawer {
 public:
  /// `firstParticle`: the first particle of each body (AssembledScene::firstParticle);
  /// `rigid`: the bodies' model, or none.
  template <class S>
  SceneDrawer(const weft::Model<S>& model, const std::vector<weft::Index>& firstParticle,
              const weft::CollisionOptions& collision, const weft::RigidModel* rigid);

  template <class S>
  SceneSnapshot snapshot(const weft::Simulation<S>& sim) const;

  /// The snapshot's drawable meshes (out is reused: its buffers keep their capacity).
  /// `tubeRadius`: radius of rope tubes, m.
  void build(const SceneSnapshot& snapshot, float tubeRadius, DrawFrame& out) const;
  /// Marks the floors among the static bodies at the `initial` snapshot: flat, level slabs
  /// (no thicker than a fifth of their width) larger than twice what else is framed. A
  /// floor is not drawn and not framed: the ground grid lies on its top instead.
  void findFloors(const SceneSnapshot& initial);
  /// What the camera frames at this snapshot (see the design note).
  Bounds framedBounds(const SceneSnapshot& snapshot) const;
  /// The ground grid's height when the scene has an upward analytic plane (the highest);
  /// none otherwise (the caller puts it under what it frames).
  std::optional<float> groundPlane() const { return groundPlane_; }
  /// A tube radius that suits ropes in a scene framed by `bounds` (m).
  float tubeRadius(const Bounds& bounds) const;
  weft::Index particleCount() const { return particleCount_; }

 private:
  struct Shape {  // triangles in a local frame
    std::vector<Eigen::Vector3f> vertices, normals;
    std::vector<std::uint32_t> indices;
  };
  struct Cloth {
    weft::Index first = 0, count = 0;    // particles [first, first + count)
    std::vector<std::uint32_t> indices;  // triangles, local to `first`
    Eigen::Vector3f front, back;
  };
  struct Rope {
    std::vector<std::array<weft::Index, 2>> segments;  // particle pairs
  };
  struct PlacedShape {
    Shape shape;
    Eigen::Vector3f colour;
    int piece = -1;  // >= 0: a rigid piece's pose moves it
    int path = -1;   // >= 0: a moving mesh obstacle's path (paths_)
    bool staticBody = false;
    bool floor = false;  // findFloors: drawn as the ground grid
  };

  weft::Index particleCount_ = 0;
  std::vector<Cloth> cloths_;
  Rope rope_;
  std::vector<PlacedShape> shapes_;
  std::vector<weft::KinematicPath> paths_;  // the paths of moving mesh obstacles
  std::vector<weft::Obstacle> planes_;      // analytic planes that do not face up
  std::optional<float> groundPlane_;
};

extern template SceneDrawer::SceneDrawer(const weft::Model<float>&, const std::vector<weft::Index>&,
                                         const weft::CollisionOptions&, const weft::RigidModel*);
extern template SceneDrawer::SceneDrawer(const weft::Model<double>&, const std::vector<weft::Index>&,
                                         const weft::CollisionOptions&, const weft::RigidModel*);
extern template SceneSnapshot SceneDrawer::snapshot(const weft::Simulation<float>&) const;
extern template SceneSnapshot SceneDrawer::snapshot(const weft::Simulation<double>&) const;

}  // namespace weftrender
