// The rigid bodies' model: validation, mass properties of compounds, the initial state.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/text.hpp"
#include "rigid_rules.hpp"
#include "weft/rigid/rigid_world.hpp"

namespace weft {

namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

std::string text(double v) { return detail::number(v); }
std::string text(const Vec3& v) { return detail::number3(v); }

// The rigid options' checks, in the kernel's one message form (core/text.hpp).
void require(bool ok, const std::string& field, const std::string& rule, const std::string& got) {
  if (!ok) detail::rejectField(field, got, rule);
}

/// Inertia of a piece (about its own centre) moved to a point at offset d (parallel axes).
Mat3 shiftInertia(const Mat3& inertiaAboutCentre, double mass, const Vec3& d) {
  return inertiaAboutCentre + mass * (d.squaredNorm() * Mat3::Identity() - d * d.transpose());
}

}  // namespace

const char* bodyMotionName(BodyMotion motion) {
  switch (motion) {
    case BodyMotion::Static:
      return "static";
    case BodyMotion::Kinematic:
      return "kinematic";
    case BodyMotion::Dynamic:
      return "dynamic";
  }
  return "unknown";
}

void RigidStats::add(const RigidStats& s) {
  candidatePairs += s.candidatePairs;
  touchingPairs += s.touchingPairs;
  contacts += s.contacts;
  warmStarted += s.warmStarted;
  witnessHits += s.witnessHits;
  narrowQueries += s.narrowQueries;
  supportContacts += s.supportContacts;
  chunks += s.chunks;
  rollbacks += s.rollbacks;
  halvingLimitHits += s.halvingLimitHits;
  redoneSteps += s.redoneSteps;
  maxPenetration = std::max(maxPenetration, s.maxPenetration);
  if (s.deepestShare > deepestShare) {
    deepestShare = s.deepestShare;
    deepestDepth = s.deepestDepth;
    deepestA = s.deepestA;
    deepestB = s.deepestB;
    deepestTime = s.deepestTime;
  }
}

const char* rigidTimeOfImpactName(RigidTimeOfImpact mode) {
  switch (mode) {
    case RigidTimeOfImpact::Speculative:
      return "speculative";
    case RigidTimeOfImpact::Rollback:
      return "rollback";
  }
  return "unknown";
}

