// The self-collision pass (see weft/collide/self_collision.hpp): conservative advancement
// on vertex-triangle and edge-edge distances, a Gauss-Seidel response with friction and
// the stopping failsafe.
#include "weft/collide/self_collision.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "bvh_internal.hpp"
#include "closest_point.hpp"
#include "collide/self_collider.hpp"

namespace weft {

namespace {

using V = Vec3<double>;

/// Closest point of the closed triangle abc to p as barycentric weights (Ericson 5.1.5);
/// slivers (sin^2 of the angle at a below eps) as their three edges.
void closestBarycentric(const V& p, const V& a, const V& b, const V& c, double bary[3]) {
  const V ab = b - a, ac = c - a;
  const double ab2 = ab.squaredNorm(), ac2 = ac.squaredNorm();
  if (!(ab.cross(ac).squaredNorm() > std::numeric_limits<double>::epsilon() * ab2 * ac2)) {
    const V* corner[3] = {&a, &b, &c};
    double best = std::numeric_limits<double>::infinity();
    for (int e = 0; e < 3; ++e) {
      const V& s = *corner[e];
      const V d = *corner[(e + 1) % 3] - s;
      const double len2 = d.squaredNorm();
      double t = len2 > 0 ? (p - s).dot(d) / len2 : 0.0;
      t = std::clamp(t, 0.0, 1.0);
      const double dist2 = (p - (s + t * d)).squaredNorm();
      if (dist2 < best) {
        best = dist2;
        bary[e] = 1 - t;
        bary[(e + 1) % 3] = t;
        bary[(e + 2) % 3] = 0;
      }
    }
    return;
  }
  const auto set = [&](double u, double v, double w) {
    bary[0] = u;
    bary[1] = v;
    bary[2] = w;
  };
  const V ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return set(1, 0, 0);
  const V bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return set(0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double den = d1 - d3, v = den > 0 ? d1 / den : 0.0;
    return set(1 - v, v, 0);
  }
  const V cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return set(0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double den = d2 - d6, w = den > 0 ? d2 / den : 0.0;
    return set(1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4, e43 = d4 - d3, e56 = d5 - d6;
  if (va <= 0 && e43 >= 0 && e56 >= 0) {
    const double den = e43 + e56, w = den > 0 ? e43 / den : 0.0;
    return set(0, 1 - w, w);
  }
  const double den = va + vb + vc;
  if (!(den > 0)) return set(1, 0, 0);
  const double v = vb / den, w = vc / den;
  set(1 - v - w, v, w);
}

constexpr int kMaxSteps = 64;

V lerp(const V x[2], double s) { return x[0] + s * (x[1] - x[0]); }

/// The shortcut's test (see advance): whether a distance `distance` at s, with `lipschitz2`
/// the bound's squared core, proves the pair stays beyond threshold / 2 up to s = 1, with a
/// relative 4e-6 to spare.
bool provenApart(double distance, double lipschitz2, double threshold, double s) {
  const double margin = distance - 0.5 * threshold, rest = 1 - s;
  const double bound = rest * rest * lipschitz2 * (1 + 4e-6);
  // (Only where the squares are normal finite numbers: underflow or overflow would make the
  // relative margin meaningless, and the exact step decides.)
  return margin >= 0 && bound < std::numeric_limits<double>::infinity() &&
         (bound >= std::numeric_limits<double>::min() || lipschitz2 == 0 || rest == 0) && margin * margin >= bound;
}

/// Conservative advancement (see the design note). eval(s, gap, weights) returns the
/// distance at s, the vector between the closest points (towards the first primitive) and
/// the weights; fallback(s, normal) gives a normal where the distance is zero. `lipschitz2`
/// is the square of the Lipschitz bound's core (lipschitzSquared): its square root is taken
/// only when a step is needed.
template <class Eval, class Fallback>
PrimitiveContact advance(Eval&& eval, Fallback&& fallback, double lipschitz2, double threshold, double start) {
  PrimitiveContact c;
  double s = std::clamp(start, 0.0, 1.0);
  V gap;
  double d = 0;
  bool found = false;
  double lipschitz = -1;  // not taken yet
  for (int k = 0; k < kMaxSteps; ++k) {
    d = eval(s, gap, c.weights);
    if (d < threshold) {
      found = true;
      break;
    }
    if (lipschitz < 0) {
      // Most queries are misses whose first step already passes s = 1: when the margin
      // (d - threshold / 2) beats (1 - s) times the bound by a relative 4e-6, far more than
      // the rounding of the step below, that step would end at or past 1, so the answer is
      // the same without the square root and the division (a profile put them on the
      // critical path of every query).
      if (provenApart(d, lipschitz2, threshold, s)) return c;
      lipschitz = std::sqrt(lipschitz2) * (1 + 1e-9);
    }
    if (!(lipschitz > 0)) return c;
    const double next = s + (d - 0.5 * threshold) / lipschitz;
    if (next >= 1) return c;  // d >= threshold / 2 up to s = 1
    s = next;
  }
  if (!found) {  // step cap: report without proof
    c.capped = true;
    d = eval(s, gap, c.weights);
  }
  c.hit = true;
  c.time = s;
  c.distance = d;
  V n = V::Zero();
  if (d > 1e-9 * threshold) {
    n = gap / d;
  } else {
    fallback(s, n);
  }
  for (int i = 0; i < 3; ++i) c.normal[i] = n[i];
  return c;
}

/// The square of the Lipschitz bound's core: the largest squared relative displacement
/// between a vertex of the first set and one of the second (the bound is its square root,
/// enlarged by a relative 1e-9 for rounding).
/// (In scalars: the positions were just stored one coordinate at a time, and a vector load
/// across two such stores waits for them to reach the cache; a profile put a sixth of the
/// pass here. Same arithmetic, in the same order, as Eigen's squaredNorm.)
double lipschitzSquared(std::initializer_list<const V*> first, std::initializer_list<const V*> second) {
  double L2 = 0;
  for (const V* f : first)
    for (const V* g : second) {
      const double dx = (f[1].x() - f[0].x()) - (g[1].x() - g[0].x());
      const double dy = (f[1].y() - f[0].y()) - (g[1].y() - g[0].y());
      const double dz = (f[1].z() - f[0].z()) - (g[1].z() - g[0].z());
      L2 = std::max(L2, dx * dx + dy * dy + dz * dz);
    }
  return L2;
}

/// Orients `n` (unit or zero) so that it points from the second primitive to the first at
/// s = 0 (gap0), or against their relative motion when they touch at s = 0 too.
void orient(V& n, const V& gap0, const V& relativeMotion) {
  double side = n.dot(gap0);
  if (side == 0) side = -n.dot(relativeMotion);
  if (side < 0) n = -n;
}

}  // namespace

namespace {
/// The distance at s, the vector between the closest points (towards the vertex) and the
/// weights: the vertex-triangle query's evaluation.
double vertexTriangleAt(const V p[2], const V a[2], const V b[2], const V c[2], double s, V& gap, double* weights) {
  const V ps = lerp(p, s), as = lerp(a, s), bs = lerp(b, s), cs = lerp(c, s);
  double bary[3];
  closestBarycentric(ps, as, bs, cs, bary);
  gap = ps - (bary[0] * as + bary[1] * bs + bary[2] * cs);
  weights[0] = 1;
  weights[1] = -bary[0];
  weights[2] = -bary[1];
  weights[3] = -bary[2];
  return gap.norm();
}

/// The same for the edge-edge query (towards the first edge).
double edgeEdgeAt(const V p[2], const V q[2], const V a[2], const V b[2], double s, V& gap, double* weights) {
  const V ps = lerp(p, s), qs = lerp(q, s), as = lerp(a, s), bs = lerp(b, s);
  double u = 0, v = 0;
  V c1, c2;
  detail::closestSegmentSegment(ps, qs, as, bs, u, v, c1, c2);
  gap = c1 - c2;
  weights[0] = 1 - u;
  weights[1] = u;
  weights[2] = -(1 - v);
  weights[3] = -v;
  return gap.norm();
}
}  // namespace

FirstLook vertexTriangleFirstLook(const V p[2], const V a[2], const V b[2], const V c[2]) {
  V gap;
  double weights[4];
  return {vertexTriangleAt(p, a, b, c, 0.0, gap, weights), lipschitzSquared({p}, {a, b, c})};
}

FirstLook edgeEdgeFirstLook(const V p[2], const V q[2], const V a[2], const V b[2]) {
  V gap;
  double weights[4];
  return {edgeEdgeAt(p, q, a, b, 0.0, gap, weights), lipschitzSquared({p, q}, {a, b})};
}

bool firstLookProvesApart(const FirstLook& look, double threshold) {
  // advance() from s = 0: not below the threshold at its first evaluation, and its shortcut
  // then proves the rest of the chunk.
  return !(look.distance < threshold) && provenApart(look.distance, look.lipschitz2, threshold, 0.0);
}

// Ericson's closest points of two segments (5.1.9, as detail::closestSegmentSegment) and
// lipschitzSquared, written without branches (see primitive_contact.hpp).
void edgeEdgeFirstLooks(int m, const double (&x)[4][3][kFirstLookBatch], const double (&d)[4][3][kFirstLookBatch],
                        double (&distance)[kFirstLookBatch], double (&lipschitz2)[kFirstLookBatch],
                        double (&lengths)[kFirstLookBatch]) {
  constexpr double tiny = 1e-300;
  for (int k = 0; k < m; ++k) {
    double d1[3], d2[3], r[3];
    for (int a = 0; a < 3; ++a) {
      d1[a] = x[1][a][k] - x[0][a][k];
      d2[a] = x[3][a][k] - x[2][a][k];
      r[a] = x[0][a][k] - x[2][a][k];
    }
    const double A = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2];
    const double E = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2];
    const double F = d2[0] * r[0] + d2[1] * r[1] + d2[2] * r[2];
    const double C = d1[0] * r[0] + d1[1] * r[1] + d1[2] * r[2];
    const double B = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2];
    const double denom = A * E - B * B;
    const double s0 = denom > 0 ? std::clamp((B * F - C * E) / denom, 0.0, 1.0) : 0.0;
    const double t0 = (B * s0 + F) / E;
    const double sLow = std::clamp(-C / A, 0.0, 1.0), sHigh = std::clamp((B - C) / A, 0.0, 1.0);
    const double s = t0 < 0 ? sLow : (t0 > 1 ? sHigh : s0);
    const double t = t0 < 0 ? 0.0 : (t0 > 1 ? 1.0 : t0);
    double g2 = 0;
    for (int a = 0; a < 3; ++a) {
      const double g = (x[0][a][k] + s * d1[a]) - (x[2][a][k] + t * d2[a]);
      g2 += g * g;
    }
    // (A sum of every input is finite only if each is: NaN and infinities propagate, and
    // std::max below would drop a NaN from the Lipschitz core.)
    double all = 0;
    for (int i = 0; i < 4; ++i)
      for (int a = 0; a < 3; ++a) all += x[i][a][k] + d[i][a][k];
    distance[k] = A <= tiny || E <= tiny || !std::isfinite(all) ? -1.0 : std::sqrt(g2);
    lengths[k] = std::sqrt(A) + std::sqrt(E);
    double L2 = 0;
    for (int i = 0; i < 2; ++i)
      for (int j = 2; j < 4; ++j) {
        double l2 = 0;
        for (int a = 0; a < 3; ++a) {
          const double dd = d[i][a][k] - d[j][a][k];
          l2 += dd * dd;
        }
        L2 = std::max(L2, l2);
      }
    lipschitz2[k] = L2;
  }
}

