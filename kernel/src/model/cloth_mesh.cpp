#include "weft/model/cloth_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/text.hpp"
#include "precision_limits.hpp"

namespace weft {

namespace {

constexpr const char* kWhere = "addClothMesh";

using detail::number;

[[noreturn]] void reject(const std::string& field, double value, const std::string& rule) {
  detail::rejectField(std::string(kWhere) + ": " + field, value, rule);
}

/// A spring material, also within the range of the builder's precision S (so that what
/// addClothMesh accepts, ModelBuilder<S>::build() accepts too).
template <class S>
void checkMaterial(const char* name, const SpringMaterial& m) {
  using Limits = detail::PrecisionLimits<S>;
  const std::string range =
      std::string(" and at most ") + detail::number(Limits::kLargest) + " in " + Limits::kName + " precision";
  if (!(std::isfinite(m.stiffness) && m.stiffness >= 0 && Limits::representable(m.stiffness)))
    reject(std::string("ClothMeshSpec.") + name + ".stiffness", m.stiffness, "finite and >= 0 (N/m)" + range);
  if (!(std::isfinite(m.damping) && m.damping >= 0 && Limits::representable(m.damping)))
    reject(std::string("ClothMeshSpec.") + name + ".damping", m.damping, "finite and >= 0 (N s/m)" + range);
}

std::uint64_t edgeKey(Index a, Index b) {
  const auto lo = static_cast<std::uint64_t>(std::min(a, b)), hi = static_cast<std::uint64_t>(std::max(a, b));
  return lo << 32 | hi;
}

}  // namespace

template <class S>
ClothMeshStats addClothMesh(ModelBuilder<S>& builder, const TriangleMesh& mesh, const ClothMeshSpec& spec) {
  // --- The spec.
  if (!(std::isfinite(spec.arealDensity) && spec.arealDensity >= 0))
    reject("ClothMeshSpec.arealDensity", spec.arealDensity, "finite and >= 0 (kg/m^2)");
  if (spec.arealDensity == 0 && !(std::isfinite(spec.totalMass) && spec.totalMass > 0))
    reject("ClothMeshSpec.totalMass", spec.totalMass, "finite and > 0 (kg) when arealDensity is 0");
  if (!(std::isfinite(spec.scale) && spec.scale > 0)) reject("ClothMeshSpec.scale", spec.scale, "finite and > 0");
  if (!std::isfinite(spec.translate.x)) reject("ClothMeshSpec.translate.x", spec.translate.x, "finite (m)");
  if (!std::isfinite(spec.translate.y)) reject("ClothMeshSpec.translate.y", spec.translate.y, "finite (m)");
  if (!std::isfinite(spec.translate.z)) reject("ClothMeshSpec.translate.z", spec.translate.z, "finite (m)");
  checkMaterial<S>("structural", spec.structural);
  if (spec.bendSprings) checkMaterial<S>("bend", spec.bend);
  using Limits = detail::PrecisionLimits<S>;

  // --- The mesh.
  const Index first = builder.particleCount();
  constexpr long long kMaxIndex = std::numeric_limits<Index>::max();
  if (static_cast<long long>(mesh.vertices.size()) > kMaxIndex - first ||
      static_cast<long long>(mesh.triangles.size()) > kMaxIndex / 3)
    throw std::invalid_argument(std::string(kWhere) + ": the mesh has " + std::to_string(mesh.vertices.size()) +
                                " vertices and " + std::to_string(mesh.triangles.size()) +
                                " triangles, too many for 32-bit particle and spring indices");
  const Index n = static_cast<Index>(mesh.vertices.size());
  const Index nt = static_cast<Index>(mesh.triangles.size());
  if (nt == 0)
    throw std::invalid_argument(std::string(kWhere) + ": mesh has no triangles (triangles is empty; " +
                                std::to_string(n) + " vertices)");
  std::vector<Vec3d> p(static_cast<size_t>(n));
  for (Index i = 0; i < n; ++i) {
    const Vec3d& v = mesh.vertices[i];
    const double in[3] = {v.x, v.y, v.z};
    const double shift[3] = {spec.translate.x, spec.translate.y, spec.translate.z};
    double out[3];
    for (int k = 0; k < 3; ++k) {
      const std::string field = "mesh vertices[" + std::to_string(i) + "]." + "xyz"[k];
      if (!std::isfinite(in[k])) reject(field, in[k], "finite (m)");
      out[k] = spec.scale * in[k] + shift[k];
      if (!std::isfinite(out[k])) reject(field + " scaled and translated", out[k], "finite (m)");
      if (!Limits::coordinate(out[k]))
        reject(field + (spec.scale == 1 && shift[k] == 0 ? "" : " scaled and translated"), out[k],
               Limits::coordinateRule());
    }
    p[i] = {out[0], out[1], out[2]};
  }
  for (Index t = 0; t < nt; ++t) {
    const auto& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k)
      if (tri[k] < 0 || tri[k] >= n)
        throw std::invalid_argument(std::string(kWhere) + ": mesh triangles[" + std::to_string(t) + "][" +
                                    std::to_string(k) + "] must be a vertex index in [0, " + std::to_string(n) +
                                    "), got " + std::to_string(tri[k]));
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2])
      throw std::invalid_argument(std::string(kWhere) + ": mesh triangles[" + std::to_string(t) +
                                  "] must have three distinct corners, got (" + std::to_string(tri[0]) + ", " +
                                  std::to_string(tri[1]) + ", " + std::to_string(tri[2]) +
                                  "); clean the mesh with cleanMesh first");
  }

  // --- Lumped masses: a third of each triangle's area to each of its corners.
  std::vector<double> vertexArea(static_cast<size_t>(n), 0.0);
  double area = 0;
  for (const auto& tri : mesh.triangles) {
    const Vec3d &a = p[tri[0]], &b = p[tri[1]], &c = p[tri[2]];
    const double ux = b.x - a.x, uy = b.y - a.y, uz = b.z - a.z;
    const double vx = c.x - a.x, vy = c.y - a.y, vz = c.z - a.z;
    const double cx = uy * vz - uz * vy, cy = uz * vx - ux * vz, cz = ux * vy - uy * vx;
    const double third = std::sqrt(cx * cx + cy * cy + cz * cz) / 6;
    for (int k = 0; k < 3; ++k) vertexArea[tri[k]] += third;
    area += 3 * third;
  }
  if (!(std::isfinite(area) && area > 0)) reject("total area of the mesh", area, "finite and > 0 (m^2)");
  const double density = spec.arealDensity > 0 ? spec.arealDensity : spec.totalMass / area;
  std::vector<double> mass(static_cast<size_t>(n));
  for (Index i = 0; i < n; ++i) {
    if (!(vertexArea[i] > 0))
      throw std::invalid_argument(std::string(kWhere) + ": mesh vertices[" + std::to_string(i) +
                                  "] has no triangle area, got " + number(vertexArea[i]) +
                                  " m^2 (no triangle uses it, or only zero-area ones): it would have no mass; "
                                  "clean the mesh with cleanMesh first");
    mass[i] = density * vertexArea[i];
    if (!(std::isfinite(mass[i]) && mass[i] > 0))
      reject("mass of mesh vertices[" + std::to_string(i) + "] (density * area / 3)", mass[i], "finite and > 0 (kg)");
    if (!(Limits::representable(mass[i]) && Limits::invertibleMass(mass[i])))
      reject("mass of mesh vertices[" + std::to_string(i) + "] (density * area / 3)", mass[i],
             std::string("such that it and 1/mass are finite in ") + Limits::kName +
                 " precision (the triangles around it are too small or too large for it)");
  }

  // --- Edges: (key, opposite corner) per triangle side, sorted; one run per unique edge.
  std::vector<std::pair<std::uint64_t, Index>> sides;
  sides.reserve(3 * static_cast<size_t>(nt));
  for (const auto& tri : mesh.triangles)
    for (int k = 0; k < 3; ++k) sides.push_back({edgeKey(tri[k], tri[(k + 1) % 3]), tri[(k + 2) % 3]});
  std::sort(sides.begin(), sides.end());
  std::vector<std::uint64_t> edges;                     // unique edges, sorted
  std::vector<std::pair<std::uint64_t, Index>> hinges;  // (opposite pair, order) of interior edges
  for (size_t i = 0; i < sides.size();) {
    size_t j = i;
    while (j < sides.size() && sides[j].first == sides[i].first) ++j;
    edges.push_back(sides[i].first);
    if (j - i == 2 && sides[i].second != sides[i + 1].second)
      hinges.push_back({edgeKey(sides[i].second, sides[i + 1].second), static_cast<Index>(hinges.size())});
    i = j;
  }
  // A bend spring joins a hinge pair not joined already: by an edge, or by an earlier
  // hinge (two interior edges with the same opposite pair, e.g. around a valence-3 vertex).
  // bendPairs: (order of the hinge's edge, pair key), sorted back into edge order.
  std::vector<std::pair<Index, std::uint64_t>> bendPairs;
  if (spec.bendSprings) {
    std::sort(hinges.begin(), hinges.end());
    for (size_t k = 0; k < hinges.size(); ++k) {
      const bool repeated = k > 0 && hinges[k].first == hinges[k - 1].first;
      if (!repeated && !std::binary_search(edges.begin(), edges.end(), hinges[k].first))
        bendPairs.push_back({hinges[k].second, hinges[k].first});
    }
    std::sort(bendPairs.begin(), bendPairs.end());
  }

  // --- Every spring's length kept under rounding to S (ModelBuilder::build's rule, checked
  // here so that the message names the mesh's vertices).
  const auto resolved = [&](std::uint64_t key, const char* kind) {
    const Index i = static_cast<Index>(key >> 32), j = static_cast<Index>(key & 0xffffffffu);
    const Vec3d &a = p[static_cast<size_t>(i)], &b = p[static_cast<size_t>(j)];
    const double rest = std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) + (a.z - b.z) * (a.z - b.z));
    const double farthest =
        std::max({std::abs(a.x), std::abs(a.y), std::abs(a.z), std::abs(b.x), std::abs(b.y), std::abs(b.z)});
    if (!Limits::springResolved(rest, farthest))
      reject(std::string("the largest |coordinate| of the ends of the ") + kind + " spring between mesh vertices[" +
                 std::to_string(i) + "] and vertices[" + std::to_string(j) + "]" +
                 (spec.scale == 1 && spec.translate.x == 0 && spec.translate.y == 0 && spec.translate.z == 0
                      ? ""
                      : " (scaled and translated)"),
             farthest, Limits::springRule(rest));
  };
  for (const std::uint64_t e : edges) resolved(e, "structural");
  for (const auto& pair : bendPairs) resolved(pair.second, "bend");

  // --- Add: particles, structural springs, bend springs, triangles.
  ClothMeshStats stats;
  stats.firstParticle = first;
  stats.area = area;
  for (Index i = 0; i < n; ++i) builder.addParticle(p[i], mass[i]);
  const auto low = [first](std::uint64_t key) { return first + static_cast<Index>(key >> 32); };
  const auto high = [first](std::uint64_t key) { return first + static_cast<Index>(key & 0xffffffffu); };
  for (const std::uint64_t e : edges) builder.addSpring(low(e), high(e), spec.structural, SpringClass::Structural);
  for (const auto& [order, e] : bendPairs) builder.addSpring(low(e), high(e), spec.bend, SpringClass::Bend);
  for (const auto& tri : mesh.triangles) builder.addTriangle(first + tri[0], first + tri[1], first + tri[2]);
  stats.particles = n;
  stats.structuralSprings = static_cast<Index>(edges.size());
  stats.bendSprings = static_cast<Index>(bendPairs.size());
  stats.triangles = nt;
  return stats;
}

template ClothMeshStats addClothMesh(ModelBuilder<float>&, const TriangleMesh&, const ClothMeshSpec&);
template ClothMeshStats addClothMesh(ModelBuilder<double>&, const TriangleMesh&, const ClothMeshSpec&);

}  // namespace weft