void validateRigidOptions(const RigidOptions& o) {
  const std::string r = "rigid.";
  require(o.substeps >= 1 && o.substeps <= 1024, r + "substeps", "in [1, 1024]", std::to_string(o.substeps));
  require(o.velocityIterations >= 1 && o.velocityIterations <= 1000, r + "velocityIterations", "in [1, 1000]",
          std::to_string(o.velocityIterations));
  require(o.positionIterations >= 0 && o.positionIterations <= 1000, r + "positionIterations", "in [0, 1000]",
          std::to_string(o.positionIterations));
  require(std::isfinite(o.speculativeDistance) && o.speculativeDistance >= 0, r + "speculativeDistance",
          "finite and >= 0 (m)", text(o.speculativeDistance));
  require(std::isfinite(o.linearSlop) && o.linearSlop >= 0, r + "linearSlop", "finite and >= 0 (m)",
          text(o.linearSlop));
  require(o.penetrationRate > 0 && o.penetrationRate <= 1, r + "penetrationRate", "in (0, 1]", text(o.penetrationRate));
  require(std::isfinite(o.maxPushVelocity) && o.maxPushVelocity > 0, r + "maxPushVelocity", "finite and > 0 (m/s)",
          text(o.maxPushVelocity));
  require(std::isfinite(o.restitutionThreshold) && o.restitutionThreshold >= 0, r + "restitutionThreshold",
          "finite and >= 0 (m/s)", text(o.restitutionThreshold));
  require(std::isfinite(o.staticSpeed) && o.staticSpeed >= 0, r + "staticSpeed", "finite and >= 0 (m/s)",
          text(o.staticSpeed));
  require(std::isfinite(o.particleThickness) && o.particleThickness > 0, r + "particleThickness", "finite and > 0 (m)",
          text(o.particleThickness));
  require(o.maxPairs >= 0 && o.maxPairs <= kMaxRigidPairs, r + "maxPairs", "in [0, 2^28] (0 = automatic)",
          std::to_string(o.maxPairs));
  require(std::isfinite(o.rollbackPenetration) && o.rollbackPenetration > 0, r + "rollbackPenetration",
          "finite and > 0 (m)", text(o.rollbackPenetration));
  require(o.maxHalvings >= 0 && o.maxHalvings <= 30, r + "maxHalvings", "in [0, 30]", std::to_string(o.maxHalvings));
  require(o.timeOfImpact == RigidTimeOfImpact::Speculative || o.timeOfImpact == RigidTimeOfImpact::Rollback,
          r + "timeOfImpact", "speculative or rollback", std::to_string(static_cast<int>(o.timeOfImpact)));
  // Rollback cuts the step at the time of impact along each pair's motion: it is continuous
  // detection, so `continuous = false` would be overruled without a word.
  require(o.continuous || o.timeOfImpact != RigidTimeOfImpact::Rollback, r + "continuous",
          "true when rollback finds the time of impact (it finds each pair's along its motion)", "false");
  require(o.narrowPhase.ofgFaces >= 1 && o.narrowPhase.ofgFaces <= kMaxOfgFaces, r + "narrowPhase.ofgFaces",
          "in [1, " + std::to_string(kMaxOfgFaces) + "]", std::to_string(o.narrowPhase.ofgFaces));
  for (std::size_t b = 0; b < o.bodies.size(); ++b) {
    const RigidBodyDesc& d = o.bodies[b];
    const std::string f = r + "bodies[" + std::to_string(b) + "].";
    require(!d.shapes.empty(), f + "shapes", "a list of at least one convex piece", "none");
    require(std::isfinite(d.density) && d.density > 0, f + "density", "finite and > 0 (kg/m^3)", text(d.density));
    require(std::isfinite(d.mass) && d.mass >= 0, f + "mass", "finite and >= 0 (kg; 0 = from the density)",
            text(d.mass));
    require(finite(d.position) && d.position.cwiseAbs().maxCoeff() <= kFarthestBody, f + "position",
            "finite and " + detail::farthestBodyRule(), text(d.position));
    require(std::isfinite(d.orientation.norm()) && d.orientation.norm() > 1e-12, f + "orientation",
            "a finite non-zero quaternion", text(d.orientation.norm()));
    require(detail::speedWithinLimit(d.velocity.x(), d.velocity.y(), d.velocity.z()), f + "velocity",
            detail::speedRule(), text(d.velocity));
    require(finite(d.angularVelocity), f + "angularVelocity", "finite (rad/s)", text(d.angularVelocity));
    require(std::isfinite(d.staticFriction) && d.staticFriction >= 0, f + "staticFriction", "finite and >= 0",
            text(d.staticFriction));
    require(d.kineticFriction >= 0 && d.kineticFriction <= d.staticFriction, f + "kineticFriction",
            "in [0, staticFriction (" + text(d.staticFriction) + ")]", text(d.kineticFriction));
    require(d.restitution >= 0 && d.restitution <= 1, f + "restitution", "in [0, 1]", text(d.restitution));
    if (d.motion == BodyMotion::Kinematic) validateKinematicPath(d.path, f + "path.");
    // A static body does not move and a kinematic one moves by its path only: a velocity or
    // a mass given to either would be dropped without a word, so it is refused.
    if (d.motion != BodyMotion::Dynamic) {
      const std::string zero =
          std::string("zero for a ") +
          (d.motion == BodyMotion::Static ? "static body (it does not move)" : "kinematic body (it moves by its path)");
      require(d.velocity.isZero(0), f + "velocity", zero, text(d.velocity));
      require(d.angularVelocity.isZero(0), f + "angularVelocity", zero, text(d.angularVelocity));
      require(d.mass == 0, f + "mass", zero + "; only dynamic bodies have a mass", text(d.mass));
    }
    for (std::size_t s = 0; s < d.shapes.size(); ++s) {
      const RigidShapeDesc& sh = d.shapes[s];
      const std::string g = f + "shapes[" + std::to_string(s) + "].";
      require(finite(sh.offset), g + "offset", "finite (m)", text(sh.offset));
      require(std::isfinite(sh.rotation.norm()) && sh.rotation.norm() > 1e-12, g + "rotation",
              "a finite non-zero quaternion", text(sh.rotation.norm()));
      switch (sh.kind) {
        case RigidShapeDesc::Kind::Sphere:
          require(std::isfinite(sh.radius) && sh.radius > 0, g + "radius", "finite and > 0 (m)", text(sh.radius));
          break;
        case RigidShapeDesc::Kind::Box:
          for (int k = 0; k < 3; ++k) {
            const char* axis[] = {"x", "y", "z"};
            require(std::isfinite(sh.halfExtents[k]) && sh.halfExtents[k] > 0, g + "halfExtents." + axis[k],
                    "finite and > 0 (m)", text(sh.halfExtents[k]));
          }
          break;
        case RigidShapeDesc::Kind::Hull:
          require(sh.points.size() >= 4, g + "points", "at least 4 points", std::to_string(sh.points.size()));
          for (std::size_t i = 0; i < sh.points.size(); ++i)
            require(finite(sh.points[i]), g + "points[" + std::to_string(i) + "]", "finite (m)", text(sh.points[i]));
          break;
      }
    }
  }
}