PrimitiveContact vertexTriangleContact(const V p[2], const V a[2], const V b[2], const V c[2], double threshold,
                                       double start) {
  const auto eval = [&](double s, V& gap, double* weights) { return vertexTriangleAt(p, a, b, c, s, gap, weights); };
  const auto fallback = [&](double s, V& n) {
    const V as = lerp(a, s), bs = lerp(b, s), cs = lerp(c, s);
    n = (bs - as).cross(cs - as);
    const double len = n.norm();
    if (!(len > 0)) {
      n = V::Zero();
      return;
    }
    n /= len;
    double bary[3];
    closestBarycentric(p[0], a[0], b[0], c[0], bary);
    const V gap0 = p[0] - (bary[0] * a[0] + bary[1] * b[0] + bary[2] * c[0]);
    const V motion = (p[1] - p[0]) - (bary[0] * (a[1] - a[0]) + bary[1] * (b[1] - b[0]) + bary[2] * (c[1] - c[0]));
    orient(n, gap0, motion);
  };
  return advance(eval, fallback, lipschitzSquared({p}, {a, b, c}), threshold, start);
}

PrimitiveContact edgeEdgeContact(const V p[2], const V q[2], const V a[2], const V b[2], double threshold,
                                 double start) {
  const auto eval = [&](double s, V& gap, double* weights) { return edgeEdgeAt(p, q, a, b, s, gap, weights); };
  const auto fallback = [&](double s, V& n) {
    const V ps = lerp(p, s), qs = lerp(q, s), as = lerp(a, s), bs = lerp(b, s);
    n = (qs - ps).cross(bs - as);
    const double len = n.norm();
    if (!(len > 1e-12 * (qs - ps).norm() * (bs - as).norm()) || !(len > 0)) {
      n = V::Zero();  // parallel edges touching: no normal (the failsafe handles the pair)
      return;
    }
    n /= len;
    double u = 0, v = 0;
    V c1, c2;
    detail::closestSegmentSegment(p[0], q[0], a[0], b[0], u, v, c1, c2);
    const V motion = ((1 - u) * (p[1] - p[0]) + u * (q[1] - q[0])) - ((1 - v) * (a[1] - a[0]) + v * (b[1] - b[0]));
    orient(n, c1 - c2, motion);
  };
  return advance(eval, fallback, lipschitzSquared({p, q}, {a, b}), threshold, start);
}

