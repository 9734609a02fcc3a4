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
using bvh_detail::text;
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
    throw std::invalid_argument(w + ".thickness must be finite and > 0 (m), got " + text(o.thickness));
  if (!(std::isfinite(o.friction) && o.friction >= 0))
    throw std::invalid_argument(w + ".friction must be finite and >= 0, got " + text(o.friction));
  if (o.iterations < 1 || o.iterations > 64)
    throw std::invalid_argument(w + ".iterations must be in [1, 64], got " + std::to_string(o.iterations));
}

template <class S>
void validateSelfCollision(const SelfCollisionOptions& o, const Model<S>& model, const Vec3Array<S>& x,
                           const char* where) {
  validateSelfCollision(o, where);
  const Triangles& tr = model.triangles();
  double smallest = std::numeric_limits<double>::infinity();
  Index which = -1;
  for (Index t = 0; t < model.triangleCount(); ++t) {
    const Index c[3] = {tr.a[t], tr.b[t], tr.c[t]};
    V p[3];
    for (int k = 0; k < 3; ++k)
      p[k] = V(static_cast<double>(x(c[k], 0)), static_cast<double>(x(c[k], 1)), static_cast<double>(x(c[k], 2)));
    const double longest =
        std::sqrt(std::max({(p[1] - p[0]).squaredNorm(), (p[2] - p[1]).squaredNorm(), (p[0] - p[2]).squaredNorm()}));
    const double altitude = longest > 0 ? (p[1] - p[0]).cross(p[2] - p[0]).norm() / longest : 0.0;
    if (!(altitude >= smallest)) {  // (a NaN altitude is the smallest: the check refuses it)
      smallest = altitude;
      which = t;
    }
  }
  if (which >= 0 && !(o.thickness < smallest))
    throw std::invalid_argument(
        std::string(where) + ".thickness = " + text(o.thickness) +
        " m must be below the smallest altitude of the cloth's triangles in the initial state, " + text(smallest) +
        " m (triangle " + std::to_string(which) + ", particles " + std::to_string(tr.a[which]) + ", " +
        std::to_string(tr.b[which]) + ", " + std::to_string(tr.c[which]) +
        "): a thicker layer puts neighbouring triangles in contact at rest; keep it below about half of that");
}

template void validateSelfCollision(const SelfCollisionOptions&, const Model<float>&, const Vec3Array<float>&,
                                    const char*);
template void validateSelfCollision(const SelfCollisionOptions&, const Model<double>&, const Vec3Array<double>&,
                                    const char*);

}  // namespace weft