std::shared_ptr<const RigidModel> buildRigidModel(const std::vector<RigidBodyDesc>& bodies) {
  RigidOptions check;
  check.bodies = bodies;
  validateRigidOptions(check);
  auto model = std::make_shared<RigidModel>();
  RigidModel& m = *model;
  const std::size_t n = bodies.size();
  m.names.reserve(n);
  m.firstPiece.push_back(0);
  for (std::size_t b = 0; b < n; ++b) {
    const RigidBodyDesc& d = bodies[b];
    const std::string f = "rigid.bodies[" + std::to_string(b) + "].";
    double mass = 0;
    Vec3 moment = Vec3::Zero();
    struct PieceMass {
      double mass;
      Vec3 centre;
      Mat3 inertia;  // about its centre, body axes
    };
    std::vector<PieceMass> parts;
    const Index first = static_cast<Index>(m.pieces.size());
    for (std::size_t s = 0; s < d.shapes.size(); ++s) {
      const RigidShapeDesc& sh = d.shapes[s];
      const Mat3 rot = sh.rotation.normalized().toRotationMatrix();
      RigidPiece piece;
      piece.body = static_cast<Index>(b);
      piece.rotation = rot;
      piece.offset = sh.offset;  // shifted to the centre of mass below
      MassProperties mp;
      if (sh.kind == RigidShapeDesc::Kind::Sphere) {
        piece.kind = RigidShapeDesc::Kind::Sphere;
        piece.radius = sh.radius;
        piece.boundingRadius = sh.radius;
        piece.innerRadius = sh.radius;
        piece.localMin = Vec3::Constant(-sh.radius);
        piece.localMax = Vec3::Constant(sh.radius);
        mp = sphereMassProperties(sh.radius, d.density);
      } else {
        ConvexHull hull;
        try {
          hull = sh.kind == RigidShapeDesc::Kind::Box ? makeBoxHull(sh.halfExtents) : makeConvexHull(sh.points);
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument(f + "shapes[" + std::to_string(s) + "]: " + e.what());
        }
        piece.kind = RigidShapeDesc::Kind::Hull;
        piece.hull = static_cast<Index>(m.hulls.size());
        piece.boundingRadius = hull.boundingRadius;
        piece.innerRadius = hull.boundingRadius;
        for (const ConvexFace& face : hull.faces)
          piece.innerRadius = std::min(piece.innerRadius, face.offset - face.normal.dot(hull.centroid));
        piece.localMin = piece.localMax = hull.vertices[0];
        for (const Vec3& p : hull.vertices) {
          piece.localMin = piece.localMin.cwiseMin(p);
          piece.localMax = piece.localMax.cwiseMax(p);
        }
        mp = sh.kind == RigidShapeDesc::Kind::Box ? boxMassProperties(sh.halfExtents, d.density)
                                                  : hullMassProperties(hull, d.density);
        piece.centre = rot * hull.centroid;  // relative to the piece origin for now
        m.hulls.push_back(std::move(hull));
      }
      const Vec3 c = sh.offset + rot * mp.centre;
      parts.push_back({mp.mass, c, rot * mp.inertia * rot.transpose()});
      mass += mp.mass;
      moment += mp.mass * c;
      m.pieces.push_back(piece);
    }
    const Vec3 com = moment / mass;
    Mat3 inertia = Mat3::Zero();
    for (const PieceMass& p : parts) inertia += shiftInertia(p.inertia, p.mass, p.centre - com);
    if (d.mass > 0) {
      inertia *= d.mass / mass;
      mass = d.mass;
    }
    for (Index k = first; k < static_cast<Index>(m.pieces.size()); ++k) {
      RigidPiece& piece = m.pieces[k];
      piece.offset -= com;
      piece.centre += piece.offset;
    }
    double reach = 0;
    for (Index k = first; k < static_cast<Index>(m.pieces.size()); ++k)
      reach = std::max(reach, m.pieces[k].centre.norm() + m.pieces[k].boundingRadius);
    const bool finiteMass = std::isfinite(mass) && mass > 0 && inertia.allFinite() && inertia.trace() > 0;
    if (!finiteMass)
      throw std::invalid_argument(f + "mass: the body's mass or inertia is not a finite positive number (" +
                                  text(mass) + " kg): its size or density is out of range");
    // The solver divides by a moving body's mass and inertia and multiplies them by speeds
    // squared: a body far outside what any scene holds (a grain of dust to a ship)
    // overflows there. (Static and kinematic bodies' masses are not used.)
    if (d.motion == BodyMotion::Dynamic) {
      require(mass >= kMinBodyMass && mass <= kMaxBodyMass, f + "mass",
              "in [1e-15, 1e15] kg for a dynamic body (given, or density x volume)", text(mass));
      require(Mat3(inertia.inverse()).allFinite(), f + "shapes", "a body whose inertia can be inverted (not too thin)",
              "inertia diagonal " + text(Vec3(inertia.diagonal())));
      // The spin, by the speed of the body's farthest point (so that 1/2 w.I w, bounded by
      // 1/2 m (|w| reach)^2, stays finite as the linear part does).
      require(detail::spinWithinLimit(d.angularVelocity, reach), f + "angularVelocity", detail::spinRule(reach),
              text(d.angularVelocity));
    }
    if (d.motion == BodyMotion::Kinematic) {
      // Its path turns every point of it about the path's centre: the farthest point (at
      // most the body's position's distance, plus its centre of mass's offset, plus its
      // reach) at most at the speed of light.
      const Vec3d& c = d.path.center;
      const double farthest =
          std::hypot(d.position.x() - c.x, d.position.y() - c.y, d.position.z() - c.z) + com.norm() + reach;
      validateKinematicSpin(d.path, farthest, f + "path.", "the body's farthest point");
    }
    m.names.push_back(d.name.empty() ? "body" + std::to_string(b) : d.name);
    m.motion.push_back(d.motion);
    m.mass.push_back(mass);
    m.inertia.push_back(inertia);
    const bool dynamic = d.motion == BodyMotion::Dynamic;
    m.inverseMass.push_back(dynamic ? 1 / mass : 0);
    m.inverseInertia.push_back(dynamic ? Mat3(inertia.inverse()) : Mat3::Zero());
    m.centreOfMass.push_back(com);
    m.reach.push_back(reach);
    m.staticFriction.push_back(d.staticFriction);
    m.kineticFriction.push_back(d.kineticFriction);
    m.restitution.push_back(d.restitution);
    m.paths.push_back(d.path);
    m.firstPiece.push_back(static_cast<Index>(m.pieces.size()));
  }
  return model;
}