template <class S>
SelfCollider<S>::SelfCollider(const Model<S>& model, const SelfCollisionOptions& options, const Vec3Array<S>& x,
                              const Executor& exec)
    : model_(&model), options_(options) {
  validateSelfCollision(options_, model, x, "SelfCollisionOptions");
  const Index triangles = model.triangleCount();
  thickness_.assign(static_cast<size_t>(model.particleCount()), options_.thickness);
  if (!options_.particleThickness.empty()) thickness_ = options_.particleThickness;
  double thickest = options_.thickness;
  thinnest_ = options_.thickness;
  if (!thickness_.empty()) {
    const auto [thin, thick] = std::minmax_element(thickness_.begin(), thickness_.end());
    thinnest_ = *thin;
    thickest = *thick;
  }
  skin_ = kSkin * thickest;
  // A triangle's thickness: the largest of its corners' (what a pass compares two
  // triangles' boxes with, before their primitives).
  triangleThickness_.resize(static_cast<size_t>(triangles));
  const Triangles& corners = model.triangles();
  for (Index t = 0; t < triangles; ++t) {
    triangleThickness_[static_cast<size_t>(t)] =
        std::max({thickness_[static_cast<size_t>(corners.a[t])], thickness_[static_cast<size_t>(corners.b[t])],
                  thickness_[static_cast<size_t>(corners.c[t])]});
  }
  if (options_.cullFlatRegions && triangles > 0) {
    const Triangles& tr = model.triangles();
    double shortest2 = std::numeric_limits<double>::infinity();
    for (Index t = 0; t < triangles; ++t) {
      const Index c[3] = {tr.a[t], tr.b[t], tr.c[t]};
      for (int k = 0; k < 3; ++k) {
        const Index i = c[k], j = c[(k + 1) % 3];
        double d2 = 0;
        for (int a = 0; a < 3; ++a) {
          const double d = static_cast<double>(x(i, a)) - static_cast<double>(x(j, a));
          d2 += d * d;
        }
        shortest2 = std::min(shortest2, d2);
      }
    }
    skin_ = std::min(skin_, kConeSkin * std::sqrt(shortest2));  // > 0: the thickness is below every altitude
  }
  if (triangles > 0) {
    const SurfaceTopology& topo = model.surfaceTopology();  // derived once per Model
    owned_.resize(static_cast<size_t>(triangles));
    for (Index t = 0; t < triangles; ++t) {
      Owned& o = owned_[static_cast<size_t>(t)];
      o.corner[0] = corners.a[t];
      o.corner[1] = corners.b[t];
      o.corner[2] = corners.c[t];
      for (Index k = topo.ownedVertices.begin(t); k < topo.ownedVertices.end(t); ++k)
        o.vertex[o.vertices++] = topo.ownedVertices.entries[k];
      for (Index k = topo.ownedEdges.begin(t); k < topo.ownedEdges.end(t); ++k) {
        const Edge& e = topo.edges[static_cast<size_t>(topo.ownedEdges.entries[k])];
        o.edge[o.edges][0] = e[0];
        o.edge[o.edges][1] = e[1];
        ++o.edges;
      }
    }
    // With flat regions culled, a grid's tree is built over its rows and columns, not over
    // the positions it starts in: its nodes are then patches of the cloth even when it
    // starts folded (a tree over folded layers pairs the layers' triangles first, and no
    // node above the leaves is flat). The tree's boxes are refit at every gathering.
    const auto& grid = model.grid();
    if (options_.cullFlatRegions && grid && grid->width * grid->height == model.particleCount()) {
      Vec3Array<S> layout(model.particleCount(), 3);
      for (Index i = 0; i < model.particleCount(); ++i)
        layout.row(i) << static_cast<S>(i % grid->width), static_cast<S>(i / grid->width), S(0);
      bvh_.build(layout, model.triangles(), exec, 0.5 * thickest);
    } else {
      bvh_.build(x, model.triangles(), exec, 0.5 * thickest);
    }
    if (options_.cullFlatRegions && triangles > 1) {
      findConnectedNodes();
      flat_.assign(connected_.size(), 0);
      cones_.resize(connected_.size());
      leafCones_.resize(static_cast<size_t>(triangles));
    }
  }
  frozen_.assign(static_cast<size_t>(model.particleCount()), 0);
  displacement_.assign(static_cast<size_t>(model.particleCount()), 0.0);
  push_.assign(3 * static_cast<size_t>(model.particleCount()), 0.0);
  unpushed_.resize(model.particleCount(), 3);
  touchedFlag_.assign(static_cast<size_t>(model.particleCount()), 0);
  touched_.reserve(static_cast<size_t>(model.particleCount()));
  lastTouched_.reserve(static_cast<size_t>(model.particleCount()));
  moved_.assign(static_cast<size_t>(model.particleCount()), 0);
  sweptBox_.resize(static_cast<size_t>(model.particleCount()));
  skinBox_.assign(static_cast<size_t>(model.particleCount()), Aabb<S>{});  // (zero: a checkpoint writes them)
  blockSums_.resize(static_cast<size_t>(Executor::blockCount(model.particleCount(), kVertexGrain)));
  blockFlags_.reserve(blockSums_.size());
  triangleBox_.resize(static_cast<size_t>(triangles));
}

