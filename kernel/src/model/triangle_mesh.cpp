#include "weft/model/triangle_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "core/text.hpp"

namespace weft {

namespace {

constexpr const char* kWhere = "cleanMesh";

using detail::number;

/// "1 vertex" / "3 vertices".
std::string counted(Index n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

/// Union-find whose root is the smallest member (the lexicographically smallest position,
/// since point ids are assigned in lexicographic order).
class SmallestRootSets {
 public:
  explicit SmallestRootSets(Index n) : parent_(static_cast<size_t>(n)) {
    for (Index i = 0; i < n; ++i) parent_[i] = i;
  }
  Index find(Index i) {
    while (parent_[i] != i) {
      parent_[i] = parent_[parent_[i]];  // path halving
      i = parent_[i];
    }
    return i;
  }
  void unite(Index a, Index b) {
    a = find(a);
    b = find(b);
    if (a < b)
      parent_[b] = a;
    else if (b < a)
      parent_[a] = b;
  }

 private:
  std::vector<Index> parent_;
};

using CellKey = std::array<std::int64_t, 3>;

/// Grid cell of coordinate x for cells of size h. Clamping keeps huge quotients (and the
/// infinity of x / h overflowing) representable; it is monotonic and never increases a
/// difference, so two points within one cell size stay in the same or adjacent cells.
std::int64_t cellOf(double x, double h) {
  constexpr double kLimit = 4611686018427387904.0;  // 2^62: key +- 1 cannot overflow
  const double q = std::floor(x / h);
  return static_cast<std::int64_t>(std::clamp(q, -kLimit, kLimit));
}

bool withinTolerance(const Vec3d& p, const Vec3d& q, double tolerance) {
  const double dx = (p.x - q.x) / tolerance, dy = (p.y - q.y) / tolerance, dz = (p.z - q.z) / tolerance;
  if (!(std::abs(dx) <= 1 && std::abs(dy) <= 1 && std::abs(dz) <= 1)) return false;
  return dx * dx + dy * dy + dz * dz <= 1;
}

/// Joins, in `sets`, every pair of points closer than `tolerance` (> 0).
void weldWithinTolerance(const std::vector<Vec3d>& points, double tolerance, SmallestRootSets& sets) {
  const Index u = static_cast<Index>(points.size());
  const double h = 2 * tolerance;  // points within tolerance differ by at most one cell per axis
  std::vector<std::pair<CellKey, Index>> byCell(static_cast<size_t>(u));
  for (Index p = 0; p < u; ++p)
    byCell[p] = {{cellOf(points[p].x, h), cellOf(points[p].y, h), cellOf(points[p].z, h)}, p};
  std::sort(byCell.begin(), byCell.end());
  // Cells as [begin, end) ranges of byCell.
  struct Cell {
    CellKey key;
    size_t begin, end;
  };
  std::vector<Cell> cells;
  for (size_t i = 0; i < byCell.size();) {
    size_t j = i;
    while (j < byCell.size() && byCell[j].first == byCell[i].first) ++j;
    cells.push_back({byCell[i].first, i, j});
    i = j;
  }
  const auto findCell = [&cells](const CellKey& key) -> const Cell* {
    const auto it =
        std::lower_bound(cells.begin(), cells.end(), key, [](const Cell& c, const CellKey& k) { return c.key < k; });
    return (it != cells.end() && it->key == key) ? &*it : nullptr;
  };
  for (const Cell& cell : cells) {
    // Each unordered pair of cells once: the cell itself and the 13 neighbours after it.
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const CellKey offset{dx, dy, dz};
          if (offset < CellKey{0, 0, 0}) continue;
          const bool self = offset == CellKey{0, 0, 0};
          const Cell* other = self ? &cell : findCell({cell.key[0] + dx, cell.key[1] + dy, cell.key[2] + dz});
          if (other == nullptr) continue;
          for (size_t i = cell.begin; i < cell.end; ++i)
            for (size_t j = self ? i + 1 : other->begin; j < other->end; ++j) {
              const Index a = byCell[i].second, b = byCell[j].second;
              if (withinTolerance(points[a], points[b], tolerance)) sets.unite(a, b);
            }
        }
  }
}

/// True if the triangle (a, b, c) of distinct positions has (almost) no area.
bool flat(const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  double e1[3] = {b.x - a.x, b.y - a.y, b.z - a.z};
  double e2[3] = {c.x - a.x, c.y - a.y, c.z - a.z};
  // Scale by the largest component so that squares neither overflow nor underflow.
  double s = 0;
  for (int k = 0; k < 3; ++k) s = std::max({s, std::abs(e1[k]), std::abs(e2[k])});
  if (!(s > 0)) return true;
  if (!std::isfinite(s)) return false;  // astronomically large: not ours to judge (the cloth builder rejects it)
  for (int k = 0; k < 3; ++k) {
    e1[k] /= s;
    e2[k] /= s;
  }
  const double e3[3] = {e2[0] - e1[0], e2[1] - e1[1], e2[2] - e1[2]};
  const double cx = e1[1] * e2[2] - e1[2] * e2[1];
  const double cy = e1[2] * e2[0] - e1[0] * e2[2];
  const double cz = e1[0] * e2[1] - e1[1] * e2[0];
  const double twiceArea = std::sqrt(cx * cx + cy * cy + cz * cz);
  const auto squared = [](const double* e) { return e[0] * e[0] + e[1] * e[1] + e[2] * e[2]; };
  const double longest2 = std::max({squared(e1), squared(e2), squared(e3)});
  return twiceArea <= kDegenerateRelativeArea * longest2;
}

}  // namespace

std::string MeshReport::summary() const {
  std::string text =
      counted(inputVertices, "vertex", "vertices") + ", " + counted(inputTriangles, "triangle", "triangles") + " in; " +
      counted(outputVertices, "vertex", "vertices") + ", " + counted(outputTriangles, "triangle", "triangles") + " out";
  const auto add = [&text](Index n, const char* one, const char* many) {
    if (n != 0) text += "; " + counted(n, one, many);
  };
  add(weldedVertices, "welded vertex", "welded vertices");
  add(unreferencedVertices, "unreferenced vertex dropped", "unreferenced vertices dropped");
  add(degenerateTriangles, "degenerate triangle dropped", "degenerate triangles dropped");
  add(duplicateTriangles, "duplicate triangle dropped", "duplicate triangles dropped");
  add(nonManifoldEdges, "non-manifold edge", "non-manifold edges");
  add(boundaryEdges, "boundary edge", "boundary edges");
  const auto ignored = [&text](std::int64_t n, const char* one, const char* many) {
    if (n != 0) text += "; " + std::to_string(n) + " " + (n == 1 ? one : many);
  };
  ignored(ignoredPoints, "point ignored", "points ignored");
  ignored(ignoredLines, "line ignored", "lines ignored");
  ignored(emptyFaces, "face with no corner ignored", "faces with no corner ignored");
  return text;
}

TriangleMesh cleanMesh(const TriangleMesh& raw, const MeshCleanOptions& options, MeshReport* report) {
  const double tolerance = options.weldTolerance;
  if (!(std::isfinite(tolerance) && tolerance >= 0))
    throw std::invalid_argument(
        std::string(kWhere) + ": MeshCleanOptions.weldTolerance must be finite and >= 0 (m), got " + number(tolerance));
  constexpr size_t kMaxCount = static_cast<size_t>(std::numeric_limits<Index>::max());
  if (raw.vertices.size() > kMaxCount || raw.triangles.size() > kMaxCount)
    throw std::invalid_argument(std::string(kWhere) + ": the mesh has " + std::to_string(raw.vertices.size()) +
                                " vertices and " + std::to_string(raw.triangles.size()) + " triangles; at most " +
                                std::to_string(kMaxCount) + " of each are supported");
  const Index n = static_cast<Index>(raw.vertices.size());
  const Index nt = static_cast<Index>(raw.triangles.size());

  // 1. Validation.
  for (Index i = 0; i < n; ++i) {
    const Vec3d& v = raw.vertices[i];
    const double coordinate[3] = {v.x, v.y, v.z};
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(coordinate[k]))
        throw std::invalid_argument(std::string(kWhere) + ": vertices[" + std::to_string(i) + "]." + "xyz"[k] +
                                    " must be finite, got " + number(coordinate[k]));
  }
  for (Index t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) {
      const Index v = raw.triangles[t][k];
      if (v < 0 || v >= n)
        throw std::invalid_argument(std::string(kWhere) + ": triangles[" + std::to_string(t) + "][" +
                                    std::to_string(k) + "] must be a vertex index in [0, " + std::to_string(n) +
                                    "), got " + std::to_string(v));
    }
  if (nt == 0)
    throw std::invalid_argument(std::string(kWhere) + ": mesh has no triangles (triangles is empty; " +
                                counted(n, "vertex", "vertices") + ")");

