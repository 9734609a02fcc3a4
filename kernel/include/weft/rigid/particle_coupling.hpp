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
//
// Held particles. A light particle caught between a dynamic body and something that does
// not yield (a cloth under a box on a table) cannot push the body back through that
// explicit exchange: the box would press the particle into the table, the table push it
// back into the box, and the box sink through the cloth. So before the bodies step,
// collectSupports finds the particles that are held (pinned or kinematic, w = 0, or lying
// within half a thickness of a static or kinematic body) and hands each held particle's
// contact with a dynamic body (within the speculative distance) to the body solver as a
// SupportContact: the body rests on the point and feels its friction, the point moving
// with the particle's velocity, while what holds the particle takes the reaction. A box
// on a tablecloth stays on it, and comes along with it when the cloth is pulled slowly
// and stays behind when it is pulled fast (friction limits the impulse it can pass on:
// the tablecloth trick). A held particle is not slowed by the body's friction: what holds
// or drives it is assumed to be stronger.
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
  /// Moving bodies whose centre of mass went through a cloth triangle (the cloth did not
  /// hold them: the coupling keeps particles out of bodies, not the triangles between
  /// them, so a body the cloth cannot carry pushes its particles apart and passes between
  /// them). Per step: how many bodies; over a run (Simulation::totalParticleBodyContacts):
  /// how many times, with the first one's body and the start of its step.
  std::int64_t crossings = 0;
  Index firstCrossingBody = -1;
  double firstCrossingTime = 0;  // s

  /// Adds a later step's figures (the first crossing stays the earliest).
  ParticleBodyStats& operator+=(const ParticleBodyStats& later) {
    contacts += later.contacts;
    impulse += later.impulse;
    if (crossings == 0 && later.crossings > 0) {
      firstCrossingBody = later.firstCrossingBody;
      firstCrossingTime = later.firstCrossingTime;
    }
    crossings += later.crossings;
    return *this;
  }
};

/// The coupling pass itself (ParticleBodyContacts) is internal to weft:
/// kernel/src/rigid/particle_contacts.hpp. A Simulation owns it and reports
/// Simulation::lastParticleBodyContacts.
template <class S>
class ParticleBodyContacts;

}  // namespace weft