std::uint64_t rigidStateHash(const RigidState& s) {
  std::uint64_t h = 1469598103934665603ull;
  const auto mix = [&](const double* p, int n) {
    for (int i = 0; i < n; ++i) {
      std::uint64_t bits;
      std::memcpy(&bits, p + i, sizeof bits);
      for (int k = 0; k < 8; ++k) h = (h ^ ((bits >> (8 * k)) & 0xff)) * 1099511628211ull;
    }
  };
  for (std::size_t b = 0; b < s.x.size(); ++b) {
    mix(s.x[b].data(), 3);
    mix(s.q[b].coeffs().data(), 4);
    mix(s.v[b].data(), 3);
    mix(s.w[b].data(), 3);
  }
  return h;
}

RigidState initialRigidState(const RigidModel& model, const std::vector<RigidBodyDesc>& bodies) {
  if (static_cast<Index>(bodies.size()) != model.bodyCount())
    throw std::invalid_argument("initialRigidState: " + std::to_string(bodies.size()) + " bodies for a model of " +
                                std::to_string(model.bodyCount()));
  RigidState s;
  const std::size_t n = bodies.size();
  s.x.resize(n);
  s.q.resize(n);
  s.v.resize(n);
  s.w.resize(n);
  for (std::size_t b = 0; b < n; ++b) {
    const RigidBodyDesc& d = bodies[b];
    s.q[b] = d.orientation.normalized();
    s.x[b] = d.position + s.q[b].toRotationMatrix() * model.centreOfMass[b];
    const bool moves = d.motion == BodyMotion::Dynamic;
    s.v[b] = moves ? d.velocity : Vec3::Zero();
    s.w[b] = moves ? d.angularVelocity : Vec3::Zero();
  }
  return s;
}

}  // namespace weft
