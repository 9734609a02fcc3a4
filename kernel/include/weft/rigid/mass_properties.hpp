// weft/rigid/mass_properties.hpp — mass, centre of mass and inertia tensor of solids.
//
// Design note
// -----------
// For a closed, outward-oriented triangle mesh the volume integrals of 1, x, y, z, x^2,
// y^2, z^2, xy, yz, zx are computed exactly (up to rounding) by the divergence theorem,
// one signed tetrahedron (origin, a, b, c) per triangle: Mirtich 1996 "Fast and accurate
// computation of polyhedral mass properties", in the tetrahedron form of Eberly. The
// inertia tensor is then shifted to the centre of mass (parallel-axis theorem). Convex
// hulls are fanned into triangles. Sphere, box and capsule have closed forms.
// Build time only; throws std::invalid_argument for a non-positive or non-finite density
// or size, and for a mesh whose signed volume is not positive (inside out, flat; an open
// mesh is caught only when its volume comes out <= 0).
#pragma once

#include <Eigen/Core>
#include <array>
#include <span>

#include "weft/rigid/convex_hull.hpp"

namespace weft {

struct MassProperties {
  double mass = 0;                                    // kg
  double volume = 0;                                  // m^3
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();   // centre of mass, shape frame, m
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();  // about the centre of mass, shape axes, kg m^2
};

/// Closed triangle mesh, triangles counter-clockwise seen from outside; density kg/m^3.
MassProperties polyhedronMassProperties(std::span<const Eigen::Vector3d> vertices,
                                        std::span<const std::array<int, 3>> triangles, double density);
MassProperties hullMassProperties(const ConvexHull& hull, double density);
/// Sphere of `radius` centred at the origin.
MassProperties sphereMassProperties(double radius, double density);
/// Box centred at the origin.
MassProperties boxMassProperties(const Eigen::Vector3d& halfExtents, double density);
/// Capsule along the y axis: a cylinder of `halfHeight` (>= 0) capped by hemispheres of `radius`.
MassProperties capsuleMassProperties(double radius, double halfHeight, double density);

}  // namespace weft
