// weft/rigid/mass_properties.cpp — volume integrals of closed triangle meshes, closed forms.
//
// Each triangle (a, b, c) with the origin spans a signed tetrahedron; summing the exact
// integrals of 1, x, y, z, x^2, y^2, z^2, xy, yz, zx over those tetrahedra gives the
// integrals over the solid (divergence theorem). The per-triangle expressions are Eberly's
// "Polyhedral Mass Properties (Revisited)" (2002), which evaluates Mirtich's (1996) face
// integrals for triangles. The mesh is first shifted to the mean of its vertices so that a
// body far from the origin loses no precision to cancellation; the inertia tensor about the
// centre of mass does not depend on that shift.
#include "weft/rigid/mass_properties.hpp"

#include <Eigen/Geometry>
#include <array>
#include <charconv>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "core/text.hpp"

namespace weft {

using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

using detail::number;

void requirePositive(const char* function, const char* field, double value) {
  if (!std::isfinite(value) || !(value > 0))
    throw std::invalid_argument(std::string(function) + ": " + field + " must be finite and > 0, got " + number(value));
}

/// Running sums of the ten integrals (times 6, 24, 24, 24, 60, 60, 60, 120, 120, 120).
struct VolumeIntegrals {
  std::array<double, 10> sum{};

  /// Eberly's subexpressions for one coordinate of the three vertices.
  static void subexpressions(double w0, double w1, double w2, double& f1, double& f2, double& f3, double& g0,
                             double& g1, double& g2) {
    const double temp0 = w0 + w1;
    f1 = temp0 + w2;
    const double temp1 = w0 * w0;
    const double temp2 = temp1 + w1 * temp0;
    f2 = temp2 + w2 * f1;
    f3 = w0 * temp1 + w1 * temp2 + w2 * f2;
    g0 = f2 + w0 * (f1 + w0);
    g1 = f2 + w1 * (f1 + w1);
    g2 = f2 + w2 * (f1 + w2);
  }

  /// Adds triangle (p0, p1, p2), counter-clockwise seen from outside.
  void add(const Vector3d& p0, const Vector3d& p1, const Vector3d& p2) {
    const Vector3d d = (p1 - p0).cross(p2 - p0);  // outward, twice the area
    double f1x, f2x, f3x, g0x, g1x, g2x;
    double f1y, f2y, f3y, g0y, g1y, g2y;
    double f1z, f2z, f3z, g0z, g1z, g2z;
    subexpressions(p0.x(), p1.x(), p2.x(), f1x, f2x, f3x, g0x, g1x, g2x);
    subexpressions(p0.y(), p1.y(), p2.y(), f1y, f2y, f3y, g0y, g1y, g2y);
    subexpressions(p0.z(), p1.z(), p2.z(), f1z, f2z, f3z, g0z, g1z, g2z);
    sum[0] += d.x() * f1x;
    sum[1] += d.x() * f2x;
    sum[2] += d.y() * f2y;
    sum[3] += d.z() * f2z;
    sum[4] += d.x() * f3x;
    sum[5] += d.y() * f3y;
    sum[6] += d.z() * f3z;
    sum[7] += d.x() * (p0.y() * g0x + p1.y() * g1x + p2.y() * g2x);
    sum[8] += d.y() * (p0.z() * g0y + p1.z() * g1y + p2.z() * g2y);
    sum[9] += d.z() * (p0.x() * g0z + p1.x() * g1z + p2.x() * g2z);
  }

  /// Mass properties at `density`, the coordinates having been shifted by -reference.
  /// Throws when the signed volume is not positive.
  MassProperties finish(const char* function, const Vector3d& reference, double density) const {
    const double volume = sum[0] / 6;
    if (!(volume > 0))
      throw std::invalid_argument(std::string(function) + ": mesh encloses no positive volume (got " + number(volume) +
                                  " m^3): open or inside out?");
    const Vector3d first(sum[1] / 24, sum[2] / 24, sum[3] / 24);   // integrals of x, y, z
    const Vector3d square(sum[4] / 60, sum[5] / 60, sum[6] / 60);  // of x^2, y^2, z^2
    const double xy = sum[7] / 120, yz = sum[8] / 120, zx = sum[9] / 120;
    const Vector3d c = first / volume;  // centre of mass, shifted frame
    // Second moments about the centre of mass (parallel-axis theorem).
    const double xx = square.x() - volume * c.x() * c.x();
    const double yy = square.y() - volume * c.y() * c.y();
    const double zz = square.z() - volume * c.z() * c.z();
    const double cxy = xy - volume * c.x() * c.y();
    const double cyz = yz - volume * c.y() * c.z();
    const double czx = zx - volume * c.z() * c.x();
    MassProperties mp;
    mp.volume = volume;
    mp.mass = density * volume;
    mp.centre = reference + c;
    mp.inertia << yy + zz, -cxy, -czx,  //
        -cxy, xx + zz, -cyz,            //
        -czx, -cyz, xx + yy;
    mp.inertia *= density;
    return mp;
  }
};

}  // namespace

