// rigid/particle_contacts.hpp (internal) — the pass that couples particles and rigid
// bodies; its design note is in the public weft/rigid/particle_coupling.hpp. Not installed:
// a Simulation owns it.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "weft/core/parallel.hpp"
#include "weft/core/types.hpp"
#include "weft/model/model.hpp"
#include "weft/rigid/particle_coupling.hpp"
#include "weft/rigid/rigid_world.hpp"

namespace weft {

template <class S>
class ParticleBodyContacts {
 public:
  static constexpr int kContactsPerParticle = 2;

  /// thickness: particle radius, m (> 0); triangleCount: the most cloth triangles
  /// countCrossings is given.
  ParticleBodyContacts(const RigidModel& bodies, Index particleCount, double thickness, Index triangleCount);

  /// Resolves the particles' candidate (x1, v1) of the step x0 -> x1 against the bodies
  /// of `world` (which has stepped over the same interval), and applies the reactions to
  /// the bodies. w: inverse masses of the particles (0: pinned, not moved).
  ParticleBodyStats resolve(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1, const ScalarArray<S>& w,
                            RigidWorld& world, const Executor& exec);

  /// Before the bodies step over [t, t + h]: the contacts of held particles (see above) at
  /// (x, v) with the dynamic bodies of `world`, handed to world.setSupports (the world
  /// must have room for particleCount x kContactsPerParticle: reserveSupports).
  /// Returns how many.
  Index collectSupports(const Vec3Array<S>& x, const Vec3Array<S>& v, const ScalarArray<S>& w, RigidWorld& world,
                        const Executor& exec);

  /// After resolve over the same step (it keeps the box of the particles' paths): the moving (dynamic or kinematic)
  /// bodies of `world` whose centre of mass went through a triangle of the cloth over the step (x0 -> x1, the bodies
  /// from world.stepStart() to world.state(), both moving linearly): an odd number of passes through the triangle's
  /// inside, at the roots of the cubic of coplanarity. Bodies in order, each tested against blocks of triangles in
  /// parallel (a yes or no a block: the same answer for any thread count); the first such body in *first (-1 if none).
  /// Nothing allocated.
  std::int64_t countCrossings(const Vec3Array<S>& x0, const Vec3Array<S>& x1, const Triangles& triangles,
                              const RigidWorld& world, const Executor& exec, Index* first);

  double thickness() const { return thickness_; }

 private:
  struct Record {
    Index piece = -1;                                   // -1: none
    Eigen::Vector3d impulse = Eigen::Vector3d::Zero();  // on the particle, N s (the body gets the opposite)
    Eigen::Vector3d point = Eigen::Vector3d::Zero();    // world, m
  };
  double thickness_;
  std::vector<Record> records_;                   // particleCount x kContactsPerParticle
  std::vector<Pose> start_, end_;                 // per piece
  std::vector<Eigen::Vector3d> boxMin_, boxMax_;  // per piece: swept box grown by the thickness
  std::vector<SupportContact> supportSlots_;      // particleCount x kContactsPerParticle
  std::vector<int> supportCount_;                 // per particle
  std::vector<SupportContact> supports_;          // the step's list, in particle order
  static constexpr Index kResolveBlock = 256;     // resolve's blocks
  static constexpr Index kCrossingParticles = 2048, kCrossingTriangles = 2048;  // countCrossings' blocks
  std::vector<Eigen::Vector3d> pathLo_, pathHi_;  // per block of resolve: the box of its particles' paths
  std::vector<std::uint8_t> side_;                // per particle: countCrossings' box test
  std::vector<std::uint8_t> triangleFlags_;       // per block of triangles: a crossing found
};

extern template class ParticleBodyContacts<float>;
extern template class ParticleBodyContacts<double>;

}  // namespace weft