template <class S>
void SelfCollider<S>::detectBlock(Index blockIndex, const Vec3Array<S>& x0, const Vec3Array<S>& x1,
                                  const ScalarArray<S>& w, bool all) {
  Block& block = blocks_[static_cast<size_t>(blockIndex)];
  block.contacts.clear();
  block.tests = 0;
  block.guards = 0;
  block.margin = std::numeric_limits<double>::infinity();
  const Index n = model_->particleCount();
  // A pair keeps the mean of its two cloths' thicknesses (the thickness when there is one).
  const double* th = thickness_.data();
  const Triangles& tr = model_->triangles();
  const S* c0[3] = {x0.data(), x0.data() + n, x0.data() + 2 * n};
  const S* c1[3] = {x1.data(), x1.data() + n, x1.data() + 2 * n};
  const std::uint8_t* moved = moved_.data();
  // A primitive pair whose boxes over this chunk are farther apart than the thickness is
  // not advanced.
  const Aabb<S>* box = sweptBox_.data();
  // A primitive pair to test: its vertices, their positions at the chunk's ends, and the
  // first look of its query (primitive_contact.hpp).
  struct Pending {
    Index v[4];
    bool vertexTriangle;
    double thickness;
    Index pair;  // the triangle pair's index in pairs_
    V p[4][2];
    FirstLook look;
  };
  std::array<Pending, kFirstLookBatch> batch;
  // The batch's positions at s = 0 and displacements again, in structure of arrays, for the
  // edge-edge first looks.
  double soaX[4][3][kFirstLookBatch], soaD[4][3][kFirstLookBatch], eeDistance[kFirstLookBatch],
      eeLipschitz2[kFirstLookBatch], eeLengths[kFirstLookBatch];
  // The full advancement on a primitive pair the first look left open; a contact goes to the
  // block's list.
  const auto test = [&](const Pending& pending) {
    const Index* v = pending.v;
    const bool vertexTriangle = pending.vertexTriangle;
    const double thickness = pending.thickness;
    const V(&p)[4][2] = pending.p;
    const auto query = [&](double threshold, double start) {
      return vertexTriangle ? vertexTriangleContact(p[0], p[1], p[2], p[3], threshold, start)
                            : edgeEdgeContact(p[0], p[1], p[2], p[3], threshold, start);
    };
    const PrimitiveContact hit = query(thickness, 0);
    if (!hit.hit) return false;
    Contact c;
    for (int i = 0; i < 4; ++i) {
      c.vertex[i] = v[i];
      c.weights[i] = hit.weights[i];
    }
    for (int i = 0; i < 3; ++i) c.normal[i] = hit.normal[i];
    c.vertexTriangle = vertexTriangle;
    c.thickness = thickness;
    // The failsafe's threshold: a quarter of the thickness, or half the distance at the
    // start of the chunk (a query at an infinite threshold stops at s = 0 and gives it).
    // Below it from the first contact on: a guard. Not: the pair stays >= theta / 2 apart
    // over the whole chunk (before the contact it stayed >= thickness / 2), the margin
    // that lets resolve() stop early.
    const double d0 = query(std::numeric_limits<double>::infinity(), 0).distance;
    const double theta = std::min(0.25 * thickness, 0.5 * d0);
    c.guard = theta > 0 && query(theta, hit.time).hit;
    block.guards += c.guard ? 1 : 0;
    block.margin = std::min(block.margin, theta > 0 ? 0.5 * theta : 0.0);
    block.contacts.push_back(c);
    return true;
  };
  const Index count = static_cast<Index>(pairs_.size());
  const Index begin = blockIndex * kGrain, end = std::min(count, begin + kGrain);
  const Owned* owned = owned_.data();
  // The primitive pairs that need a test are gathered, a batch at a time, across triangle
  // pairs; then come their first looks (independent work the processor overlaps), then the
  // full query for those the look leaves open, in their order: the contacts, and which
  // triangle pairs had one, are what testing them one by one gives.
  int m = 0;
  const auto flush = [&] {
    edgeEdgeFirstLooks(m, soaX, soaD, eeDistance, eeLipschitz2, eeLengths);
    for (int k = 0; k < m; ++k) {
      Pending& e = batch[static_cast<size_t>(k)];
      e.look = e.vertexTriangle ? vertexTriangleFirstLook(e.p[0], e.p[1], e.p[2], e.p[3])
                                : batchedLook(eeDistance[k], eeLipschitz2[k], eeLengths[k]);
    }
    for (int k = 0; k < m; ++k) {
      const Pending& e = batch[static_cast<size_t>(k)];
      if (!firstLookProvesApart(e.look, e.thickness) && test(e)) pairHit_[static_cast<size_t>(e.pair)] = 1;
    }
    m = 0;
  };
  for (Index pi = begin; pi < end; ++pi) {
    const TrianglePair pair = pairs_[static_cast<size_t>(pi)];
    // After a response only the pairs it moved a vertex of (or that were in contact) can
    // have changed; the others keep their answer (no contact).
    std::uint8_t& hit = pairHit_[static_cast<size_t>(pi)];
    if (!all && !hit) {
      const Index ta[3] = {tr.a[pair.first], tr.b[pair.first], tr.c[pair.first]};
      const Index tb[3] = {tr.a[pair.second], tr.b[pair.second], tr.c[pair.second]};
      if (!(moved[ta[0]] | moved[ta[1]] | moved[ta[2]] | moved[tb[0]] | moved[tb[1]] | moved[tb[2]])) continue;
    }
    hit = 0;
    const Aabb<S>& first = triangleBox_[static_cast<size_t>(pair.first)];
    const Aabb<S>& second = triangleBox_[static_cast<size_t>(pair.second)];
    const double apartBeyond =
        0.5 *
        (triangleThickness_[static_cast<size_t>(pair.first)] + triangleThickness_[static_cast<size_t>(pair.second)]) *
        kBoxesApart;
    bool apart = false;
    for (int a = 0; a < 3 && !apart; ++a)
      apart = static_cast<double>(first.lo[a]) - static_cast<double>(second.hi[a]) > apartBeyond ||
              static_cast<double>(second.lo[a]) - static_cast<double>(first.hi[a]) > apartBeyond;
    if (apart) continue;  // (then so is every primitive pair of the two)
    const Owned& firstOwned = owned[pair.first];
    const Owned& secondOwned = owned[pair.second];
    for (unsigned mask = primitiveMask_[static_cast<size_t>(pi)]; mask != 0; mask &= mask - 1) {
      Index v[4];
      const bool vertexTriangle = primitiveVertices(firstOwned, secondOwned, std::countr_zero(mask), v);
      if (w[v[0]] == S(0) && w[v[1]] == S(0) && w[v[2]] == S(0) && w[v[3]] == S(0)) continue;
      const double thickness = 0.5 * (th[v[0]] + th[v[3]]);
      if (primitiveBoxesApart(box, v, vertexTriangle ? 1 : 2, thickness * kBoxesApart)) continue;
      ++block.tests;
      if (m == kFirstLookBatch) flush();
      Pending& pending = batch[static_cast<size_t>(m++)];
      std::copy(v, v + 4, pending.v);
      pending.vertexTriangle = vertexTriangle;
      pending.thickness = thickness;
      pending.pair = pi;
      for (int i = 0; i < 4; ++i) {
        pending.p[i][0] = V(c0[0][v[i]], c0[1][v[i]], c0[2][v[i]]);
        pending.p[i][1] = V(c1[0][v[i]], c1[1][v[i]], c1[2][v[i]]);
        for (int a = 0; a < 3; ++a) {
          soaX[i][a][m - 1] = pending.p[i][0][a];
          soaD[i][a][m - 1] = pending.p[i][1][a] - pending.p[i][0][a];
        }
      }
    }
  }
  flush();
}