  // 2. Welding. Identical positions first (one sort; -0 becomes +0 so it sorts with 0),
  // giving the distinct points in lexicographic order; then points within the tolerance.
  std::vector<Vec3d> position(static_cast<size_t>(n));
  for (Index i = 0; i < n; ++i)
    position[i] = {raw.vertices[i].x + 0.0, raw.vertices[i].y + 0.0, raw.vertices[i].z + 0.0};
  const auto key = [&position](Index i) { return std::tie(position[i].x, position[i].y, position[i].z); };
  std::vector<Index> order(static_cast<size_t>(n));
  for (Index i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&key](Index a, Index b) { return std::tuple(key(a), a) < std::tuple(key(b), b); });
  std::vector<Index> pointOf(static_cast<size_t>(n));
  std::vector<Vec3d> points;
  for (Index k = 0; k < n; ++k) {
    const Index i = order[k];
    if (k == 0 || key(order[k - 1]) != key(i)) points.push_back(position[i]);
    pointOf[i] = static_cast<Index>(points.size()) - 1;
  }
  const Index pointCount = static_cast<Index>(points.size());
  SmallestRootSets sets(pointCount);
  if (tolerance > 0) weldWithinTolerance(points, tolerance, sets);
  std::vector<Index> groupOf(static_cast<size_t>(n));  // vertex -> its group's root point
  Index groups = 0;
  for (Index p = 0; p < pointCount; ++p) groups += sets.find(p) == p ? 1 : 0;
  for (Index i = 0; i < n; ++i) groupOf[i] = sets.find(pointOf[i]);

  // 3. Degenerate and duplicate triangles.
  MeshReport r;
  r.inputVertices = n;
  r.inputTriangles = nt;
  r.weldedVertices = n - groups;
  std::vector<char> keep(static_cast<size_t>(nt), 0);
  std::vector<std::pair<std::array<Index, 3>, Index>> sortedCorners;  // (sorted groups, triangle)
  sortedCorners.reserve(static_cast<size_t>(nt));
  for (Index t = 0; t < nt; ++t) {
    std::array<Index, 3> g{groupOf[raw.triangles[t][0]], groupOf[raw.triangles[t][1]], groupOf[raw.triangles[t][2]]};
    if (g[0] == g[1] || g[1] == g[2] || g[0] == g[2] || flat(points[g[0]], points[g[1]], points[g[2]])) {
      ++r.degenerateTriangles;
      continue;
    }
    std::sort(g.begin(), g.end());
    sortedCorners.push_back({g, t});
  }
  std::sort(sortedCorners.begin(), sortedCorners.end());
  for (size_t k = 0; k < sortedCorners.size(); ++k) {
    if (k > 0 && sortedCorners[k].first == sortedCorners[k - 1].first)
      ++r.duplicateTriangles;
    else
      keep[sortedCorners[k].second] = 1;
  }

  // 4. Referenced groups, numbered in the order of their first member in the input.
  std::vector<char> referenced(static_cast<size_t>(pointCount), 0);
  for (Index t = 0; t < nt; ++t)
    if (keep[t])
      for (int k = 0; k < 3; ++k) referenced[groupOf[raw.triangles[t][k]]] = 1;
  TriangleMesh out;
  std::vector<Index> outIndex(static_cast<size_t>(pointCount), -1);
  for (Index i = 0; i < n; ++i) {
    const Index g = groupOf[i];
    if (referenced[g] && outIndex[g] < 0) {
      outIndex[g] = static_cast<Index>(out.vertices.size());
      out.vertices.push_back(points[g]);
    }
  }
  for (Index t = 0; t < nt; ++t)
    if (keep[t])
      out.triangles.push_back({outIndex[groupOf[raw.triangles[t][0]]], outIndex[groupOf[raw.triangles[t][1]]],
                               outIndex[groupOf[raw.triangles[t][2]]]});
  r.outputVertices = static_cast<Index>(out.vertices.size());
  r.outputTriangles = static_cast<Index>(out.triangles.size());
  r.unreferencedVertices = groups - r.outputVertices;

  // 5. Boundary and non-manifold edges.
  std::vector<std::uint64_t> edges;
  edges.reserve(3 * out.triangles.size());
  for (const auto& tri : out.triangles)
    for (int k = 0; k < 3; ++k) {
      const auto a = static_cast<std::uint64_t>(tri[k]), b = static_cast<std::uint64_t>(tri[(k + 1) % 3]);
      edges.push_back(std::min(a, b) << 32 | std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i == 1) ++r.boundaryEdges;
    if (j - i > 2) ++r.nonManifoldEdges;
    i = j;
  }

  if (report != nullptr) *report = r;
  if (r.outputTriangles == 0)
    throw std::invalid_argument(
        std::string(kWhere) + ": mesh has no triangles after cleaning: " + std::to_string(r.degenerateTriangles) +
        " degenerate and " + std::to_string(r.duplicateTriangles) + " duplicate of " +
        counted(nt, "input triangle", "input triangles") + " (weldTolerance " + number(tolerance) + " m)");
  return out;
}

}  // namespace weft
