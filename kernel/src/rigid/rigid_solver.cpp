// RigidWorld's contact solver: constraints from the manifolds, warm starting, the substeps'
// velocity passes (friction, the manifold's normal block), split impulses, positions and
// restitution (the step that calls them and the collision detection: rigid_world.cpp).
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>

#include "weft/rigid/rigid_world.hpp"

namespace weft {

namespace {

constexpr double kWarmStartDistance = 0.01;  // m

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Quaterniond;

/// Orthonormal tangents of a unit normal, a fixed function of it (warm starting of
/// friction re-projects the stored world impulse, so the basis may change between steps).
void tangents(const Vec3& n, Vec3& t1, Vec3& t2) {
  if (std::abs(n.x()) >= 0.57735026918962576) {
    t1 = Vec3(n.y(), -n.x(), 0).normalized();
  } else {
    t1 = Vec3(0, n.z(), -n.y()).normalized();
  }
  t2 = n.cross(t1);
}

/// Rotation over h with the world angular momentum L held fixed (torque-free motion
/// between contact impulses): RK4 on dq/dt = 1/2 (0, w(q)) q with w(q) = R I^-1 R^T L.
Quat integrateRotation(const Quat& q0, const Vec3& L, const Mat3& invInertiaBody, double h) {
  const auto derivative = [&](const Eigen::Vector4d& c) -> Eigen::Vector4d {
    Quat q(c[3], c[0], c[1], c[2]);
    q.normalize();
    const Mat3 r = q.toRotationMatrix();
    const Vec3 w = r * (invInertiaBody * (r.transpose() * L));
    const Quat dq = Quat(0, w.x(), w.y(), w.z()) * q;
    return 0.5 * dq.coeffs();
  };
  const Eigen::Vector4d c0 = q0.coeffs();
  const Eigen::Vector4d k1 = derivative(c0);
  const Eigen::Vector4d k2 = derivative(c0 + 0.5 * h * k1);
  const Eigen::Vector4d k3 = derivative(c0 + 0.5 * h * k2);
  const Eigen::Vector4d k4 = derivative(c0 + h * k3);
  const Eigen::Vector4d c = c0 + (h / 6) * (k1 + 2 * k2 + 2 * k3 + k4);
  Quat q(c[3], c[0], c[1], c[2]);
  q.normalize();
  return q;
}

}  // namespace

void RigidWorld::buildConstraints(double h) {
  const RigidModel& m = *model_;
  const Index count = static_cast<Index>(pairs_.size());
  constraints_.clear();
  pairFirstConstraint_.clear();
  for (Index k = 0; k < count; ++k) {
    pairFirstConstraint_.push_back(static_cast<Index>(constraints_.size()));
    const ContactManifold& man = manifolds_[k];
    if (man.pointCount == 0) continue;
    const Index a = m.pieces[pairs_[k].a].body;
    const Index b = m.pieces[pairs_[k].b].body;
    const double thinner = std::min(m.pieces[pairs_[k].a].innerRadius, m.pieces[pairs_[k].b].innerRadius);
    const std::uint64_t key = pairs_[k].key();
    // The same pair's points of the last step, for warm starting.
    const auto found = std::lower_bound(lastPairs_.begin(), lastPairs_.end(), key,
                                        [](const Pair& p, std::uint64_t kk) { return p.key() < kk; });
    Index lastBegin = 0, lastEnd = 0;
    if (found != lastPairs_.end() && found->key() == key) {
      const std::size_t li = static_cast<std::size_t>(found - lastPairs_.begin());
      lastBegin = lastPairFirstConstraint_[li];
      lastEnd = lastPairFirstConstraint_[li + 1];
    }
    const double muStatic = std::sqrt(m.staticFriction[a] * m.staticFriction[b]);
    const double muKinetic = std::sqrt(m.kineticFriction[a] * m.kineticFriction[b]);
    const double e = std::max(m.restitution[a], m.restitution[b]);
    const double ima = m.inverseMass[a], imb = m.inverseMass[b];
    const Mat3& iia = invInertiaWorld_[a];
    const Mat3& iib = invInertiaWorld_[b];
    for (int p = 0; p < man.pointCount; ++p) {
      const ContactPoint& cp = man.points[p];
      // Rollback: only touching points are solved (the chunk is cut so that the others
      // cannot get deeper than the limit within it).
      if (rollback() && cp.separation > options_.linearSlop) continue;
      Constraint c;
      c.bodyA = a;
      c.bodyB = b;
      c.rA = cp.position - state_.x[a];
      c.rB = cp.position - state_.x[b];
      c.normal = man.normal;
      tangents(c.normal, c.tangent1, c.tangent2);
      const auto effectiveMass = [&](const Vec3& dir) {
        const Vec3 ra = c.rA.cross(dir), rb = c.rB.cross(dir);
        const double sum = ima + imb + ra.dot(iia * ra) + rb.dot(iib * rb);
        return sum > 0 ? 1 / sum : 0.0;
      };
      c.normalMass = effectiveMass(c.normal);
      c.tangentMass1 = effectiveMass(c.tangent1);
      c.tangentMass2 = effectiveMass(c.tangent2);
      c.inverseMassA = ima;
      c.inverseMassB = imb;
      for (int d = 0; d < 3; ++d) {
        c.crossA[d] = c.rA.cross(c.direction(d));
        c.crossB[d] = c.rB.cross(c.direction(d));
        c.angularA[d] = iia * c.crossA[d];
        c.angularB[d] = iib * c.crossB[d];
      }
      c.separation = cp.separation;
      c.previousSeparation = cp.separation;
      last_.maxPenetration = std::max(last_.maxPenetration, -cp.separation);
      if (const double share = -cp.separation / thinner; share > last_.deepestShare) {
        last_.deepestShare = share;
        last_.deepestDepth = -cp.separation;
        last_.deepestA = a;
        last_.deepestB = b;
        last_.deepestTime = state_.time;
      }
      const Vec3 dv = state_.v[b] + state_.w[b].cross(c.rB) - state_.v[a] - state_.w[a].cross(c.rA);
      c.approachVelocity = dv.dot(c.normal);
      const Vec3 slip = dv - c.approachVelocity * c.normal;
      c.friction = slip.norm() < options_.staticSpeed ? muStatic : muKinetic;
      c.restitution = e;
      c.pairKey = key;
      c.featureId = cp.featureId;
      // Warm start from the last step's point of this pair with the same feature id or,
      // when the features changed (ties between coincident edges flip them), the nearest
      // one in body A's frame within kWarmStartDistance (as Jolt matches by position).
      c.anchor = rotation_[a].transpose() * c.rA;
      Index match = -1;
      double nearest = kWarmStartDistance * kWarmStartDistance;
      for (Index l = lastBegin; l < lastEnd; ++l) {
        const WarmPoint& old = lastPoints_[l];
        if (old.featureId == c.featureId) {
          match = l;
          break;
        }
        const double d2 = (old.anchor - c.anchor).squaredNorm();
        if (d2 < nearest) {
          nearest = d2;
          match = l;
        }
      }
      if (match >= 0) {
        // Impulses per substep: rescaled when the substep changed.
        const double scale = lastSubstep_ > 0 ? h / lastSubstep_ : 1.0;
        const WarmPoint& old = lastPoints_[match];
        c.normalImpulse = scale * old.normalImpulse;
        const Vec3 friction = scale * old.frictionImpulse;
        c.tangentImpulse1 = friction.dot(c.tangent1);
        c.tangentImpulse2 = friction.dot(c.tangent2);
        ++last_.warmStarted;
      }
      constraints_.push_back(c);
    }
  }
  pairFirstConstraint_.push_back(static_cast<Index>(constraints_.size()));
  // One block per manifold: the (regularised) inverse of K_ij = n . (velocity change at
  // point i per unit normal impulse at point j). Points of one face are coplanar, so K has
  // rank 3 at most: the small ridge makes the answer the one of least impulse, spread
  // evenly over the points, as a body resting on four corners has.
  blocks_.clear();
  for (Index k = 0; k < count; ++k) {
    const Index first = pairFirstConstraint_[k], end = pairFirstConstraint_[k + 1];
    if (end == first) continue;
    Block block;
    block.first = first;
    block.count = static_cast<int>(end - first);
    if (block.count > 1) {
      const Constraint* c = constraints_.data() + first;
      const Index a = c[0].bodyA, b = c[0].bodyB;
      const double im = m.inverseMass[a] + m.inverseMass[b];
      Eigen::Matrix4d K = Eigen::Matrix4d::Identity();
      for (int i = 0; i < block.count; ++i) {
        const Vec3 ai = c[i].rA.cross(c[i].normal), bi = c[i].rB.cross(c[i].normal);
        for (int j = 0; j < block.count; ++j) {
          const Vec3 aj = c[j].rA.cross(c[j].normal), bj = c[j].rB.cross(c[j].normal);
          K(i, j) =
              im * c[i].normal.dot(c[j].normal) + ai.dot(invInertiaWorld_[a] * aj) + bi.dot(invInertiaWorld_[b] * bj);
        }
      }
      const double ridge = 1e-6 * K.diagonal().head(block.count).maxCoeff();
      for (int i = 0; i < block.count; ++i) K(i, i) += ridge;
      block.inverse = Eigen::Matrix4d::Zero();
      if (block.count == 4) {
        block.inverse = K.inverse();
      } else if (block.count == 3) {
        block.inverse.topLeftCorner<3, 3>() = K.topLeftCorner<3, 3>().inverse();
      } else {
        block.inverse.topLeftCorner<2, 2>() = K.topLeftCorner<2, 2>().inverse();
      }
    }
    blocks_.push_back(block);
  }
  colourBlocks();
  (void)h;
}

void RigidWorld::colourBlocks() {
  // Greedy colouring in block (pair) order, as Box2D v3 colours its constraint graph: each
  // manifold takes the lowest colour neither of its dynamic bodies has yet. Static and
  // kinematic bodies are only read by the passes, so they do not constrain the colours.
  const RigidModel& m = *model_;
  std::fill(bodyColours_.begin(), bodyColours_.end(), 0);
  colourCount_.assign(kColours + 1, 0);
  const std::size_t count = blocks_.size();
  colourOrder_.resize(count);  // within the reserved capacity
  for (std::size_t k = 0; k < count; ++k) {
    const Constraint& c = constraints_[static_cast<std::size_t>(blocks_[k].first)];
    const bool dynA = m.motion[c.bodyA] == BodyMotion::Dynamic, dynB = m.motion[c.bodyB] == BodyMotion::Dynamic;
    const std::uint64_t used = (dynA ? bodyColours_[c.bodyA] : 0) | (dynB ? bodyColours_[c.bodyB] : 0);
    int colour = kColours;  // all taken: the serial colour
    if (~used != 0) colour = std::countr_zero(~used);
    if (colour < kColours) {
      if (dynA) bodyColours_[c.bodyA] |= std::uint64_t(1) << colour;
      if (dynB) bodyColours_[c.bodyB] |= std::uint64_t(1) << colour;
    }
    blocks_[k].colour = colour;
    ++colourCount_[colour];
  }
  // Counting sort: block indices colour by colour, in block order within a colour
  // (colourCount_ becomes each colour's insertion cursor).
  colourStart_.assign(kColours + 2, 0);
  for (int c = 0; c <= kColours; ++c) colourStart_[c + 1] = colourStart_[c] + colourCount_[c];
  for (int c = 0; c <= kColours; ++c) colourCount_[c] = colourStart_[c];
  for (std::size_t k = 0; k < count; ++k)
    colourOrder_[static_cast<std::size_t>(colourCount_[blocks_[k].colour]++)] = static_cast<Index>(k);
}

template <class Fn>
void RigidWorld::forEachBlockByColour(const Executor& executor, bool reversed, Fn&& fn) {
  // Colours with few manifolds run serially (a parallel dispatch costs more than they do);
  // the result is the same either way, as a colour's manifolds share no dynamic body.
  constexpr Index kParallelBlocks = 128, kGrain = 32;
  for (int k = 0; k <= kColours; ++k) {
    const int colour = reversed ? kColours - k : k;
    const Index begin = colourStart_[colour], end = colourStart_[colour + 1];
    if (begin == end) continue;
    if (colour == kColours || end - begin < kParallelBlocks) {
      for (Index i = begin; i < end; ++i) fn(colourOrder_[static_cast<std::size_t>(i)]);
    } else {
      executor.parallelFor(end - begin, kGrain, [&](Index b0, Index b1) {
        for (Index i = b0; i < b1; ++i) fn(colourOrder_[static_cast<std::size_t>(begin + i)]);
      });
    }
  }
}

void RigidWorld::warmStart(const Executor& executor) {
  forEachBlockByColour(executor, false, [&](Index b) {
    const Block& block = blocks_[static_cast<std::size_t>(b)];
    for (int p = 0; p < block.count; ++p) {
      Constraint& c = constraints_[static_cast<std::size_t>(block.first + p)];
      // An impulse found while the point was still apart at the start of its substep is an
      // impact (a speculative contact closing): it stopped the approach once and must not
      // be applied again (it would throw the body back). Only resting contact carries over.
      const bool impact = c.previousSeparation > options_.linearSlop;
      c.previousSeparation = c.separation;
      if (impact) {
        c.normalImpulse = c.tangentImpulse1 = c.tangentImpulse2 = 0;
        continue;
      }
      apply(c, 0, c.normalImpulse);
      apply(c, 1, c.tangentImpulse1);
      apply(c, 2, c.tangentImpulse2);
    }
  });
  for (Support& s : supports_) {
    const bool impact = s.previousSeparation > options_.linearSlop;
    s.previousSeparation = s.separation;
    for (int k = 0; k < 3; ++k) {
      if (impact) s.impulse[k] = 0;
      applySupport(s, k, s.impulse[k]);
    }
  }
}

void RigidWorld::advanceSeparations(double hs, const Executor& executor) {
  // The points moved with the bodies' velocities (real and split) over the substep.
  executor.parallelFor(static_cast<Index>(constraints_.size()), 256, [&](Index begin, Index end) {
    for (Index k = begin; k < end; ++k) {
      Constraint& c = constraints_[static_cast<std::size_t>(k)];
      const Index a = c.bodyA, b = c.bodyB;
      const Vec3 va = state_.v[a] + pushV_[a] + (state_.w[a] + pushW_[a]).cross(c.rA);
      const Vec3 vb = state_.v[b] + pushV_[b] + (state_.w[b] + pushW_[b]).cross(c.rB);
      c.separation += hs * (vb - va).dot(c.normal);
    }
  });
  for (Support& s : supports_) {
    const Vec3 vb = state_.v[s.body] + pushV_[s.body] + (state_.w[s.body] + pushW_[s.body]).cross(s.r);
    s.separation += hs * (vb.dot(s.direction[0]) - s.speed[0]);
  }
}

double RigidWorld::relativeVelocity(const Constraint& c, int k) const {
  return c.direction(k).dot(state_.v[c.bodyB] - state_.v[c.bodyA]) + c.crossB[k].dot(state_.w[c.bodyB]) -
         c.crossA[k].dot(state_.w[c.bodyA]);
}

void RigidWorld::apply(const Constraint& c, int k, double lambda) {
  // Only dynamic bodies are written: a static or kinematic one (the floor under many
  // manifolds of one colour) is shared by parallel passes and must only be read.
  const Vec3& d = c.direction(k);
  if (c.inverseMassA > 0) {
    state_.v[c.bodyA] -= (c.inverseMassA * lambda) * d;
    state_.w[c.bodyA] -= lambda * c.angularA[k];
  }
  if (c.inverseMassB > 0) {
    state_.v[c.bodyB] += (c.inverseMassB * lambda) * d;
    state_.w[c.bodyB] += lambda * c.angularB[k];
  }
}

void RigidWorld::solveFriction(Constraint& c, double slip1, double slip2, double share) {
  const double limit = c.friction * c.normalImpulse;
  double l1 = c.tangentImpulse1 - share * c.tangentMass1 * slip1;
  double l2 = c.tangentImpulse2 - share * c.tangentMass2 * slip2;
  const double len = std::sqrt(l1 * l1 + l2 * l2);
  if (len > limit) {  // Coulomb's cone
    const double scale = len > 0 ? limit / len : 0;
    l1 *= scale;
    l2 *= scale;
  }
  apply(c, 1, l1 - c.tangentImpulse1);
  apply(c, 2, l2 - c.tangentImpulse2);
  c.tangentImpulse1 = l1;
  c.tangentImpulse2 = l2;
}

void RigidWorld::solveNormal(Constraint& c) {
  // A speculative point (s > 0) lets the gap close within the substep and no more.
  const double allowed = c.separation > 0 ? c.separation * invStep_ : 0.0;
  const double total = std::max(c.normalImpulse - c.normalMass * (relativeVelocity(c, 0) + allowed), 0.0);
  apply(c, 0, total - c.normalImpulse);
  c.normalImpulse = total;
  c.maxNormalImpulse = std::max(c.maxNormalImpulse, total);
}

void RigidWorld::solveVelocities(bool backward, const Executor& executor) {
  // Colour by colour (the order of the colours alternating between passes, so no manifold
  // is always solved first), each colour's manifolds in parallel.
  forEachBlockByColour(executor, backward, [&](Index b) { solveBlock(blocks_[static_cast<std::size_t>(b)]); });
}

void RigidWorld::solveBlock(const Block& block) {
  {
    Constraint* c = constraints_.data() + block.first;
    // Friction first, the normal last (non-penetration matters most).
    if (block.count == 1) {
      solveFriction(c[0], relativeVelocity(c[0], 1), relativeVelocity(c[0], 2), 1.0);
      solveNormal(c[0]);
      return;
    }
    // Friction symmetrically: each point's tangential impulse from the same velocities
    // (Jacobi within the manifold, each point taking its share), so no corner is served
    // first and a symmetric stack stays symmetric.
    {
      std::array<double, 8> slip;
      for (int p = 0; p < block.count; ++p) {
        slip[2 * p] = relativeVelocity(c[p], 1);
        slip[2 * p + 1] = relativeVelocity(c[p], 2);
      }
      const double share = 1.0 / block.count;
      for (int p = 0; p < block.count; ++p) solveFriction(c[p], slip[2 * p], slip[2 * p + 1], share);
    }
    // The manifold's normal impulses together (the block solver Box2D v2 uses for two
    // points, here for up to four): the increments that bring every point to its target
    // normal velocity at once, through the inverse of the points' coupling matrix K. A
    // point-by-point sweep would let the first point take the whole load and spin the
    // body; the block answer is symmetric. When it would pull (a total below zero), the
    // points are solved one by one instead.
    Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
    for (int p = 0; p < block.count; ++p) {
      const double allowed = c[p].separation > 0 ? c[p].separation * invStep_ : 0.0;
      rhs[p] = -(relativeVelocity(c[p], 0) + allowed);
    }
    const Eigen::Vector4d x = block.inverse * rhs;
    bool valid = true;
    for (int p = 0; p < block.count; ++p) valid = valid && c[p].normalImpulse + x[p] >= 0;
    if (!valid) {
      for (int p = 0; p < block.count; ++p) solveNormal(c[p]);
      return;
    }
    for (int p = 0; p < block.count; ++p) {
      c[p].normalImpulse += x[p];
      c[p].maxNormalImpulse = std::max(c[p].maxNormalImpulse, c[p].normalImpulse);
      apply(c[p], 0, x[p]);
    }
  }
}

void RigidWorld::solvePositions(double h, const Executor& executor) {
  // Split impulses (Catto; Bullet's splitImpulse): penetration is recovered through
  // velocities that move the positions of this step only and are then forgotten, so
  // pushing bodies apart never leaves energy in them (a stack does not hop or rock).
  const RigidModel& m = *model_;
  const Index n = m.bodyCount();
  for (Index b = 0; b < n; ++b) {
    pushV_[b].setZero();
    pushW_[b].setZero();
  }
  for (int it = 0; it < options_.positionIterations; ++it) {
    forEachBlockByColour(executor, it % 2 == 1, [&](Index blockIndex) {
      const Block& block = blocks_[static_cast<std::size_t>(blockIndex)];
      for (int p = 0; p < block.count; ++p) {
        Constraint& c = constraints_[static_cast<std::size_t>(block.first + p)];
        const double depth = -(c.separation + options_.linearSlop);
        if (depth <= 0) continue;
        const Index a = c.bodyA, b = c.bodyB;
        const Vec3 dv = pushV_[b] + pushW_[b].cross(c.rB) - pushV_[a] - pushW_[a].cross(c.rA);
        const double target = std::min(options_.penetrationRate * depth / h, options_.maxPushVelocity);
        const double lambda = -c.normalMass * (dv.dot(c.normal) - target);
        const double total = std::max(c.pushImpulse + lambda, 0.0);
        const Vec3 impulse = (total - c.pushImpulse) * c.normal;
        c.pushImpulse = total;
        if (c.inverseMassA > 0) {  // only dynamic bodies are written (see apply)
          pushV_[a] -= m.inverseMass[a] * impulse;
          pushW_[a] -= invInertiaWorld_[a] * c.rA.cross(impulse);
        }
        if (c.inverseMassB > 0) {
          pushV_[b] += m.inverseMass[b] * impulse;
          pushW_[b] += invInertiaWorld_[b] * c.rB.cross(impulse);
        }
      }
    });
    for (Support& s : supports_) {  // the held point does not move: the body alone is pushed
      const double depth = -(s.separation + options_.linearSlop);
      if (depth <= 0) continue;
      const Index b = s.body;
      const double dv = s.direction[0].dot(pushV_[b]) + s.cross[0].dot(pushW_[b]);
      const double target = std::min(options_.penetrationRate * depth / h, options_.maxPushVelocity);
      const double total = std::max(s.pushImpulse - s.mass[0] * (dv - target), 0.0);
      const double lambda = total - s.pushImpulse;
      s.pushImpulse = total;
      pushV_[b] += (m.inverseMass[b] * lambda) * s.direction[0];
      pushW_[b] += lambda * s.angular[0];
    }
  }
}

void RigidWorld::integratePositions(double h, bool last, const Executor& executor) {
  const RigidModel& m = *model_;
  executor.parallelFor(m.bodyCount(), 64, [&](Index begin, Index end) {
    for (Index b = begin; b < end; ++b) {
      switch (m.motion[b]) {
        case BodyMotion::Static:
          break;
        case BodyMotion::Kinematic:
          if (last) {  // exactly on the path at the end of the step
            state_.x[b] = targetX_[b];
            state_.q[b] = targetQ_[b];
          } else {
            state_.x[b] += h * state_.v[b];
            const double turn = h * state_.w[b].norm();
            if (turn > 0)
              state_.q[b] =
                  (Quat(Eigen::AngleAxisd(turn, state_.w[b] / state_.w[b].norm())) * state_.q[b]).normalized();
          }
          rotation_[b] = state_.q[b].toRotationMatrix();
          break;
        case BodyMotion::Dynamic: {
          state_.x[b] += h * (state_.v[b] + pushV_[b]);
          // Torque-free rotation with the world angular momentum fixed over the step, then
          // the split-impulse turn (positions only).
          const Vec3 L = rotation_[b] * m.inertia[b] * rotation_[b].transpose() * state_.w[b];
          state_.q[b] = integrateRotation(state_.q[b], L, m.inverseInertia[b], h);
          const double turn = h * pushW_[b].norm();
          if (turn > 0)
            state_.q[b] = (Quat(Eigen::AngleAxisd(turn, pushW_[b] / pushW_[b].norm())) * state_.q[b]).normalized();
          const Mat3 r = state_.q[b].toRotationMatrix();
          rotation_[b] = r;
          invInertiaWorld_[b] = r * m.inverseInertia[b] * r.transpose();
          state_.w[b] = invInertiaWorld_[b] * L;
          break;
        }
      }
    }
  });
}

void RigidWorld::buildSupports(double h) {
  // The held points of this step (SupportContact), as constraints on their body alone;
  // warm started from the last step's point with the same key.
  // The points and gaps are those at the step's start. A later chunk of a step taken in
  // chunks (chunked()) starts `elapsed` into it: its point is the same point of the body,
  // carried with the body since the step's start, and its gap is the step's less what the
  // body and the support closed of it since (the gap an earlier chunk let the body close
  // is not offered again).
  const RigidModel& m = *model_;
  supports_.clear();
  const double scale = lastSubstep_ > 0 ? h / lastSubstep_ : 1.0;
  const double elapsed = chunked() ? state_.time - stepBegin_.time : 0.0;
  auto last = lastSupports_.begin();
  for (const SupportContact& in : supportInput_) {
    Support s;
    s.body = in.body;
    s.key = in.key;
    double separation = in.separation;
    if (elapsed > 0) {
      const Vec3 r0 = in.point - stepBegin_.x[in.body];
      s.r = (state_.q[in.body] * stepBegin_.q[in.body].conjugate())._transformVector(r0);
      const Vec3 moved = state_.x[in.body] - stepBegin_.x[in.body] + s.r - r0;
      separation += in.normal.dot(moved - elapsed * in.velocity);
    } else {
      s.r = in.point - state_.x[in.body];
    }
    s.direction[0] = in.normal;
    tangents(in.normal, s.direction[1], s.direction[2]);
    const Mat3& ii = invInertiaWorld_[in.body];
    for (int k = 0; k < 3; ++k) {
      s.cross[k] = s.r.cross(s.direction[k]);
      s.angular[k] = ii * s.cross[k];
      const double sum = m.inverseMass[in.body] + s.cross[k].dot(s.angular[k]);
      s.mass[k] = sum > 0 ? 1 / sum : 0.0;
      s.speed[k] = s.direction[k].dot(in.velocity);
    }
    s.separation = s.previousSeparation = separation;
    last_.maxPenetration = std::max(last_.maxPenetration, -separation);
    const Vec3 u = state_.v[in.body] + state_.w[in.body].cross(s.r) - in.velocity;
    const Vec3 slip = u - u.dot(in.normal) * in.normal;
    s.friction = slip.norm() < options_.staticSpeed ? m.staticFriction[in.body] : m.kineticFriction[in.body];
    // Keys increase in both lists: one merge pass finds the matches.
    last = std::lower_bound(last, lastSupports_.end(), in.key,
                            [](const Support& o, std::uint64_t key) { return o.key < key; });
    if (last != lastSupports_.end() && last->key == in.key) {
      s.impulse[0] = scale * last->impulse[0];
      const Vec3 friction = scale * (last->impulse[1] * last->direction[1] + last->impulse[2] * last->direction[2]);
      s.impulse[1] = friction.dot(s.direction[1]);
      s.impulse[2] = friction.dot(s.direction[2]);
    }
    supports_.push_back(s);  // within the reserved capacity
  }
  last_.supportContacts = static_cast<std::int64_t>(supports_.size());
}

double RigidWorld::supportVelocity(const Support& s, int k) const {
  return s.direction[k].dot(state_.v[s.body]) + s.cross[k].dot(state_.w[s.body]) - s.speed[k];
}

void RigidWorld::applySupport(const Support& s, int k, double lambda) {
  state_.v[s.body] += (model_->inverseMass[s.body] * lambda) * s.direction[k];
  state_.w[s.body] += lambda * s.angular[k];
}

void RigidWorld::solveSupports(bool backward) {
  // Point by point (a support is one particle): friction within Coulomb's cone, then the
  // normal, which may close a positive gap within the substep and no more.
  const std::size_t count = supports_.size();
  for (std::size_t i = 0; i < count; ++i) {
    Support& s = supports_[backward ? count - 1 - i : i];
    const double limit = s.friction * s.impulse[0];
    double l1 = s.impulse[1] - s.mass[1] * supportVelocity(s, 1);
    double l2 = s.impulse[2] - s.mass[2] * supportVelocity(s, 2);
    const double len = std::sqrt(l1 * l1 + l2 * l2);
    if (len > limit) {
      const double shrink = len > 0 ? limit / len : 0;
      l1 *= shrink;
      l2 *= shrink;
    }
    applySupport(s, 1, l1 - s.impulse[1]);
    applySupport(s, 2, l2 - s.impulse[2]);
    s.impulse[1] = l1;
    s.impulse[2] = l2;
    const double allowed = s.separation > 0 ? s.separation * invStep_ : 0.0;
    const double total = std::max(s.impulse[0] - s.mass[0] * (supportVelocity(s, 0) + allowed), 0.0);
    applySupport(s, 0, total - s.impulse[0]);
    s.impulse[0] = total;
  }
}

void RigidWorld::applyRestitution() {
  const RigidModel& m = *model_;
  for (Constraint& c : constraints_) {
    if (c.restitution == 0 || c.approachVelocity > -options_.restitutionThreshold || c.maxNormalImpulse == 0) continue;
    const Index a = c.bodyA, b = c.bodyB;
    const Vec3 dv = state_.v[b] + state_.w[b].cross(c.rB) - state_.v[a] - state_.w[a].cross(c.rA);
    const double vn = dv.dot(c.normal);
    const double lambda = -c.normalMass * (vn + c.restitution * c.approachVelocity);
    const double total = std::max(c.normalImpulse + lambda, 0.0);
    const Vec3 impulse = (total - c.normalImpulse) * c.normal;
    c.normalImpulse = total;
    state_.v[a] -= m.inverseMass[a] * impulse;
    state_.w[a] -= invInertiaWorld_[a] * c.rA.cross(impulse);
    state_.v[b] += m.inverseMass[b] * impulse;
    state_.w[b] += invInertiaWorld_[b] * c.rB.cross(impulse);
  }
}

}  // namespace weft