template <class S>
bool SelfCollider<S>::detect(const Vec3Array<S>& x0, const Vec3Array<S>& x1, const ScalarArray<S>& w,
                             const Executor& exec, SelfCollisionStats& stats) {
  const bool gathered = !candidatesCover(x0, x1, exec);
  if (gathered) {
    if (!gatherCandidates(x0, x1, exec, stats)) return false;
    onlyMoved_ = false;  // new candidates: test them all
  }
  ++stats.passes;
  const Index n = model_->particleCount();
  // This chunk's box of every vertex and every triangle.
  exec.parallelFor(n, kVertexGrain, [&](Index begin, Index end) {
    for (int a = 0; a < 3; ++a)
      for (Index i = begin; i < end; ++i) {
        sweptBox_[static_cast<size_t>(i)].lo[a] = std::min(x0(i, a), x1(i, a));
        sweptBox_[static_cast<size_t>(i)].hi[a] = std::max(x0(i, a), x1(i, a));
      }
  });
  const Triangles& tr = model_->triangles();
  exec.parallelFor(model_->triangleCount(), kVertexGrain, [&](Index begin, Index end) {
    const Aabb<S>* box = sweptBox_.data();
    // (Triangle by triangle: its three corners' boxes are loaded once for the three axes.)
    for (Index t = begin; t < end; ++t) {
      const Aabb<S>&bi = box[tr.a[t]], &bj = box[tr.b[t]], &bk = box[tr.c[t]];
      Aabb<S>& out = triangleBox_[static_cast<size_t>(t)];
      for (int a = 0; a < 3; ++a) {
        out.lo[a] = std::min(std::min(bi.lo[a], bj.lo[a]), bk.lo[a]);
        out.hi[a] = std::max(std::max(bi.hi[a], bj.hi[a]), bk.hi[a]);
      }
    }
  });
  const bool all = !onlyMoved_;
  // New candidates' primitive pairs are found block by block just before the block is
  // tested (its pairs, their triangles' records and boxes still in cache).
  exec.parallelFor(blocksUsed_, 1, [&](Index kb, Index ke) {
    for (Index k = kb; k < ke; ++k) {
      if (gathered) expandBlock(k);
      detectBlock(k, x0, x1, w, all);
    }
  });
  for (Index k = 0; k < blocksUsed_; ++k) stats.tests += blocks_[static_cast<size_t>(k)].tests;
  return true;
}

