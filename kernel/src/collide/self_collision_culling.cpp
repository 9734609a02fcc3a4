// The self-collision pass's culling of flat regions (see weft/collide/self_collision.hpp,
// "flat regions"): which BVH nodes are edge-connected, found once, and the normal cones of
// every node at each gathering.
#include <algorithm>
#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include "collide/self_collider.hpp"
#include "weft/collide/self_collision.hpp"

namespace weft {

namespace {

using V = Vec3<double>;

/// The smallest cone holding two cones narrower than a half space (cos > 0), or a cone with
/// cos <= 0 when that is a half space or more. Containment is decided on cosines; only a
/// true merge takes angles.
template <class Cone>
Cone mergedCone(const Cone& a, const Cone& b) {
  Cone wide{{0, 0, 1}, -1, 0};
  if (!(a.cos > 0 && b.cos > 0)) return wide;
  const V ua(a.axis[0], a.axis[1], a.axis[2]), ub(b.axis[0], b.axis[1], b.axis[2]);
  const double cg = std::clamp(ua.dot(ub), -1.0, 1.0);
  const V across = ua.cross(ub);
  const double sg = across.norm();
  // a holds b when angle(a, b) + half(b) <= half(a): cos(angle + half(b)) >= cos(half(a)).
  if (cg * b.cos - sg * b.sin >= a.cos) return a;
  if (cg * a.cos - sg * a.sin >= b.cos) return b;
  const double angleA = std::atan2(a.sin, a.cos), angleB = std::atan2(b.sin, b.cos), gamma = std::atan2(sg, cg);
  const double half = 0.5 * (angleA + angleB + gamma);
  if (!(half < 0.5 * M_PI) || !(sg > 0)) return wide;
  // The axis: a turned towards b by half - angleA, in the plane of the two.
  const V towards = (ub - cg * ua) / sg;
  const double turn = half - angleA;
  const V axis = (std::cos(turn) * ua + std::sin(turn) * towards).normalized();
  // (1e-12: rounding in the rotation; the cone is then a hair wider than the exact one.)
  return {{axis[0], axis[1], axis[2]}, std::cos(half + 1e-12), std::sin(half + 1e-12)};
}

}  // namespace

template <class S>
void SelfCollider<S>::findConnectedNodes() {
  const std::vector<BvhNode<S>>& nodes = bvh_.nodes();
  const Index nodeCount = static_cast<Index>(nodes.size()), triangles = bvh_.triangleCount();
  // Each node's last slot (its slots are a contiguous range; children follow their parent
  // in pre-order, so a reverse sweep sees children first).
  std::vector<Index> lastSlot(static_cast<size_t>(nodeCount));
  for (Index q = nodeCount - 1; q >= 0; --q) {
    const Index c = nodes[static_cast<size_t>(q)].child[1];
    lastSlot[static_cast<size_t>(q)] = c < 0 ? ~c : lastSlot[static_cast<size_t>(c)];
  }
  std::vector<Index> slotOf(static_cast<size_t>(triangles));
  for (Index s = 0; s < triangles; ++s) slotOf[static_cast<size_t>(bvh_.slotTriangle(s))] = s;
  // Triangles sharing an edge: sort (edge, triangle) and join neighbours in the order.
  const Triangles& tr = model_->triangles();
  std::vector<std::pair<std::uint64_t, Index>> sides;
  sides.reserve(3 * static_cast<size_t>(triangles));
  for (Index t = 0; t < triangles; ++t) {
    const Index c[3] = {tr.a[t], tr.b[t], tr.c[t]};
    for (int k = 0; k < 3; ++k) {
      const auto lo = static_cast<std::uint64_t>(std::min(c[k], c[(k + 1) % 3]));
      const auto hi = static_cast<std::uint64_t>(std::max(c[k], c[(k + 1) % 3]));
      sides.emplace_back(lo << 32 | hi, t);
    }
  }
  std::sort(sides.begin(), sides.end());
  // Each edge joins its two triangles in their lowest common node. Bottom-up (reverse
  // pre-order: a subtree before its root), a union-find over the slots counts the merges
  // made in each node's subtree: the node is connected when its slots minus those merges
  // leave one component.
  std::vector<std::pair<Index, std::array<Index, 2>>> joins;  // (node, slots)
  joins.reserve(sides.size());
  for (size_t k = 1; k < sides.size(); ++k) {
    if (sides[k].first != sides[k - 1].first) continue;
    const Index s1 = slotOf[static_cast<size_t>(sides[k - 1].second)],
                s2 = slotOf[static_cast<size_t>(sides[k].second)];
    if (s1 == s2) continue;
    Index q = 0;
    for (;;) {
      const Index left = nodes[static_cast<size_t>(q)].child[0];
      const Index leftLast = left < 0 ? ~left : lastSlot[static_cast<size_t>(left)];
      const bool first = s1 <= leftLast, second = s2 <= leftLast;
      if (first != second) break;
      q = first ? left : nodes[static_cast<size_t>(q)].child[1];  // (internal: the two slots differ)
    }
    joins.push_back({q, {s1, s2}});
  }
  std::sort(joins.begin(), joins.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Index> parent(static_cast<size_t>(triangles));
  for (Index s = 0; s < triangles; ++s) parent[static_cast<size_t>(s)] = s;
  const auto root = [&](Index s) {
    while (parent[static_cast<size_t>(s)] != s) {
      parent[static_cast<size_t>(s)] = parent[static_cast<size_t>(parent[static_cast<size_t>(s)])];
      s = parent[static_cast<size_t>(s)];
    }
    return s;
  };
  std::vector<Index> components(static_cast<size_t>(nodeCount));  // in each node's subtree
  connected_.assign(static_cast<size_t>(nodeCount), 0);
  size_t next = 0;
  for (Index q = nodeCount - 1; q >= 0; --q) {
    Index count = 0;
    for (const Index c : nodes[static_cast<size_t>(q)].child) count += c < 0 ? 1 : components[static_cast<size_t>(c)];
    for (; next < joins.size() && joins[next].first == q; ++next) {
      const Index a = root(joins[next].second[0]), b = root(joins[next].second[1]);
      if (a == b) continue;
      parent[static_cast<size_t>(std::max(a, b))] = std::min(a, b);
      --count;
    }
    components[static_cast<size_t>(q)] = count;
    connected_[static_cast<size_t>(q)] = count == 1 ? 1 : 0;
  }
}

template <class S>
void SelfCollider<S>::findFlatRegions(const Executor& exec) {
  const Triangles& tr = model_->triangles();
  // Leaf cones: the normal at the boxes' centres, widened by the most the corners can turn
  // it anywhere in their boxes (|n' - n| <= |d1| |e2| + |e1| |d2| + |d1| |d2|). A block of
  // slots at a time: the corners' box centres and squared radii gathered into columns,
  // then the cones computed down the columns without a branch (the compiler vectorises
  // it: a leaf takes seven square roots and four divisions), then stored.
  const Index triangles = bvh_.triangleCount();
  exec.parallelFor(triangles, kConeBlock, [&](Index begin, Index end) {
    for (Index b0 = begin; b0 < end; b0 += kConeBlock) {
      const int m = static_cast<int>(std::min(kConeBlock, end - b0));
      alignas(64) double cx[3][kConeBlock], cy[3][kConeBlock], cz[3][kConeBlock], r2[3][kConeBlock];
      for (int i = 0; i < m; ++i) {
        const Index t = bvh_.slotTriangle(b0 + i);
        const Index c[3] = {tr.a[t], tr.b[t], tr.c[t]};
        for (int k = 0; k < 3; ++k) {
          const Aabb<S>& box = skinBox_[static_cast<size_t>(c[k])];
          double centre[3], sum = 0;
          for (int a = 0; a < 3; ++a) {
            const double lo = static_cast<double>(box.lo[a]), hi = static_cast<double>(box.hi[a]);
            centre[a] = 0.5 * (lo + hi);
            sum += 0.25 * (hi - lo) * (hi - lo);
          }
          cx[k][i] = centre[0];
          cy[k][i] = centre[1];
          cz[k][i] = centre[2];
          r2[k][i] = sum;
        }
      }
      alignas(64) double ax[kConeBlock], ay[kConeBlock], az[kConeBlock], cosine[kConeBlock], sine[kConeBlock];
      for (int i = 0; i < m; ++i) {
        const double e1x = cx[1][i] - cx[0][i], e1y = cy[1][i] - cy[0][i], e1z = cz[1][i] - cz[0][i];
        const double e2x = cx[2][i] - cx[0][i], e2y = cy[2][i] - cy[0][i], e2z = cz[2][i] - cz[0][i];
        const double nx = e1y * e2z - e1z * e2y, ny = e1z * e2x - e1x * e2z, nz = e1x * e2y - e1y * e2x;
        const double length = std::sqrt(nx * nx + ny * ny + nz * nz);
        const double r0 = std::sqrt(r2[0][i]), d1 = r0 + std::sqrt(r2[1][i]), d2 = r0 + std::sqrt(r2[2][i]);
        const double e1 = std::sqrt(e1x * e1x + e1y * e1y + e1z * e1z);
        const double e2 = std::sqrt(e2x * e2x + e2y * e2y + e2z * e2z);
        const double turn = d1 * e2 + e1 * d2 + d1 * d2;
        const bool narrow = turn < length;  // (false for NaN)
        const double sn = turn / length;
        // (1 - sn^2 < 0 only where the cone is not narrow: its square root is not kept.)
        const double cs = std::sqrt(std::max(0.0, 1 - sn * sn));
        ax[i] = narrow ? nx / length : 0.0;
        ay[i] = narrow ? ny / length : 0.0;
        az[i] = narrow ? nz / length : 1.0;
        cosine[i] = narrow ? cs : -1.0;
        sine[i] = narrow ? sn : 0.0;
      }
      for (int i = 0; i < m; ++i) leafCones_[static_cast<size_t>(b0 + i)] = {{ax[i], ay[i], az[i]}, cosine[i], sine[i]};
    }
  });
  // Node cones, children before parents: the axis bisects the children's, and the
  // half-angle covers each child's cone about it. A node is flat when its cone is narrower
  // than a half space and its triangles are connected.
  const std::vector<BvhNode<S>>& nodes = bvh_.nodes();
  const auto nodeCone = [&](Index q) {
    const BvhNode<S>& node = nodes[static_cast<size_t>(q)];
    const Cone* child[2];
    for (int k = 0; k < 2; ++k)
      child[k] = node.child[k] < 0 ? &leafCones_[static_cast<size_t>(~node.child[k])]
                                   : &cones_[static_cast<size_t>(node.child[k])];
    Cone& cone = cones_[static_cast<size_t>(q)];
    cone = mergedCone(*child[0], *child[1]);
    flat_[static_cast<size_t>(q)] = connected_[static_cast<size_t>(q)] != 0 && cone.cos > 0;
  };
  bvh_.bottomUp(
      exec, [](Index) {}, nodeCone);  // (the leaves are done)
}

template void SelfCollider<float>::findConnectedNodes();
template void SelfCollider<double>::findConnectedNodes();
template void SelfCollider<float>::findFlatRegions(const Executor&);
template void SelfCollider<double>::findFlatRegions(const Executor&);

}  // namespace weft
