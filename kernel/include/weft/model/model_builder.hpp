// weft/model/model_builder.hpp — assembling and validating a Model and its initial State.
//
// Design note
// -----------
// Every value that comes from a user passes through ModelBuilder, which rejects bad
// input at build time with std::invalid_argument naming the field, the item and the
// value (a step never throws). Masses are given per particle; pins set the inverse
// mass to zero and keep the mass (so totals stay meaningful). A spring's rest length
// defaults to the distance between its endpoints at the moment it is added.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "weft/core/state.hpp"
#include "weft/model/model.hpp"

namespace weft {

template <class S>
struct ModelAndState {
  Model<S> model;
  State<S> state;
};

template <class S>
class ModelBuilder {
 public:
  /// Adds a particle at `position` (m) with `mass` (kg, finite and > 0) and velocity
  /// `velocity` (m/s, finite, a speed of at most kMaxSpeed). Returns its index.
  Index addParticle(const Vec3d& position, double mass, const Vec3d& velocity = {});

  /// Adds a spring between particles a and b. restLength < 0 (the default) means the
  /// current distance between them. Returns its index.
  Index addSpring(Index a, Index b, const SpringMaterial& material, SpringClass kind = SpringClass::Structural,
                  double restLength = -1);

  /// Adds a surface triangle with corners a, b, c (distinct particles; normal along
  /// (b - a) x (c - a)). Returns its index.
  Index addTriangle(Index a, Index b, Index c);

  /// Pins particle i: its inverse mass becomes 0, so no force moves it.
  void pin(Index i);

  /// Records the model as a regular grid (called by buildClothGrid; validated against the
  /// springs added when build() runs).
  void setGridLayout(GridLayout<S> layout) { grid_ = std::move(layout); }

  Index particleCount() const { return static_cast<Index>(mass_.size()); }
  Index springCount() const { return static_cast<Index>(springA_.size()); }
  Index triangleCount() const { return static_cast<Index>(triangles_.size()); }
  Vec3d position(Index i) const;

  /// Makes room for this many more particles, springs and triangles (an optimisation only:
  /// a large cloth then holds no spare capacity while it is assembled).
  void reserve(Index particles, Index springs, Index triangles);

  /// Builds the immutable model and its initial state. The builder is left empty. Every
  /// value is checked before anything is moved, so a build that throws leaves the builder
  /// as it was; the builder's arrays are released one by one as the model takes them, so a
  /// large model does not need both copies at once.
  ModelAndState<S> build();

 private:
  void checkParticle(const char* what, Index i) const;
  bool checkGridLayout(const GridLayout<S>& layout) const;
  std::vector<double> px_, py_, pz_, vx_, vy_, vz_, mass_;
  std::vector<char> pinned_;
  std::vector<Index> springA_, springB_;
  std::vector<double> rest_, stiffness_, damping_;
  std::vector<SpringClass> kind_;
  std::vector<std::array<Index, 3>> triangles_;
  std::optional<GridLayout<S>> grid_;
};

extern template class ModelBuilder<float>;
extern template class ModelBuilder<double>;

}  // namespace weft