template <class S>
double SelfCollider<S>::respond(Vec3Array<S>& x1, Vec3Array<S>& v1, const ScalarArray<S>& w, double h,
                                const double* supports, SelfCollisionStats& stats) {
  const double mu = options_.friction;
  std::fill(displacement_.begin(), displacement_.end(), 0.0);
  double largest = 0;  // m, the largest entry of displacement_
  // Every contact with a normal and a free side, in block order, with each vertex's share of
  // a relative change (w beta / sw, beta the contact's weight of the vertex).
  std::size_t capacity = 0;  // (over every block: the used ones change from chunk to chunk)
  for (const Block& block : blocks_) capacity += block.contacts.capacity();
  if (shares_.capacity() < capacity) shares_.reserve(capacity);  // (grows only with the contact lists)
  shares_.clear();
  for (Index k = 0; k < blocksUsed_; ++k) {
    for (const Contact& c : blocks_[static_cast<size_t>(k)].contacts) {
      ++stats.contacts;
      stats.vertexTriangle += c.vertexTriangle ? 1 : 0;
      const V n(c.normal[0], c.normal[1], c.normal[2]);
      if (n.squaredNorm() == 0) continue;  // no normal: left to the failsafe
      Share sh;
      sh.contact = &c;
      // A vertex resting on an obstacle whose push along n (the sign of its weight) would
      // go into that obstacle is blocked: it moves only in the obstacle's tangent plane, so
      // along n it counts with the inverse mass w (1 - (n.m)^2) and the other side takes
      // the rest; the pair still separates by what it must. Unless that leaves the contact
      // less than kSupportedMass of its inverse mass along n (the other side pinned, or
      // pressing along m): then the obstacle's next chunk pushes back, as without supports.
      double sw = 0, free = 0, wi[4], nm[4];
      for (int i = 0; i < 4; ++i) {
        const Index j = c.vertex[i];
        wi[i] = static_cast<double>(w[j]);
        sh.rests[i] = nullptr;
        nm[i] = 0;
        if (supports) {
          const double* m = supports + 3 * j;
          if (m[0] != 0 || m[1] != 0 || m[2] != 0) {
            sh.rests[i] = m;
            nm[i] = n[0] * m[0] + n[1] * m[1] + n[2] * m[2];
          }
        }
        const double wb2 = wi[i] * c.weights[i] * c.weights[i];
        free += wb2;
        sw += c.weights[i] * nm[i] < 0 ? wb2 * std::max(0.0, 1 - nm[i] * nm[i]) : wb2;
      }
      const bool blocking = sw >= kSupportedMass * free;
      if (!blocking) {  // as without supports
        sw = free;
        for (int i = 0; i < 4; ++i) sh.rests[i] = nullptr;
      }
      if (!(sw > 0)) continue;
      for (int i = 0; i < 4; ++i) {
        sh.blocked[i] = blocking && c.weights[i] * nm[i] < 0;
        sh.share[i] = wi[i] * c.weights[i] / sw;
        sh.frictionShare[i] = wi[i] * c.weights[i] / free;
      }
      shares_.push_back(sh);
    }
  }
  // Relative changes dx, dv of one contact, distributed by the shares. A blocked vertex
  // moves in its obstacle's tangent plane only (also when a push or impulse is taken back:
  // the map is linear, a take-back undoes exactly what was given). The push and impulse
  // move any other vertex resting on an obstacle away from it (beta n . m >= 0), and their
  // take-backs never below where the contact started it: left whole. Friction does not
  // move it into its obstacle (`friction`: the one-sided cut, and Share::frictionShare).
  // `moves` false: velocities only.
  const auto apply = [&](const Share& sh, bool friction, const V& dxRelative, const V& dvRelative, bool moves) {
    const Contact& c = *sh.contact;
    const double* share = friction ? sh.frictionShare : sh.share;
    for (int i = 0; i < 4; ++i) {
      const double f = share[i];
      if (f == 0) continue;
      const Index j = c.vertex[i];
      V dx = f * dxRelative, dv = f * dvRelative;
      if (const double* m = sh.rests[i]) {
        const V mv(m[0], m[1], m[2]);
        if (sh.blocked[i]) {
          dx -= dx.dot(mv) * mv;
          dv -= dv.dot(mv) * mv;
        } else if (friction) {
          dx -= std::min(0.0, dx.dot(mv)) * mv;
          dv -= std::min(0.0, dv.dot(mv)) * mv;
        }
      }
      for (int a = 0; a < 3; ++a) v1(j, a) = static_cast<S>(static_cast<double>(v1(j, a)) + dv[a]);
      if (!moves) continue;
      moved_[static_cast<size_t>(j)] = 1;
      touch(j, x1);
      double step2 = 0;
      for (int a = 0; a < 3; ++a) {
        const S before = x1(j, a);
        x1(j, a) = static_cast<S>(static_cast<double>(before) + dx[a]);
        const double d = static_cast<double>(x1(j, a)) - static_cast<double>(before);  // as stored
        step2 += d * d;
      }
      double& total = displacement_[static_cast<size_t>(j)];
      total += std::sqrt(step2);
      largest = std::max(largest, total);
    }
  };
  const auto relative = [&](const Contact& c, const V& n, double* along) {  // relative velocity, and x1 along n
    V vr = V::Zero();
    double s1 = 0;
    for (int i = 0; i < 4; ++i) {
      const Index j = c.vertex[i];
      if (along)
        s1 += c.weights[i] * (static_cast<double>(x1(j, 0)) * n[0] + static_cast<double>(x1(j, 1)) * n[1] +
                              static_cast<double>(x1(j, 2)) * n[2]);
      vr += c.weights[i] * V(v1(j, 0), v1(j, 1), v1(j, 2));
    }
    if (along) *along = s1;
    return vr;
  };
  // Sweep 1: the push to the thickness and the normal impulse that stops the approach.
  for (Share& sh : shares_) {
    const Contact& c = *sh.contact;
    const V n(c.normal[0], c.normal[1], c.normal[2]);
    double s1 = 0;
    const double vn = relative(c, n, &s1).dot(n);
    sh.push = std::max(0.0, c.thickness - s1);
    sh.impulse = vn < 0 ? -vn : 0.0;
    apply(sh, false, sh.push * n, sh.impulse * n, true);
  }
  // Sweeps 2 .. kImpulseSweeps: sequential impulses, each contact's accumulated normal
  // impulse and push kept >= 0. A contact applied after another that shares a vertex may
  // have left that vertex separating, or pushed beyond the thickness (an edge pair moves
  // both its vertices, one of which an earlier contact had already stopped): the earlier
  // contact now takes back what it gave in excess, so a resting layer ends at rest instead
  // of being thrown up by overlapping contacts and falling back (jitter).
  for (int sweep = 1; sweep < kImpulseSweeps; ++sweep) {
    for (Share& sh : shares_) {
      const Contact& c = *sh.contact;
      const V n(c.normal[0], c.normal[1], c.normal[2]);
      double s1 = 0;
      const double vn = relative(c, n, &s1).dot(n);
      const double next = std::max(0.0, sh.impulse - vn);
      const double push = std::max(0.0, sh.push + c.thickness - s1);
      if (next == sh.impulse && push == sh.push) continue;
      apply(sh, false, (push - sh.push) * n, (next - sh.impulse) * n, push != sh.push);
      sh.impulse = next;
      sh.push = push;
    }
  }
  // Friction: the tangential relative velocity, reduced by at most mu x the normal change
  // (the impulse and the push, as a velocity over the chunk). Shared as without supports:
  // a blocked vertex moves in the tangent plane, where friction acts (the normal shares
  // would give the pair more than its relative change, reversing the sliding).
  if (mu > 0) {
    for (Share& sh : shares_) {
      const Contact& c = *sh.contact;
      const V n(c.normal[0], c.normal[1], c.normal[2]);
      const V vr = relative(c, n, nullptr);
      const V vt = vr - vr.dot(n) * n;
      const double vtLength = vt.norm();
      const double budget = mu * (sh.impulse + sh.push / h);
      const double scale = vtLength > 0 ? std::min(1.0, budget / vtLength) : 0.0;
      if (scale == 0) continue;
      const V dvt = -scale * vt;
      apply(sh, true, h * dvt, dvt, true);
    }
  }
  return largest;
}

