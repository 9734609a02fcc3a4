// weft/model/model.hpp — what a step only reads.
//
// Design note
// -----------
// A Model is the immutable description of a mass-spring system: per-particle masses
// (inverse mass 0 = pinned), and the springs as structure-of-arrays (endpoints, rest
// length, stiffness, damping, class) and, for cloth, the surface triangles. It is built once by a ModelBuilder (which
// validates every input) and never changes afterwards, so any number of States and
// Simulations may share it read-only across threads.
//
// Springs from the cloth-grid builder also carry a GridLayout: the grid's width and
// height and, per spring family (a fixed neighbour offset such as "right neighbour" or
// "two rows down"), the family's uniform rest length, stiffness and damping. The
// GridStencil force strategy uses it to evaluate springs with contiguous loads only.
//
// What follows from the springs and triangles alone (incidence lists, the spring
// colouring, collision edges) is derived data of the Model too: computed on first use,
// once, and shared by every Simulation on the Model (weft/model/topology.hpp).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "weft/core/types.hpp"
#include "weft/model/topology.hpp"

namespace weft {

/// What a spring stands for in the cloth model (the seed's "interleaved" springs are
/// Bend). Used for per-class materials and counts; the force law is the same for all.
enum class SpringClass : std::uint8_t { Structural = 0, Shear = 1, Bend = 2 };
inline constexpr int kSpringClassCount = 3;
const char* springClassName(SpringClass c);

/// Material of a spring: Hooke stiffness ks (N/m) and damping kd (N s/m) of the
/// Witkin/Baraff damped spring.
struct SpringMaterial {
  double stiffness = 0;  // ks, N/m, >= 0
  double damping = 0;    // kd, N s/m, >= 0
};

/// Springs as structure of arrays; entry s is one spring between particles a[s], b[s].
template <class S>
struct Springs {
  IndexArray a;                   // (m) first endpoint
  IndexArray b;                   // (m) second endpoint
  ScalarArray<S> restLength;      // (m) r, m
  ScalarArray<S> stiffness;       // (m) ks, N/m
  ScalarArray<S> damping;         // (m) kd, N s/m
  std::vector<SpringClass> kind;  // (m) class, cold data (counts, materials)

  Index count() const { return static_cast<Index>(a.rows()); }
};

/// Triangles (the cloth's surface: wind acts on them, frames are written with them), as
/// structure of arrays; triangle t has corners a[t], b[t], c[t], counter-clockwise seen
/// from the side its normal (b - a) x (c - a) points to. Ropes have none.
struct Triangles {
  IndexArray a;  // (t) first corner
  IndexArray b;  // (t) second corner
  IndexArray c;  // (t) third corner

  Index count() const { return static_cast<Index>(a.rows()); }
};

/// One family of a regular grid's springs: every particle (r, c) with (r + rowOffset,
/// c + columnOffset) inside the grid is joined to it, with the same parameters.
template <class S>
struct GridFamily {
  int rowOffset = 0;      // dr >= 0
  int columnOffset = 0;   // dc, may be negative (the anti-diagonal shear spring)
  S restLength = 0;       // m
  S stiffness = 0;        // N/m
  S damping = 0;          // N s/m
  Index firstSpring = 0;  // the family's springs are springs [firstSpring, firstSpring + springCount)
  Index springCount = 0;
};

/// Regular-grid description of a model built by buildClothGrid: particle (r, c) is
/// index r * width + c.
template <class S>
struct GridLayout {
  Index width = 0;
  Index height = 0;
  std::vector<GridFamily<S>> families;
};

template <class S>
class ModelBuilder;

namespace detail {
template <class S>
struct DerivedTopology;
}

template <class S>
class Model {
 public:
  Model();

  Index particleCount() const { return static_cast<Index>(mass_.rows()); }
  Index springCount() const { return springs_.count(); }

  const ScalarArray<S>& mass() const { return mass_; }                // (n) kg
  const ScalarArray<S>& inverseMass() const { return inverseMass_; }  // (n) 1/kg, 0 = pinned
  bool isPinned(Index i) const { return inverseMass_[i] == S(0); }
  Index pinnedCount() const;
  const Springs<S>& springs() const { return springs_; }
  const Triangles& triangles() const { return triangles_; }
  Index triangleCount() const { return triangles_.count(); }
  /// Number of springs of each class.
  std::array<Index, kSpringClassCount> springCountByClass() const;
  /// Present for models built as a regular grid (enables the GridStencil strategy).
  const std::optional<GridLayout<S>>& grid() const { return grid_; }

  // Derived topology (weft/model/topology.hpp): computed the first time it is asked for,
  // then shared. Safe to call from several threads.

  /// Particle -> springs; an entry is 2 s + side (side 1: the particle is endpoint b).
  const Incidence& springIncidence() const;
  /// Particle -> triangles; an entry is the triangle's index.
  const Incidence& triangleIncidence() const;
  /// Greedy edge colouring of the springs (each spring takes the smallest colour neither
  /// endpoint has yet; at most 2 x the largest degree - 1 colours).
  const SpringColouring<S>& springColouring() const;
  /// True when the triangles are exactly a cloth grid's (two per cell, in cell order: cell
  /// (r, c) with top-left a = r W + c gives (a, a+1, a+W+1) and (a, a+W+1, a+W)).
  bool trianglesFormGrid() const;
  /// The edges a contact pass tests against mesh edges: the structural and shear springs'
  /// endpoints (a cloth's sides and diagonals, a rope's links), in spring order.
  const std::vector<Edge>& collisionEdges() const;
  /// The triangles' edges and the vertices and edges each triangle owns (self-collision).
  const SurfaceTopology& surfaceTopology() const;
  /// How many derived structures this Model (and any copy of it) has computed so far:
  /// a second Simulation on the same Model adds none.
  int derivedBuildCount() const;

 private:
  friend class ModelBuilder<S>;
  ScalarArray<S> mass_;
  ScalarArray<S> inverseMass_;
  Springs<S> springs_;
  Triangles triangles_;
  std::optional<GridLayout<S>> grid_;
  // Shared by copies of this Model, which have the same springs and triangles.
  std::shared_ptr<detail::DerivedTopology<S>> derived_;
};

extern template class Model<float>;
extern template class Model<double>;

}  // namespace weft
