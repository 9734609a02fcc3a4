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

#include "collide/primitive_contact.hpp"
#include "contact_math.hpp"
#include "contact_response.hpp"
#include "mesh_queries.hpp"
#include "weft/collide/collision_model.hpp"
#include "weft/collide/obstacles.hpp"

namespace weft {

using namespace detail;

template <class S>
ContactSolver<S>::ContactSolver(const CollisionOptions& options, Index particleCount, std::vector<Edge> edges,
                                std::shared_ptr<const CollisionModel> model, Triangles triangles)
    : options_(options), particleCount_(particleCount) {
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
  for (const IndexArray* corner : {&triangles.a, &triangles.b, &triangles.c})
    if (corner->rows() != triangles.a.rows() ||
        (corner->rows() > 0 && (corner->minCoeff() < 0 || corner->maxCoeff() >= particleCount)))
      throw std::invalid_argument("ContactSolver: the triangles' corners must be particles in [0, " +
                                  std::to_string(particleCount) + "), " + std::to_string(triangles.count()) +
                                  " triangles");
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
  // The corner pass needs a mesh with corners and a cloth.
  if (options_.continuous && options_.corners && triangles.count() > 0 &&
      std::any_of(meshes.begin(), meshes.end(), [](const MeshCollider& c) { return !c.corners.empty(); })) {
    triangles_ = std::move(triangles);
    cornerHits_.resize(static_cast<size_t>(triangles_.count()));
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

// A lower bound on the distance to the mesh of every point of a cloth edge over a chunk
// (its ends moving a0 -> a1 and b0 -> b1, in the mesh's frame), from its ends' clearance
// records ca and cb. The point at alpha along the edge is within da + alpha L of a's
// record point and within db + (1 - alpha) L of b's (da, db: the farthest each end gets
// from its record point; L: the edge's greatest length), so its distance is at least the
// larger of ca - da - alpha L and cb - db - (1 - alpha) L: the bound is the least of that
// over alpha. NaN (no record for either end) skips nothing.
inline double edgeClearance(const double* ca, const double* cb, V a0, V a1, V b0, V b1) {
  const V ra{ca[0], ca[1], ca[2]}, rb{cb[0], cb[1], cb[2]};
  const double ea = ca[3] - std::max(norm(a0 - ra), norm(a1 - ra));
  const double eb = cb[3] - std::max(norm(b0 - rb), norm(b1 - rb));
  const double length = std::max(norm(b0 - a0), norm(b1 - a1));
  if (!(length > 0)) return std::max(ea, eb);
  const double alpha = std::clamp((ea - eb + length) / (2 * length), 0.0, 1.0);
  return std::max(ea - alpha * length, eb - (1 - alpha) * length);
}

// A lower bound on the distance to the mesh of every point of a cloth triangle over a
// chunk (corner k moving p[k][0] -> p[k][1], in the mesh's frame), from its corners'
// clearance records c[k]: its centroid g stays at least c[k] - (the farthest g gets from
// corner k's record point) from the mesh, and every point of the triangle is within rho
// (the farthest a corner gets from g) of g.
inline double triangleClearance(const double* const (&c)[3], const V (&p)[3][2]) {
  double best = -std::numeric_limits<double>::infinity(), rho = 0;
  V g[2];
  for (int s = 0; s < 2; ++s) {
    g[s] = (1.0 / 3) * (p[0][s] + p[1][s] + p[2][s]);
    for (int k = 0; k < 3; ++k) rho = std::max(rho, norm(p[k][s] - g[s]));
  }
  for (int k = 0; k < 3; ++k) {
    const V r{c[k][0], c[k][1], c[k][2]};
    best = std::max(best, c[k][3] - std::max(norm(g[0] - r), norm(g[1] - r)));
  }
  return best - rho;
}

// f(0) + f(1) (+ f(2)), written out so that the compiler sees one expression.
template <int N, class F>
auto sumOver(F f) {
  static_assert(N == 2 || N == 3);
  if constexpr (N == 2)
    return f(0) + f(1);
  else
    return f(0) + f(1) + f(2);
}

// The response to a contact between a mesh obstacle and the point sum_k beta[k] x1[idx[k]]
// of N particles (an edge's point, N = 2; a triangle's, N = 3): the point goes back to the
// thickness h from the mesh point q along n (both in the mesh's frame, n unit from q
// towards the particles), and its velocity relative to the mesh gets the contact's
// restitution and friction. Both changes are shared by the N particles in proportion to
// beta w, so the point's change is exactly the one asked for. False when every particle
// of the point is pinned (nothing moves).
template <int N, class S>
bool respondPoint(const CollisionOptions& options, const MeshObstacle& mo, const Index (&idx)[N],
                  const double (&beta)[N], V n, V q, const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1,
                  const ScalarArray<S>& w, double t0, double t1) {
  const double h = options.thickness;
  double wk[N];
  for (int k = 0; k < N; ++k) wk[k] = static_cast<double>(w[idx[k]]);
  const double weight = sumOver<N>([&](int k) { return beta[k] * beta[k] * wk[k]; });
  if (!(weight > 0)) return false;  // the contact point sits on pinned particles
  V p[N];
  for (int k = 0; k < N; ++k) p[k] = toBody(mo, row(x1, idx[k]), t1);
  const double separation = dot(sumOver<N>([&](int k) { return beta[k] * p[k]; }) - q, n);
  if (separation < h) {
    const double lambda = (h - separation) / weight;
    for (int k = 0; k < N; ++k) p[k] = p[k] + (lambda * beta[k] * wk[k]) * n;
  }
  const V qEnd = toWorld(mo, q, t1);
  const V surfaceVelocity = mo.path && t1 > t0 ? (1 / (t1 - t0)) * (qEnd - toWorld(mo, q, t0)) : V{0, 0, 0};
  const V nw = mo.path ? v(kinematicRotate(*mo.path, d3(n), t1)) : n;
  V vk[N];
  for (int k = 0; k < N; ++k) vk[k] = row(v1, idx[k]);
  const V relative = sumOver<N>([&](int k) { return beta[k] * vk[k]; }) - surfaceVelocity;
  V after = relative;
  const double factor = respondVelocity(surface(mo), options.restingSpeed, nw, after);
  const V change = after - relative;
  for (int k = 0; k < N; ++k) vk[k] = vk[k] + (beta[k] * wk[k] / weight) * change;
  if (factor < 1) {
    // Friction on the contact point's tangential motion over the chunk, as for a particle.
    const V start = sumOver<N>([&](int k) { return beta[k] * toBody(mo, row(x0, idx[k]), t0); });
    const V moved = sumOver<N>([&](int k) { return beta[k] * p[k]; }) - start;
    const V slide = (-(1 - factor)) * (moved - dot(moved, n) * n);
    for (int k = 0; k < N; ++k) p[k] = p[k] + (beta[k] * wk[k] / weight) * slide;
  }
  for (int k = 0; k < N; ++k) {
    if (!(wk[k] > 0)) continue;
    setRow(x1, idx[k], toWorld(mo, p[k], t1));
    setRow(v1, idx[k], vk[k]);
  }
  return true;
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
void ContactSolver<S>::recordSupports() {
  support_.assign(3 * static_cast<size_t>(particleCount_), 0.0);
}

template <class S>
CollisionStats ContactSolver<S>::resolve(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1,
                                         const ScalarArray<S>& w, double t0, double t1, const Executor& exec) {
  const Index n = static_cast<Index>(x1.rows());
  const double h = options_.thickness, eps = options_.epsilon;
  const double supportReach = kSupportReach * h;
  exec.parallelForBlocks(n, kGrain, [&](Index block, Index b, Index e) {
    std::int64_t hits = 0, ccd = 0;
    double deepest = 0;
    double* const support = support_.empty() ? nullptr : support_.data();
    for (Index i = b; i < e; ++i) {
      if (support) {
        for (int a = 0; a < 3; ++a) support[3 * i + a] = 0;
      }
      if (w[i] == S(0)) continue;
      const V p0 = row(x0, i), p1 = row(x1, i);
      Contact c = detect(options_, p0, p1);
      // Supports: the nearest obstacle within the thickness + supportReach at x1 (world
      // normal), for a particle that needs no response in this chunk.
      double nearest = h + supportReach;
      V nearNormal{0, 0, 0};
      if (support && !c.found)
        for (const Obstacle& o : options_.obstacles) {
          V nrm;
          const double phi = distance(o, p1, nrm);
          if (phi < nearest) {
            nearest = phi;
            nearNormal = nrm;
          }
        }
      // Mesh obstacles: the first impact along the segment in each mesh's frame; without
      // continuous detection only when x1 itself is within the thickness.
      for (size_t m = 0; m < model_->meshes().size(); ++m) {
        const MeshObstacle& mo = options_.meshes[m];
        const V b0 = toBody(mo, p0, t0), b1 = toBody(mo, p1, t1);
        double* clear = clearanceOf(clearance_, m, i, n);
        const double length = norm(b1 - b0);
        // The whole chunk farther than the thickness from the mesh (every point of it is
        // within `length` of b1): nothing to find, as the queries below would confirm.
        // (With supports recorded, within their reach too.)
        if (clearanceBound(clear, b1, length) > h + (support ? std::max(2 * eps, supportReach) : 2 * eps)) continue;
        // The distance at b1, looked up a little farther than needed (8 thicknesses) so
        // that it tells the next chunks to skip too.
        const double reach = 9 * h + eps + length;
        V closest;
        const double d1 = meshDistance(model_->meshes()[m], b1, reach, support ? &closest : nullptr);
        clear[0] = b1.x;
        clear[1] = b1.y;
        clear[2] = b1.z;
        clear[3] = std::min(d1, reach);
        if (support && d1 < nearest && d1 > 1e-9 * h) {
          nearest = d1;
          const V nb = (1 / d1) * (b1 - closest);
          nearNormal = mo.path ? v(kinematicRotate(*mo.path, d3(nb), t1)) : nb;
        }
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
      if (!c.found) {
        if (support && nearest < h + supportReach) {
          support[3 * i] = nearNormal.x;
          support[3 * i + 1] = nearNormal.y;
          support[3 * i + 2] = nearNormal.z;
        }
        continue;
      }
      ++hits;
      ccd += c.continuous ? 1 : 0;
      deepest = std::max(deepest, c.depth);
      V vel = row(v1, i), normal;
      const V p = c.obstacle
                      ? respondAnalytic(options_, c, p0, p1, vel, normal)
                      : respondMesh(options_, options_.meshes[static_cast<size_t>(c.mesh)],
                                    model_->meshes()[static_cast<size_t>(c.mesh)], c.s, p0, p1, t0, t1, vel, normal);
      setRow(x1, i, p);
      setRow(v1, i, vel);
      if (support) {
        support[3 * i] = normal.x;
        support[3 * i + 1] = normal.y;
        support[3 * i + 2] = normal.z;
      }
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
  if (!cornerHits_.empty()) stats.cornerContacts = resolveCorners(x0, x1, v1, w, t0, t1, exec);
  return stats;
}

template <class S>
std::int64_t ContactSolver<S>::resolveEdges(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1,
                                            const ScalarArray<S>& w, double t0, double t1, const Executor& exec) {
  // Detection, per edge and in parallel, on the particles' resolved motion x0 -> x1: the
  // earliest contact over the mesh obstacles.
  const double h = options_.thickness, eps = options_.epsilon;
  const Index particles = static_cast<Index>(x1.rows());
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
        const V a0 = toBody(mo, pi0, t0), a1 = toBody(mo, pi1, t1), b0 = toBody(mo, pj0, t0), b1 = toBody(mo, pj1, t1);
        // The whole edge farther than the thickness from the mesh over the chunk: no
        // contact, as edgeImpact would find.
        if (edgeClearance(clearanceOf(clearance_, m, i, particles), clearanceOf(clearance_, m, j, particles), a0, a1,
                          b0, b1) > h + 2 * eps)
          continue;
        EdgeProbe probe;
        const double s = edgeImpact(model_->meshes()[m], a0, a1, b0, b1, h, eps, probe);
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
  // Response, serially in edge order (edges share particles): respondPoint at the edge's
  // point alpha between its ends.
  std::int64_t hits = 0;
  for (Index k = 0; k < edgeCount; ++k) {
    const EdgeHit& r = edgeHits_[static_cast<size_t>(k)];
    if (r.mesh < 0) continue;
    const auto [i, j] = edges_[static_cast<size_t>(k)];
    const Index idx[2] = {i, j};
    const double beta[2] = {1 - r.alpha, r.alpha};
    if (respondPoint(options_, options_.meshes[static_cast<size_t>(r.mesh)], idx, beta,
                     V{r.normal[0], r.normal[1], r.normal[2]}, V{r.point[0], r.point[1], r.point[2]}, x0, x1, v1, w, t0,
                     t1))
      ++hits;
  }
  return hits;
}

template <class S>
std::int64_t ContactSolver<S>::resolveCorners(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1,
                                              const ScalarArray<S>& w, double t0, double t1, const Executor& exec) {
  // Detection, per cloth triangle and in parallel, on the particles' motion x0 -> x1 as
  // resolved so far: the earliest time a mesh corner comes within the thickness of the
  // triangle (conservative advancement; no hit proves it stayed beyond half the thickness).
  const double h = options_.thickness, eps = options_.epsilon;
  const Index n = static_cast<Index>(x1.rows());
  const Index triangleCount = triangles_.count();
  exec.parallelForBlocks(triangleCount, kGrain, [&](Index, Index b, Index e) {
    for (Index t = b; t < e; ++t) {
      CornerHit& record = cornerHits_[static_cast<size_t>(t)];
      record.mesh = -1;
      const Index idx[3] = {triangles_.a[t], triangles_.b[t], triangles_.c[t]};
      if (w[idx[0]] == S(0) && w[idx[1]] == S(0) && w[idx[2]] == S(0)) continue;
      double first = 2;
      for (size_t m = 0; m < model_->meshes().size(); ++m) {
        const MeshCollider& mesh = model_->meshes()[m];
        if (mesh.corners.empty()) continue;
        const MeshObstacle& mo = options_.meshes[m];
        V p[3][2];
        for (int k = 0; k < 3; ++k) {
          p[k][0] = toBody(mo, row(x0, idx[k]), t0);
          p[k][1] = toBody(mo, row(x1, idx[k]), t1);
        }
        // The whole triangle farther than the thickness from the mesh (its corners
        // included) over the chunk: nothing to find.
        const double* const clear[3] = {clearanceOf(clearance_, m, idx[0], n), clearanceOf(clearance_, m, idx[1], n),
                                        clearanceOf(clearance_, m, idx[2], n)};
        if (triangleClearance(clear, p) > h + 2 * eps) continue;
        const Aabb<double> box = boxAround({p[0][0], p[0][1], p[1][0], p[1][1], p[2][0], p[2][1]}, h + eps);
        Vec3<double> a[2], bb[2], c[2];
        for (int s = 0; s < 2; ++s) {
          a[s] = e3(p[0][s]);
          bb[s] = e3(p[1][s]);
          c[s] = e3(p[2][s]);
        }
        mesh.bvh.forEachOverlapping(box, [&](Index mt) {
          const std::uint8_t mask = mesh.corners[static_cast<size_t>(mt)];
          if (mask == 0) return;
          const Index corner[3] = {mesh.triangles.a[mt], mesh.triangles.b[mt], mesh.triangles.c[mt]};
          for (int k = 0; k < 3; ++k) {
            if (!(mask & (1u << k))) continue;
            const Index qi = corner[k];
            const double qc[3] = {mesh.x(qi, 0), mesh.x(qi, 1), mesh.x(qi, 2)};
            bool inside = true;
            for (int axis = 0; axis < 3; ++axis)
              inside = inside && qc[axis] >= box.lo[axis] && qc[axis] <= box.hi[axis];
            if (!inside) continue;
            const Vec3<double> q[2] = {{qc[0], qc[1], qc[2]}, {qc[0], qc[1], qc[2]}};
            const PrimitiveContact hit = vertexTriangleContact(q, a, bb, c, h);
            if (!hit.hit || !(hit.time < first)) continue;
            const double nn =
                hit.normal[0] * hit.normal[0] + hit.normal[1] * hit.normal[1] + hit.normal[2] * hit.normal[2];
            if (!(nn > 0)) continue;  // a degenerate triangle touching the corner: no side to push to
            first = hit.time;
            record.mesh = static_cast<int>(m);
            for (int i = 0; i < 3; ++i) {
              record.beta[i] = -hit.weights[i + 1];
              record.point[i] = qc[i];
              record.normal[i] = -hit.normal[i];  // the query's normal points at the corner
            }
          }
        });
      }
    }
  });
  // Response, serially in triangle order (triangles share particles).
  std::int64_t hits = 0;
  for (Index t = 0; t < triangleCount; ++t) {
    const CornerHit& r = cornerHits_[static_cast<size_t>(t)];
    if (r.mesh < 0) continue;
    const Index idx[3] = {triangles_.a[t], triangles_.b[t], triangles_.c[t]};
    if (respondPoint(options_, options_.meshes[static_cast<size_t>(r.mesh)], idx, r.beta,
                     V{r.normal[0], r.normal[1], r.normal[2]}, V{r.point[0], r.point[1], r.point[2]}, x0, x1, v1, w, t0,
                     t1))
      ++hits;
  }
  return hits;
}

template class ContactSolver<float>;
template class ContactSolver<double>;

}  // namespace weft