template <class S>
SelfCollisionStats SelfCollider<S>::resolve(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1,
                                            const ScalarArray<S>& w, double h, const Executor& exec,
                                            const double* supports) {
  SelfCollisionStats stats;
  if (bvh_.triangleCount() < 2) return stats;
  for (const Index j : touched_) touchedFlag_[static_cast<size_t>(j)] = 0;  // (left by a chunk that threw)
  touched_.clear();
  overflowed_ = !resolvePasses(x0, x1, v1, w, h, exec, supports, stats);
  if (overflowed_) {  // the chunk will be retried or the step failed: the last chunk's pushes stay
    for (const Index j : touched_) touchedFlag_[static_cast<size_t>(j)] = 0;
    touched_.clear();
    return stats;
  }
  // What the response and the failsafe did to each vertex they moved (touch): the next
  // gathering's skin covers as much again (kPush). The others were not pushed.
  for (const Index j : lastTouched_)
    for (int a = 0; a < 3; ++a) push_[3 * static_cast<size_t>(j) + static_cast<size_t>(a)] = 0;
  for (const Index j : touched_) {
    for (int a = 0; a < 3; ++a)
      push_[3 * static_cast<size_t>(j) + static_cast<size_t>(a)] =
          static_cast<double>(x1(j, a)) - static_cast<double>(unpushed_(j, a));
    touchedFlag_[static_cast<size_t>(j)] = 0;
  }
  lastTouched_.swap(touched_);
  touched_.clear();
  return stats;
}

