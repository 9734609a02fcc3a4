// The self-collision options' validation and the pass's statistics (see
// weft/collide/self_collision.hpp).
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "bvh_internal.hpp"
#include "weft/collide/self_collision.hpp"

namespace weft {

namespace {
using V = Vec3<double>;

}  // namespace

SelfCollisionStats& SelfCollisionStats::operator+=(const SelfCollisionStats& o) {
  passes += o.passes;
  rebuilds += o.rebuilds;
  candidates += o.candidates;
  tests += o.tests;
  contacts += o.contacts;
  vertexTriangle += o.vertexTriangle;
  failsafeChunks += o.failsafeChunks;
  frozen += o.frozen;
  unresolved += o.unresolved;
  return *this;
}

void validateSelfCollision(const SelfCollisionOptions& o, const char* where) {
  const std::string w = where;
  if (!(std::isfinite(o.thickness) && o.thickness > 0))
    throw std::invalid_argument(w + ".thickness must be finite and > 0 (m), got " + detail::number(o.thickness));
  if (!(std::isfinite(o.friction) && o.friction >= 0))
    throw std::invalid_argument(w + ".friction must be finite and >= 0, got " + detail::number(o.friction));
  if (o.iterations < 1 || o.iterations > 64)
    throw std::invalid_argument(w + ".iterations must be in [1, 64], got " + std::to_string(o.iterations));
  if (o.maxCandidatesPerTriangle < 1 || o.maxCandidatesPerTriangle > (1 << 20))
    throw std::invalid_argument(w + ".maxCandidatesPerTriangle must be in [1, 1048576], got " +
                                std::to_string(o.maxCandidatesPerTriangle));
  for (size_t i = 0; i < o.particleThickness.size(); ++i)
    if (!(std::isfinite(o.particleThickness[i]) && o.particleThickness[i] > 0))
      throw std::invalid_argument(w + ".particleThickness[" + std::to_string(i) + "] must be finite and > 0 (m), got " +
                                  detail::number(o.particleThickness[i]));
}

template <class S>
void validateSelfCollision(const SelfCollisionOptions& o, const Model<S>& model, const Vec3Array<S>& x,
                           const char* where, const std::function<std::string(Index particle)>& thicknessField) {
  validateSelfCollision(o, where);
  const bool perParticle = !o.particleThickness.empty();
  if (perParticle && static_cast<Index>(o.particleThickness.size()) != model.particleCount())
    throw std::invalid_argument(std::string(where) + ".particleThickness holds " +
                                std::to_string(o.particleThickness.size()) + " values for " +
                                std::to_string(model.particleCount()) + " particles");
  const Triangles& tr = model.triangles();
  // The triangle whose altitude leaves the least room for its thickness (the smallest
  // altitude when the thickness is one).
  double worst = std::numeric_limits<double>::infinity(), worstAltitude = 0, worstThickness = 0;
  Index which = -1, thickest = -1;
  for (Index t = 0; t < model.triangleCount(); ++t) {
    const Index c[3] = {tr.a[t], tr.b[t], tr.c[t]};
    V p[3];
    for (int k = 0; k < 3; ++k)
      p[k] = V(static_cast<double>(x(c[k], 0)), static_cast<double>(x(c[k], 1)), static_cast<double>(x(c[k], 2)));
    const double longest =
        std::sqrt(std::max({(p[1] - p[0]).squaredNorm(), (p[2] - p[1]).squaredNorm(), (p[0] - p[2]).squaredNorm()}));
    const double altitude = longest > 0 ? (p[1] - p[0]).cross(p[2] - p[0]).norm() / longest : 0.0;
    double thickness = o.thickness;
    Index from = c[0];
    if (perParticle) {
      thickness = 0;
      for (const Index i : c)
        if (o.particleThickness[static_cast<size_t>(i)] > thickness) {
          thickness = o.particleThickness[static_cast<size_t>(i)];
          from = i;
        }
    }
    const double room = altitude / thickness;
    if (!(room >= worst)) {  // (a NaN altitude leaves the least room: the check refuses it)
      worst = room;
      worstAltitude = altitude;
      worstThickness = thickness;
      which = t;
      thickest = from;
    }
  }
  if (which < 0 || worst > 1) return;
  const std::string field = !perParticle ? std::string(where) + ".thickness"
                            : thicknessField
                                ? thicknessField(thickest)
                                : std::string(where) + ".particleThickness[" + std::to_string(thickest) + "]";
  throw std::invalid_argument(
      field + " = " + detail::number(worstThickness) + " m must be below the " +
      (perParticle ? "altitude of its cloth's triangles" : "smallest altitude of the cloth's triangles") +
      " in the initial state, " + detail::number(worstAltitude) + " m (triangle " + std::to_string(which) +
      ", particles " + std::to_string(tr.a[which]) + ", " + std::to_string(tr.b[which]) + ", " +
      std::to_string(tr.c[which]) +
      "): a thicker layer puts neighbouring triangles in contact at rest; keep it below about half of that");
}

template void validateSelfCollision(const SelfCollisionOptions&, const Model<float>&, const Vec3Array<float>&,
                                    const char*, const std::function<std::string(Index)>&);
template void validateSelfCollision(const SelfCollisionOptions&, const Model<double>&, const Vec3Array<double>&,
                                    const char*, const std::function<std::string(Index)>&);

}  // namespace weft