MassProperties polyhedronMassProperties(std::span<const Vector3d> vertices,
                                        std::span<const std::array<int, 3>> triangles, double density) {
  static const char* const kFunction = "polyhedronMassProperties";
  requirePositive(kFunction, "density", density);
  const int vertexCount = static_cast<int>(vertices.size());
  Vector3d reference = Vector3d::Zero();
  for (int i = 0; i < vertexCount; ++i) {
    const Vector3d& v = vertices[static_cast<std::size_t>(i)];
    if (!v.allFinite())
      throw std::invalid_argument(std::string(kFunction) + ": vertex " + std::to_string(i) +
                                  " has a non-finite coordinate (" + number(v.x()) + ", " + number(v.y()) + ", " +
                                  number(v.z()) + ")");
    reference += v;
  }
  if (vertexCount > 0) reference /= vertexCount;
  VolumeIntegrals integrals;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (const int index : triangles[t])
      if (index < 0 || index >= vertexCount)
        throw std::invalid_argument(std::string(kFunction) + ": triangle " + std::to_string(t) + " has vertex index " +
                                    std::to_string(index) + ", out of range [0, " + std::to_string(vertexCount) + ")");
    integrals.add(vertices[static_cast<std::size_t>(triangles[t][0])] - reference,
                  vertices[static_cast<std::size_t>(triangles[t][1])] - reference,
                  vertices[static_cast<std::size_t>(triangles[t][2])] - reference);
  }
  return integrals.finish(kFunction, reference, density);
}

MassProperties hullMassProperties(const ConvexHull& hull, double density) {
  static const char* const kFunction = "hullMassProperties";
  requirePositive(kFunction, "density", density);
  const Vector3d reference = hull.centroid;
  VolumeIntegrals integrals;
  for (int f = 0; f < hull.faceCount(); ++f) {
    const std::span<const int> idx = hull.faceIndices(f);
    // Fan from the first vertex: the polygon is convex, so every fan triangle is inside it.
    const Vector3d p0 = hull.vertices[static_cast<std::size_t>(idx[0])] - reference;
    for (std::size_t k = 1; k + 1 < idx.size(); ++k)
      integrals.add(p0, hull.vertices[static_cast<std::size_t>(idx[k])] - reference,
                    hull.vertices[static_cast<std::size_t>(idx[k + 1])] - reference);
  }
  return integrals.finish(kFunction, reference, density);
}

MassProperties sphereMassProperties(double radius, double density) {
  requirePositive("sphereMassProperties", "radius", radius);
  requirePositive("sphereMassProperties", "density", density);
  MassProperties mp;
  mp.volume = 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
  mp.mass = density * mp.volume;
  mp.inertia = Matrix3d::Identity() * (0.4 * mp.mass * radius * radius);
  return mp;
}

MassProperties boxMassProperties(const Vector3d& halfExtents, double density) {
  static const char* const kFields[3] = {"halfExtents.x", "halfExtents.y", "halfExtents.z"};
  for (int k = 0; k < 3; ++k) requirePositive("boxMassProperties", kFields[k], halfExtents[k]);
  requirePositive("boxMassProperties", "density", density);
  const Vector3d square = halfExtents.cwiseProduct(halfExtents);
  MassProperties mp;
  mp.volume = 8 * halfExtents.x() * halfExtents.y() * halfExtents.z();
  mp.mass = density * mp.volume;
  mp.inertia =
      (mp.mass / 3 * Vector3d(square.y() + square.z(), square.z() + square.x(), square.x() + square.y())).asDiagonal();
  return mp;
}

MassProperties capsuleMassProperties(double radius, double halfHeight, double density) {
  static const char* const kFunction = "capsuleMassProperties";
  requirePositive(kFunction, "radius", radius);
  if (!std::isfinite(halfHeight) || !(halfHeight >= 0))
    throw std::invalid_argument(std::string(kFunction) + ": halfHeight must be finite and >= 0, got " +
                                number(halfHeight));
  requirePositive(kFunction, "density", density);
  const double r = radius, h = halfHeight, r2 = r * r;
  // Cylinder of length 2h: axial m r^2 / 2, transverse m (3 r^2 + (2h)^2) / 12.
  const double cylinderVolume = std::numbers::pi * r2 * 2 * h;
  const double cylinderMass = density * cylinderVolume;
  // Two hemispheres, together one sphere of mass ms. Each hemisphere has, about its flat
  // face's centre, the sphere's 2/5 mh r^2 on every axis; its centre of mass sits 3r/8 from
  // that face, so about its own centre of mass the transverse moment is
  // 2/5 mh r^2 - mh (3r/8)^2, and about the capsule centre (h + 3r/8 away)
  // 2/5 mh r^2 - mh (3r/8)^2 + mh (h + 3r/8)^2 = mh (2/5 r^2 + h^2 + 3/4 h r).
  const double sphereVolume = 4.0 / 3.0 * std::numbers::pi * r2 * r;
  const double sphereMass = density * sphereVolume;
  const double axial = cylinderMass * r2 / 2 + 0.4 * sphereMass * r2;
  const double transverse = cylinderMass * (r2 / 4 + h * h / 3) + sphereMass * (0.4 * r2 + h * h + 0.75 * h * r);
  MassProperties mp;
  mp.volume = cylinderVolume + sphereVolume;
  mp.mass = density * mp.volume;
  mp.inertia = Vector3d(transverse, axial, transverse).asDiagonal();
  return mp;
}

}  // namespace weft