template <class S>
bool SelfCollider<S>::resolvePasses(const Vec3Array<S>& x0, Vec3Array<S>& x1, Vec3Array<S>& v1, const ScalarArray<S>& w,
                                    double h, const Executor& exec, const double* supports, SelfCollisionStats& stats) {
  for (int pass = 0;; ++pass) {
    const bool last = pass == options_.iterations;  // then the failsafe acts on what this pass finds
    onlyMoved_ = pass > 0;
    if (!detect(x0, x1, w, exec, stats)) return false;
    std::fill(moved_.begin(), moved_.end(), std::uint8_t{0});
    bool any = false, guards = false;
    double margin = std::numeric_limits<double>::infinity();
    for (Index k = 0; k < blocksUsed_; ++k) {
      const Block& block = blocks_[static_cast<size_t>(k)];
      any = any || !block.contacts.empty();
      guards = guards || block.guards > 0;
      margin = std::min(margin, block.margin);
    }
    if (!any) return true;                       // no pair within the thickness / 2: nothing can intersect
    margin = std::min(margin, 0.5 * thinnest_);  // (the pairs not in contact: proven >= their thickness / 2)
    if (!last) {
      // Converged: no pair came within its failsafe threshold, so every pair stayed at
      // least `margin` apart over the chunk, and the response moved no vertex by more than
      // a quarter of that (a distance changes by at most twice the largest displacement):
      // nothing intersects, and further passes would only move vertices by less.
      const double moved = respond(x1, v1, w, h, supports, stats);
      if (!guards && 2 * moved < 0.5 * margin) return true;
      continue;
    }
    break;
  }
  // The failsafe: stop the free vertices of every pair that came too close, until none does.
  std::fill(frozen_.begin(), frozen_.end(), std::uint8_t{0});
  bool counted = false;
  for (;;) {
    std::int64_t stopped = 0, stuck = 0, hits = 0;
    for (Index k = 0; k < blocksUsed_; ++k) {
      for (const Contact& c : blocks_[static_cast<size_t>(k)].contacts) {
        if (!c.guard) continue;
        ++hits;
        bool any = false;
        for (int i = 0; i < 4; ++i) {
          const Index j = c.vertex[i];
          if (w[j] == S(0) || frozen_[static_cast<size_t>(j)]) continue;
          frozen_[static_cast<size_t>(j)] = 1;
          moved_[static_cast<size_t>(j)] = 1;
          touch(j, x1);
          for (int a = 0; a < 3; ++a) {
            x1(j, a) = x0(j, a);
            v1(j, a) = S(0);
          }
          ++stopped;
          any = true;
        }
        stuck += any ? 0 : 1;
      }
    }
    if (hits == 0) break;
    if (!counted) {
      ++stats.failsafeChunks;
      counted = true;
    }
    stats.frozen += stopped;
    if (stopped == 0) {
      stats.unresolved += stuck;
      break;
    }
    onlyMoved_ = true;
    if (!detect(x0, x1, w, exec, stats)) return false;
    std::fill(moved_.begin(), moved_.end(), std::uint8_t{0});
  }
  return true;
}

template class SelfCollider<float>;
template class SelfCollider<double>;

}  // namespace weft
