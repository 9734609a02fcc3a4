// ContactSolver's diagnostics for reports (serial, not in the step): contacts and
// penetration of a state, and particles that tunnelled over a run.
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "collide/contact_solver.hpp"
#include "contact_math.hpp"
#include "mesh_queries.hpp"
#include "weft/collide/collision_model.hpp"
#include "weft/collide/obstacles.hpp"

namespace weft {

using namespace detail;

template <class S>
std::int64_t ContactSolver<S>::countContacts(const Vec3Array<S>& x, const ScalarArray<S>& w, double t) const {
  std::int64_t count = 0;
  for (Index i = 0; i < static_cast<Index>(x.rows()); ++i)
    if (w[i] != S(0) && pointPenetration(options_, model_->meshes(), row(x, i), t) > -options_.epsilon) ++count;
  return count;
}

template <class S>
double ContactSolver<S>::penetration(const Vec3Array<S>& x, const ScalarArray<S>& w, double t) const {
  double deepest = 0;
  for (Index i = 0; i < static_cast<Index>(x.rows()); ++i)
    if (w[i] != S(0)) deepest = std::max(deepest, pointPenetration(options_, model_->meshes(), row(x, i), t));
  return deepest;
}

template <class S>
std::int64_t ContactSolver<S>::countTunnelled(const Vec3Array<S>& start, const Vec3Array<S>& end,
                                              const ScalarArray<S>& w, double t0, double t1) const {
  std::int64_t count = 0;
  for (Index i = 0; i < static_cast<Index>(end.rows()); ++i) {
    if (w[i] == S(0)) continue;
    const V a = row(start, i), b = row(end, i);
    bool tunnelled = false;
    for (const Obstacle& o : options_.obstacles) {
      V nn;
      if (distance(o, b, nn) < 0 && distance(o, a, nn) >= 0) tunnelled = true;  // ended inside, started outside
      if (o.kind != ObstacleKind::Box) continue;
      // Thinnest axis of the box: opposite sides along it, within the other two extents.
      const double ex[3] = {o.halfExtents.x, o.halfExtents.y, o.halfExtents.z};
      const int axis = ex[0] <= ex[1] && ex[0] <= ex[2] ? 0 : (ex[1] <= ex[2] ? 1 : 2);
      const double ca[3] = {a.x - o.point.x, a.y - o.point.y, a.z - o.point.z};
      const double cb[3] = {b.x - o.point.x, b.y - o.point.y, b.z - o.point.z};
      bool within = true;
      for (int k = 0; k < 3; ++k)
        if (k != axis) within = within && std::abs(cb[k]) <= ex[k] && std::abs(ca[k]) <= ex[k];
      if (within && ((ca[axis] < -ex[axis] && cb[axis] > ex[axis]) || (ca[axis] > ex[axis] && cb[axis] < -ex[axis])))
        tunnelled = true;
    }
    for (size_t m = 0; m < model_->meshes().size() && !tunnelled; ++m) {
      const MeshObstacle& mo = options_.meshes[m];
      const V bb = toBody(mo, b, t1);
      if (model_->meshes()[m].closed)  // ended inside, started outside
        tunnelled = windingNumber(model_->meshes()[m], bb) > 0.5 &&
                    windingNumber(model_->meshes()[m], toBody(mo, a, t0)) <= 0.5;
      else  // the straight path from start to end goes through the sheet
        tunnelled = meshImpact(model_->meshes()[m], toBody(mo, a, t0), bb, 0.0, 1e-9 * options_.thickness) < 1 &&
                    meshDistance(model_->meshes()[m], bb, options_.thickness) > 0.5 * options_.thickness &&
                    meshDistance(model_->meshes()[m], toBody(mo, a, t0), options_.thickness) > 0.5 * options_.thickness;
    }
    count += tunnelled ? 1 : 0;
  }
  return count;
}

#define WEFT_INSTANTIATE(S)                                                                                        \
  template std::int64_t ContactSolver<S>::countContacts(const Vec3Array<S>&, const ScalarArray<S>&, double) const; \
  template double ContactSolver<S>::penetration(const Vec3Array<S>&, const ScalarArray<S>&, double) const;         \
  template std::int64_t ContactSolver<S>::countTunnelled(const Vec3Array<S>&, const Vec3Array<S>&,                 \
                                                         const ScalarArray<S>&, double, double) const;
WEFT_INSTANTIATE(float)
WEFT_INSTANTIATE(double)
#undef WEFT_INSTANTIATE

}  // namespace weft
