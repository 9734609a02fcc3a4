#include "weft/collide/shapes.hpp"

#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/text.hpp"

namespace weft {

TriangleMesh makeIcosphere(const Vec3d& center, double radius, Index divisions) {
  if (!std::isfinite(radius) || !(radius > 0)) {
    detail::rejectField("makeIcosphere: radius", radius, "finite and > 0");
  }
  if (divisions < 1 || divisions > 4096) {
    throw std::invalid_argument("makeIcosphere: divisions must be in [1, 4096], got " + std::to_string(divisions));
  }
  const double g = (1 + std::sqrt(5.0)) / 2;
  const std::array<std::array<double, 3>, 12> ico = {{{-1, g, 0},
                                                      {1, g, 0},
                                                      {-1, -g, 0},
                                                      {1, -g, 0},
                                                      {0, -1, g},
                                                      {0, 1, g},
                                                      {0, -1, -g},
                                                      {0, 1, -g},
                                                      {g, 0, -1},
                                                      {g, 0, 1},
                                                      {-g, 0, -1},
                                                      {-g, 0, 1}}};
  const std::array<std::array<int, 3>, 20> faces = {{{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                                     {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                                     {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                                     {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}}};
  const Index d = divisions;
  TriangleMesh raw;
  raw.vertices.reserve(static_cast<size_t>(20 * (d + 1) * (d + 2) / 2));
  raw.triangles.reserve(static_cast<size_t>(20 * d * d));
  for (const auto& f : faces) {
    const auto& A = ico[static_cast<size_t>(f[0])];
    const auto& B = ico[static_cast<size_t>(f[1])];
    const auto& C = ico[static_cast<size_t>(f[2])];
    const Index first = static_cast<Index>(raw.vertices.size());
    // Point (i, j): weights (d - i - j, i, j) on (A, B, C); row i has d - i + 1 points.
    for (Index i = 0; i <= d; ++i) {
      for (Index j = 0; i + j <= d; ++j) {
        const double wa = static_cast<double>(d - i - j), wb = static_cast<double>(i), wc = static_cast<double>(j);
        double p[3];
        for (int k = 0; k < 3; ++k) {
          // Zero weights contribute +0 exactly, so an edge point is the same two-term sum from either face.
          p[k] = (wa * A[static_cast<size_t>(k)] + wb * B[static_cast<size_t>(k)]) + wc * C[static_cast<size_t>(k)];
        }
        const double len = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        raw.vertices.push_back(
            {center.x + radius * p[0] / len, center.y + radius * p[1] / len, center.z + radius * p[2] / len});
      }
    }
    const auto at = [&](Index i, Index j) { return first + i * (d + 1) - i * (i - 1) / 2 + j; };
    for (Index i = 0; i < d; ++i) {
      for (Index j = 0; i + j < d; ++j) {
        raw.triangles.push_back({at(i, j), at(i + 1, j), at(i, j + 1)});
        if (i + j + 1 < d) raw.triangles.push_back({at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
      }
    }
  }
  MeshCleanOptions options;
  options.weldTolerance = 0;
  return cleanMesh(raw, options);
}

template <class S>
Vec3Array<S> meshPositions(const TriangleMesh& mesh) {
  Vec3Array<S> x(static_cast<Index>(mesh.vertices.size()), 3);
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Index r = static_cast<Index>(i);
    x(r, 0) = static_cast<S>(mesh.vertices[i].x);
    x(r, 1) = static_cast<S>(mesh.vertices[i].y);
    x(r, 2) = static_cast<S>(mesh.vertices[i].z);
  }
  return x;
}

Triangles meshTriangles(const TriangleMesh& mesh) {
  Triangles t;
  const Index n = static_cast<Index>(mesh.triangles.size());
  t.a.resize(n);
  t.b.resize(n);
  t.c.resize(n);
  for (Index i = 0; i < n; ++i) {
    t.a[i] = mesh.triangles[static_cast<size_t>(i)][0];
    t.b[i] = mesh.triangles[static_cast<size_t>(i)][1];
    t.c[i] = mesh.triangles[static_cast<size_t>(i)][2];
  }
  return t;
}

template Vec3Array<float> meshPositions(const TriangleMesh&);
template Vec3Array<double> meshPositions(const TriangleMesh&);

}  // namespace weft
