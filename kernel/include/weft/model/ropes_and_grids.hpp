// weft/model/ropes_and_grids.hpp — ropes and cloth grids.
//
// Design note
// -----------
// A rope is a chain of particles joined by structural springs i -> i+1 and, optionally,
// bend springs i -> i+2 (the original design's "interleaved" springs, which give the
// chain bending stiffness). A cloth grid is width x height particles with structural
// springs to the right and lower neighbours, shear springs along both diagonals of every
// quad, and bend springs skipping one particle along rows and columns; each class has
// its own material. Springs are emitted family by family (right, down, diagonal,
// anti-diagonal, skip-right, skip-down), each family in particle order, which is both
// the cache-friendly order for the general force strategies and the order the grid
// stencil relies on.
#pragma once

#include "weft/model/model_builder.hpp"

namespace weft {

struct RopeSpec {
  Index particleCount = 32;  // >= 2
  Vec3d origin{0, 0, 0};     // position of particle 0, m
  Vec3d direction{1, 0, 0};  // direction of the chain (normalised on use)
  double length = 1;         // total rest length, m (> 0)
  double totalMass = 0.1;    // kg (> 0), spread evenly
  SpringMaterial structural{500, 0.05};
  bool bendSprings = true;  // add i -> i+2 springs
  SpringMaterial bend{50, 0.01};
};

struct ClothGridSpec {
  Index width = 64;           // particles along a row (>= 2)
  Index height = 64;          // rows (>= 2)
  Vec3d origin{0, 0, 0};      // position of particle (0, 0), m
  Vec3d rowAxis{1, 0, 0};     // direction from column c to c+1 (normalised on use)
  Vec3d columnAxis{0, 0, 1};  // direction from row r to r+1 (normalised on use)
  double spacing = 1.0 / 63;  // distance between neighbours, m (> 0)
  double totalMass = 0.5;     // kg (> 0), spread evenly
  SpringMaterial structural{800, 0.05};
  bool shearSprings = true;
  SpringMaterial shear{400, 0.025};
  bool bendSprings = true;
  SpringMaterial bend{100, 0.01};
};

/// Number of springs of each class a grid of this spec has: structural
/// (w-1)h + w(h-1), shear 2(w-1)(h-1), bend (w-2)h + w(h-2) (for w, h >= 2).
std::array<Index, kSpringClassCount> expectedGridSpringCounts(const ClothGridSpec& spec);

template <class S>
void addRope(ModelBuilder<S>& builder, const RopeSpec& spec);

/// Adds the grid's particles, springs and triangles (particle (r, c) is the builder's
/// particle count before the call + r * width + c). Into an empty builder it also records
/// the grid layout, which the GridStencil strategy needs (kept only if nothing else adds
/// springs).
template <class S>
void addClothGrid(ModelBuilder<S>& builder, const ClothGridSpec& spec);

/// Index of grid particle (row, column).
inline Index gridIndex(const ClothGridSpec& spec, Index row, Index column) { return row * spec.width + column; }

}  // namespace weft
