// ContactSolver: the particle and edge contact passes of a chunk (detection in parallel,
// response per particle, the edge response serially in edge order), the clearance bound
// that lets particles far from a mesh skip it, and the rollback's deepest penetration.
#include "collide/contact_solver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

#include "contact_math.hpp"
#include "contact_response.hpp"
#include "mesh_queries.hpp"
#include "weft/collide/collision_model.hpp"
#include "weft/collide/obstacles.hpp"

namespace weft {

using namespace detail;

template <class S>
ContactSolver<S>::ContactSolver(const CollisionOptions& options, Index particleCount, std::vector<Edge> edges,
                                std::shared_ptr<const CollisionModel> model)
    : options_(options) {
  validateCollision(options_);
  for (size_t k = 0; k < edges.size(); ++k)
    for (const Index i : edges[k])
      if (i < 0 || i >= particleCount)
        throw std::invalid_argument("ContactSolver: edges[" + std::to_string(k) + "] has particle " +
                                    std::to_string(i) + ", not in [0, " + std::to_string(particleCount) + ")");
  if (model && !model->matches(options_))
    throw std::invalid_argument(
        "ContactSolver: the collision model was built from other mesh obstacles (or another featureAngle) than "
        "these CollisionOptions (" +
        std::to_string(options_.meshes.size()) + " meshes)");
  if (options_.continuous && options_.edges && !options_.meshes.empty()) {
    edges_ = std::move(edges);
    edgeHits_.resize(edges_.size());
  }
  if (options_.maxPenetration == 0) options_.maxPenetration = 0.5 * options_.thickness;
  const Index blocks = Executor::blockCount(particleCount, kGrain);
  blockDepth_.assign(static_cast<size_t>(blocks), 0.0);
  blockHits_.assign(static_cast<size_t>(blocks), 0);
  blockCcd_.assign(static_cast<size_t>(blocks), 0);
  // The mesh obstacles prepared once: given, or built here for this solver alone.
  model_ = model ? std::move(model) : std::make_shared<const CollisionModel>(options_);
  if (options_.meshes.empty()) return;
  // No clearance known yet: -infinity, so that every particle is tested first.
  clearance_.assign(options_.meshes.size() * static_cast<size_t>(particleCount) * 4,
                    -std::numeric_limits<double>::infinity());
  // The edge pass needs a mesh with feature edges.
  const std::vector<MeshCollider>& meshes = model_->meshes();
  if (std::none_of(meshes.begin(), meshes.end(), [](const MeshCollider& c) { return !c.featureEdges.empty(); })) {
    edges_.clear();
    edgeHits_.clear();
  }
}

namespace {

// The clearance record of particle i against mesh m (see ContactSolver::clearance_).
inline double* clearanceOf(std::vector<double>& clearance, size_t m, Index i, Index n) {
  return clearance.data() + 4 * (m * static_cast<size_t>(n) + static_cast<size_t>(i));
}
// The lower bound on the distance to the mesh of every point within `reach` of p.
inline double clearanceBound(const double* c, V p, double reach) {
  return c[3] - norm(p - V{c[0], c[1], c[2]}) - reach;
}

}  // namespace

template <class S>
double ContactSolver<S>::deepestPenetration(const Vec3Array<S>& x1, const ScalarArray<S>& w, double t1,
                                            const Executor& exec) {
  const Index n = static_cast<Index>(x1.rows());
  const double h = options_.thickness, eps = options_.epsilon;
  exec.parallelForBlocks(n, kGrain, [&](Index block, Index b, Index e) {
    double deepest = 0;
    for (Index i = b; i < e; ++i) {
      if (w[i] == S(0)) continue;
      const V p = row(x1, i);
      for (const Obstacle& o : options_.obstacles) {
        V nn;
        deepest = std::max(deepest, h - distance(o, p, nn));
      }
      for (size_t m = 0; m < model_->meshes().size(); ++m) {
        const V bp = toBody(options_.meshes[m], p, t1);
        if (clearanceBound(clearanceOf(clearance_, m, i, n), bp, 0) > h + 2 * eps) continue;  // farther than h
        deepest = std::max(deepest, h - meshDistance(model_->meshes()[m], bp, h + eps));
      }
    }
    blockDepth_[block] = deepest;
  });
  double deepest = 0;
  for (Index k = 0; k < Executor::blockCount(n, kGrain); ++k) deepest = std::max(deepest, blockDepth_[k]);
  return deepest;
}

template <class S>
CollisionStats ContactSolver<S>::resolve(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1,
                                         const ScalarArray<S>& w, double t0, double t1, const Executor& exec) {
  const Index n = static_cast<Index>(x1.rows());
  const double h = options_.thickness, eps = options_.epsilon;
  exec.parallelForBlocks(n, kGrain, [&](Index block, Index b, Index e) {
    std::int64_t hits = 0, ccd = 0;
    double deepest = 0;
    for (Index i = b; i < e; ++i) {
      if (w[i] == S(0)) continue;
      const V p0 = row(x0, i), p1 = row(x1, i);
      Contact c = detect(options_, p0, p1);
      // Mesh obstacles: the first impact along the segment in each mesh's frame; without
      // continuous detection only when x1 itself is within the thickness.
      for (size_t m = 0; m < model_->meshes().size(); ++m) {
        const MeshObstacle& mo = options_.meshes[m];
        const V b0 = toBody(mo, p0, t0), b1 = toBody(mo, p1, t1);
        double* clear = clearanceOf(clearance_, m, i, n);
        const double length = norm(b1 - b0);
        // The whole chunk farther than the thickness from the mesh (every point of it is
        // within `length` of b1): nothing to find, as the queries below would confirm.
        if (clearanceBound(clear, b1, length) > h + 2 * eps) continue;
        // The distance at b1, looked up a little farther than needed (8 thicknesses) so
        // that it tells the next chunks to skip too.
        const double reach = 9 * h + eps + length;
        const double d1 = meshDistance(model_->meshes()[m], b1, reach);
        clear[0] = b1.x;
        clear[1] = b1.y;
        clear[2] = b1.z;
        clear[3] = std::min(d1, reach);
        const double depth = h - d1;
        if (depth <= 0 && !options_.continuous) continue;
        if (depth <= 0 && d1 - length > h + 2 * eps) continue;  // the segment stays clear
        const double s = meshImpact(model_->meshes()[m], b0, b1, h, eps);
        if (s >= 1 && depth <= 0) continue;
        const double at = std::min(s, 1.0);
        if (!c.found || at < c.s || (at == c.s && depth > c.depth)) {
          c.found = true;
          c.continuous = depth <= 0;
          c.s = at < 1 ? at : 0;  // within the thickness at x1 only (a slow approach inside): push out from x1
          c.depth = std::max(depth, 0.0);
          c.obstacle = nullptr;
          c.mesh = static_cast<Index>(m);
        }
      }
      if (!c.found) continue;
      ++hits;
      ccd += c.continuous ? 1 : 0;
      deepest = std::max(deepest, c.depth);
      V vel = row(v1, i);
      const V p = c.obstacle ? respondAnalytic(options_, c, p0, p1, vel)
                             : respondMesh(options_, options_.meshes[static_cast<size_t>(c.mesh)],
                                           model_->meshes()[static_cast<size_t>(c.mesh)], c.s, p0, p1, t0, t1, vel);
      setRow(x1, i, p);
      setRow(v1, i, vel);
    }
    blockHits_[block] = hits;
    blockCcd_[block] = ccd;
    blockDepth_[block] = deepest;
  });
  CollisionStats stats;
  for (Index k = 0; k < Executor::blockCount(n, kGrain); ++k) {
    stats.contacts += blockHits_[k];
    stats.continuousHits += blockCcd_[k];
    stats.maxPenetration = std::max(stats.maxPenetration, blockDepth_[k]);
  }
  if (!edges_.empty()) stats.edgeContacts = resolveEdges(x0, x1, v1, w, t0, t1, exec);
  return stats;
}

template <class S>
std::int64_t ContactSolver<S>::resolveEdges(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1,
                                            const ScalarArray<S>& w, double t0, double t1, const Executor& exec) {
  // Detection, per edge and in parallel, on the particles' resolved motion x0 -> x1: the
  // earliest contact over the mesh obstacles.
  const double h = options_.thickness, eps = options_.epsilon;
  const auto edgeCount = static_cast<Index>(edges_.size());
  exec.parallelForBlocks(edgeCount, kGrain, [&](Index, Index b, Index e) {
    for (Index k = b; k < e; ++k) {
      EdgeHit& record = edgeHits_[static_cast<size_t>(k)];
      record.mesh = -1;
      const auto [i, j] = edges_[static_cast<size_t>(k)];
      if (w[i] == S(0) && w[j] == S(0)) continue;
      const V pi0 = row(x0, i), pi1 = row(x1, i), pj0 = row(x0, j), pj1 = row(x1, j);
      double first = 2;
      for (size_t m = 0; m < model_->meshes().size(); ++m) {
        const MeshObstacle& mo = options_.meshes[m];
        EdgeProbe probe;
        const double s = edgeImpact(model_->meshes()[m], toBody(mo, pi0, t0), toBody(mo, pi1, t1), toBody(mo, pj0, t0),
                                    toBody(mo, pj1, t1), h, eps, probe);
        if (!(s < first)) continue;
        first = s;
        const V n = (1 / probe.distance) * (probe.onEdge - probe.onMesh);
        record.mesh = static_cast<int>(m);
        record.alpha = probe.alpha;
        record.point[0] = probe.onMesh.x;
        record.point[1] = probe.onMesh.y;
        record.point[2] = probe.onMesh.z;
        record.normal[0] = n.x;
        record.normal[1] = n.y;
        record.normal[2] = n.z;
      }
    }
  });
  // Response, serially in edge order (edges share particles): the contact point of the
  // edge, at alpha between its ends, goes back to the thickness along the normal, and its
  // velocity relative to the mesh gets the contact's restitution and friction; both
  // changes are shared by the two ends in proportion to their inverse masses (the
  // point's change is exactly the one asked for).
  std::int64_t hits = 0;
  for (Index k = 0; k < edgeCount; ++k) {
    const EdgeHit& r = edgeHits_[static_cast<size_t>(k)];
    if (r.mesh < 0) continue;
    const auto [i, j] = edges_[static_cast<size_t>(k)];
    const MeshObstacle& mo = options_.meshes[static_cast<size_t>(r.mesh)];
    const double wi = static_cast<double>(w[i]), wj = static_cast<double>(w[j]), al = r.alpha;
    const double weight = (1 - al) * (1 - al) * wi + al * al * wj;
    if (!(weight > 0)) continue;  // the contact point sits on a pinned end
    ++hits;
    const V n{r.normal[0], r.normal[1], r.normal[2]}, q{r.point[0], r.point[1], r.point[2]};
    V a = toBody(mo, row(x1, i), t1), b = toBody(mo, row(x1, j), t1);
    const double separation = dot((1 - al) * a + al * b - q, n);
    if (separation < h) {
      const double lambda = (h - separation) / weight;
      a = a + (lambda * (1 - al) * wi) * n;
      b = b + (lambda * al * wj) * n;
    }
    const V qEnd = toWorld(mo, q, t1);
    const V surfaceVelocity = mo.path && t1 > t0 ? (1 / (t1 - t0)) * (qEnd - toWorld(mo, q, t0)) : V{0, 0, 0};
    const V nw = mo.path ? v(kinematicRotate(*mo.path, d3(n), t1)) : n;
    const V vi = row(v1, i), vj = row(v1, j);
    const V relative = (1 - al) * vi + al * vj - surfaceVelocity;
    V after = relative;
    const double factor = respondVelocity(surface(mo), options_.restingSpeed, nw, after);
    const V change = after - relative;
    const V vi1 = vi + ((1 - al) * wi / weight) * change, vj1 = vj + (al * wj / weight) * change;
    if (factor < 1) {
      // Friction on the contact point's tangential motion over the chunk, as for a particle.
      const V start = (1 - al) * toBody(mo, row(x0, i), t0) + al * toBody(mo, row(x0, j), t0);
      const V moved = (1 - al) * a + al * b - start;
      const V slide = (-(1 - factor)) * (moved - dot(moved, n) * n);
      a = a + ((1 - al) * wi / weight) * slide;
      b = b + (al * wj / weight) * slide;
    }
    const V ai = toWorld(mo, a, t1), bj = toWorld(mo, b, t1);
    if (wi > 0) {
      setRow(x1, i, ai);
      setRow(v1, i, vi1);
    }
    if (wj > 0) {
      setRow(x1, j, bj);
      setRow(v1, j, vj1);
    }
  }
  return hits;
}

template class ContactSolver<float>;
template class ContactSolver<double>;

}  // namespace weft
