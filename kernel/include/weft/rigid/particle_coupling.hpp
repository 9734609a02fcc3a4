// weft/rigid/particle_coupling.hpp — particles push bodies and bodies push particles.
//
// Design note
// -----------
// Two-way coupling of cloth and ropes with rigid bodies, after both have stepped over
// [t, t + h]: the bodies from their poses at t to those at t + h (RigidWorld::step), the
// particles from x0 to the candidate (x1, v1). Each free particle is a sphere of radius
// `thickness` and is tested against every body piece whose box (the piece at t united
// with the piece at t + h, grown by the thickness) holds its segment's box:
//
//   detection  in the piece's own frame, the particle moves from R0^T (x0 - p0) to
//              R1^T (x1 - p1) (the body's motion taken out, as for moving mesh
//              obstacles); conservative advancement along that segment on the piece's
//              distance function (1-Lipschitz: a step of distance - thickness never jumps
//              over the surface) finds the first point within epsilon of the thickened
//              surface; a particle that ends inside is pushed out along the normal.
//   response   relative to the body's surface velocity u = v + w x r: the normal
//              approach is removed (inelastic) and the tangential slip feels Coulomb
//              friction (the body's coefficients), with the impulse J computed for the
//              pair's effective mass 1 / (w_particle + 1/m + (r x n) I^-1 (r x n)), so a
//              light particle on a heavy body takes nearly all the change and a heavy
//              one moves a light body. The particle gets w_particle J, the body -J.
//
// Detection and the particle's response run in parallel per block of particles, each
// particle writing its own slots (at most kContactsPerParticle bodies); the bodies'
// impulses are then applied serially in particle order, so linear momentum is exchanged
// exactly (up to rounding) and the result is bitwise the same for any thread count. The
// body's reaction acts from the next step on (the body's positions of this step are
// kept): an explicit coupling, which is what keeps the two solvers independent. Nothing
// is allocated after construction.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "weft/core/parallel.hpp"
#include "weft/core/types.hpp"
#include "weft/rigid/rigid_world.hpp"

namespace weft {

struct ParticleBodyStats {
  std::int64_t contacts = 0;  // particle-piece contacts resolved
  double impulse = 0;         // sum of |J| over them, N s
};

template <class S>
class ParticleBodyContacts {
 public:
  static constexpr int kContactsPerParticle = 2;

  /// thickness: particle radius, m (> 0).
  ParticleBodyContacts(const RigidModel& bodies, Index particleCount, double thickness);

  /// Resolves the particles' candidate (x1, v1) of the step x0 -> x1 against the bodies
  /// of `world` (which has stepped over the same interval), and applies the reactions to
  /// the bodies. w: inverse masses of the particles (0: pinned, not moved).
  ParticleBodyStats resolve(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1, const ScalarArray<S>& w,
                            RigidWorld& world, const Executor& exec);

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
};

extern template class ParticleBodyContacts<float>;
extern template class ParticleBodyContacts<double>;

}  // namespace weft
