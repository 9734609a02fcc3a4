#include "weft/model/model_builder.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "core/text.hpp"
#include "precision_limits.hpp"

namespace weft {

namespace {

[[noreturn]] void reject(const std::string& where, const std::string& field, double value, const std::string& rule) {
  detail::rejectField(where + ": " + field, value, rule);
}

void requireFinite(const std::string& where, const std::string& field, double value) {
  if (!std::isfinite(value)) reject(where, field, value, "finite");
}

std::string indexed(const char* field, Index i) { return std::string(field) + " [" + std::to_string(i) + "]"; }

}  // namespace

template <class S>
void ModelBuilder<S>::checkParticle(const char* what, Index i) const {
  if (i < 0 || i >= particleCount()) {
    std::ostringstream msg;
    msg << what << ": particle index must be in [0, " << particleCount() << "), got " << i;
    throw std::invalid_argument(msg.str());
  }
}

template <class S>
Index ModelBuilder<S>::addParticle(const Vec3d& position, double mass, const Vec3d& velocity) {
  const Index i = particleCount();
  const char* where = "ModelBuilder::addParticle";
  requireFinite(where, indexed("position.x of particle", i), position.x);
  requireFinite(where, indexed("position.y of particle", i), position.y);
  requireFinite(where, indexed("position.z of particle", i), position.z);
  requireFinite(where, indexed("velocity.x of particle", i), velocity.x);
  requireFinite(where, indexed("velocity.y of particle", i), velocity.y);
  requireFinite(where, indexed("velocity.z of particle", i), velocity.z);
  if (!detail::speedWithinLimit(velocity.x, velocity.y, velocity.z))
    detail::rejectField(std::string(where) + ": " + indexed("velocity of particle", i), detail::number3(velocity),
                        detail::speedRule());
  if (!(std::isfinite(mass) && mass > 0)) reject(where, indexed("mass of particle", i), mass, "finite and > 0 (kg)");
  px_.push_back(position.x);
  py_.push_back(position.y);
  pz_.push_back(position.z);
  vx_.push_back(velocity.x);
  vy_.push_back(velocity.y);
  vz_.push_back(velocity.z);
  mass_.push_back(mass);
  pinned_.push_back(0);
  return i;
}

template <class S>
Vec3d ModelBuilder<S>::position(Index i) const {
  checkParticle("ModelBuilder::position", i);
  return {px_[i], py_[i], pz_[i]};
}

template <class S>
Index ModelBuilder<S>::addSpring(Index a, Index b, const SpringMaterial& material, SpringClass kind,
                                 double restLength) {
  const Index s = springCount();
  const char* where = "ModelBuilder::addSpring";
  checkParticle(where, a);
  checkParticle(where, b);
  if (a == b) reject(where, indexed("endpoint b of spring", s), b, "different from endpoint a");
  if (!(std::isfinite(material.stiffness) && material.stiffness >= 0))
    reject(where, indexed("stiffness of spring", s), material.stiffness, "finite and >= 0 (N/m)");
  if (!(std::isfinite(material.damping) && material.damping >= 0))
    reject(where, indexed("damping of spring", s), material.damping, "finite and >= 0 (N s/m)");
  if (!std::isfinite(restLength)) reject(where, indexed("restLength of spring", s), restLength, "finite");
  if (restLength < 0) {
    const double dx = px_[a] - px_[b], dy = py_[a] - py_[b], dz = pz_[a] - pz_[b];
    restLength = std::sqrt(dx * dx + dy * dy + dz * dz);
  }
  springA_.push_back(a);
  springB_.push_back(b);
  rest_.push_back(restLength);
  stiffness_.push_back(material.stiffness);
  damping_.push_back(material.damping);
  kind_.push_back(kind);
  return s;
}

template <class S>
Index ModelBuilder<S>::addTriangle(Index a, Index b, Index c) {
  const Index t = triangleCount();
  const char* where = "ModelBuilder::addTriangle";
  checkParticle(where, a);
  checkParticle(where, b);
  checkParticle(where, c);
  if (a == b || b == c || a == c)
    throw std::invalid_argument(std::string(where) + ": corners of triangle [" + std::to_string(t) +
                                "] must be distinct particles, got (" + std::to_string(a) + ", " + std::to_string(b) +
                                ", " + std::to_string(c) + ")");
  triangles_.push_back({a, b, c});
  return t;
}

template <class S>
void ModelBuilder<S>::pin(Index i) {
  checkParticle("ModelBuilder::pin", i);
  pinned_[i] = 1;
}

/// Checks the recorded grid layout against the springs exactly (the stencil strategy trusts
/// it): throws for a layout that does not fit; false when the model is not exactly that one
/// grid (springs outside the families or in two, particles after the grid's), which then
/// gets no layout (Auto picks Gather) instead of silently wrong forces.
template <class S>
bool ModelBuilder<S>::checkGridLayout(const GridLayout<S>& g) const {
  const Index n = particleCount();
  const Index m = springCount();
  if (static_cast<long long>(g.width) * g.height > n)
    throw std::invalid_argument("ModelBuilder::build: grid layout " + std::to_string(g.width) + " x " +
                                std::to_string(g.height) + " exceeds the particle count " + std::to_string(n));
  // Every family must stay inside the grid, so the stencil never reads out of bounds.
  for (const GridFamily<S>& f : g.families) {
    const bool rowsInside = (f.rowOffset >= 0) && (f.rowOffset < g.height);
    const bool columnsInside = (f.columnOffset > -g.width) && (f.columnOffset < g.width);
    const bool forward = (f.rowOffset > 0) || (f.columnOffset > 0);
    const bool springsInside = (f.firstSpring >= 0) && (f.springCount >= 0) && (f.firstSpring <= m - f.springCount);
    const bool inside = rowsInside && columnsInside && forward && springsInside;
    if (!inside)
      throw std::invalid_argument("ModelBuilder::build: grid layout family (rowOffset " + std::to_string(f.rowOffset) +
                                  ", columnOffset " + std::to_string(f.columnOffset) + ", firstSpring " +
                                  std::to_string(f.firstSpring) + ", springCount " + std::to_string(f.springCount) +
                                  ") does not fit a " + std::to_string(g.width) + " x " + std::to_string(g.height) +
                                  " grid of " + std::to_string(m) + " springs");
  }
  std::vector<char> covered(static_cast<size_t>(m), 0);  // springs claimed by a family
  bool exactCover = true;
  for (const GridFamily<S>& f : g.families) {
    Index s = f.firstSpring;
    for (Index r = 0; r + f.rowOffset < g.height; ++r) {
      for (Index c = std::max(0, -f.columnOffset); c < std::min(g.width, g.width - f.columnOffset); ++c, ++s) {
        const size_t k = static_cast<size_t>(s);
        const bool ok = s < m && springA_[k] == r * g.width + c &&
                        springB_[k] == (r + f.rowOffset) * g.width + c + f.columnOffset &&
                        static_cast<S>(rest_[k]) == f.restLength && static_cast<S>(stiffness_[k]) == f.stiffness &&
                        static_cast<S>(damping_[k]) == f.damping;
        if (!ok)
          throw std::invalid_argument("ModelBuilder::build: spring " + std::to_string(s) +
                                      " does not match the recorded grid layout");
        exactCover = exactCover && !covered[k];
        covered[k] = 1;
      }
    }
    if (s - f.firstSpring != f.springCount)
      throw std::invalid_argument("ModelBuilder::build: grid family spring count mismatch");
  }
  exactCover = exactCover && static_cast<long long>(g.width) * g.height == n;
  for (Index s = 0; s < m && exactCover; ++s) exactCover = covered[static_cast<size_t>(s)] != 0;
  return exactCover;
}

template <class S>
void ModelBuilder<S>::reserve(Index particles, Index springs, Index triangles) {
  const auto more = [](auto& v, Index count) { v.reserve(v.size() + static_cast<size_t>(std::max<Index>(count, 0))); };
  for (auto* v : {&px_, &py_, &pz_, &vx_, &vy_, &vz_, &mass_}) more(*v, particles);
  more(pinned_, particles);
  more(springA_, springs);
  more(springB_, springs);
  for (auto* v : {&rest_, &stiffness_, &damping_}) more(*v, springs);
  more(kind_, springs);
  more(triangles_, triangles);
}

template <class S>
ModelAndState<S> ModelBuilder<S>::build() {
  const Index n = particleCount();
  const Index m = springCount();
  // n == 0 is a model without particles: a scene of rigid bodies only.

  // Values must be representable in S (converting an out-of-range double to float is
  // undefined behaviour, and an infinite position is no position).
  using Limits = detail::PrecisionLimits<S>;
  const char* precision = Limits::kName;
  const auto scalar = [&](double value, const char* field, Index i) {
    if (!Limits::representable(value))
      reject("ModelBuilder::build", indexed(field, i), value,
             std::string("within the range of ") + precision +
                 " precision (|value| <= " + detail::number(Limits::kLargest) + ")");
    return static_cast<S>(value);
  };
  const auto coordinate = [&](double value, const char* field, Index i) {
    if (!Limits::coordinate(value)) reject("ModelBuilder::build", indexed(field, i), value, Limits::coordinateRule());
    return static_cast<S>(value);
  };

  // Everything that can be refused is checked first, on the builder's own arrays, so that a
  // refused build leaves the builder untouched.
  for (Index i = 0; i < n; ++i) {
    (void)scalar(mass_[i], "mass of particle", i);
    if (!pinned_[i] && !Limits::invertibleMass(mass_[i]))
      reject("ModelBuilder::build", indexed("mass of particle", i), mass_[i],
             "large enough that 1/mass is finite in the chosen precision");
    (void)coordinate(px_[i], "position.x of particle", i);
    (void)coordinate(py_[i], "position.y of particle", i);
    (void)coordinate(pz_[i], "position.z of particle", i);
    // (Velocities: addParticle held them to kMaxSpeed, within the range of float too.)
  }
  for (Index s = 0; s < m; ++s) {
    (void)scalar(rest_[s], "restLength of spring", s);
    (void)scalar(stiffness_[s], "stiffness of spring", s);
    (void)scalar(damping_[s], "damping of spring", s);
    const Index a = springA_[s], b = springB_[s];
    Limits::requireSpringResolved("ModelBuilder::build", s, a, b, rest_[s],
                                  {px_[a], py_[a], pz_[a], px_[b], py_[b], pz_[b]});
  }
  const bool isGrid = grid_ && checkGridLayout(*grid_);

  ModelAndState<S> out;
  Model<S>& model = out.model;
  State<S>& state = out.state;
  // Each array is released as soon as the model holds its copy (the largest scenes are
  // springs above all: a 256^2 cloth has 390k).
  const auto take = [](auto& from, auto& to) {
    using To = std::remove_reference_t<decltype(to)>;
    to.resize(static_cast<Index>(from.size()));
    for (size_t k = 0; k < from.size(); ++k) to[static_cast<Index>(k)] = static_cast<typename To::Scalar>(from[k]);
    std::remove_reference_t<decltype(from)>().swap(from);
  };
  model.mass_.resize(n);
  model.inverseMass_.resize(n);
  for (Index i = 0; i < n; ++i) {
    model.mass_[i] = static_cast<S>(mass_[i]);
    model.inverseMass_[i] = pinned_[i] ? S(0) : static_cast<S>(1.0 / mass_[i]);
  }
  state.x.resize(n, 3);
  state.v.resize(n, 3);
  for (Index i = 0; i < n; ++i) {
    state.x(i, 0) = static_cast<S>(px_[i]);
    state.x(i, 1) = static_cast<S>(py_[i]);
    state.x(i, 2) = static_cast<S>(pz_[i]);
    state.v(i, 0) = pinned_[i] ? S(0) : static_cast<S>(vx_[i]);
    state.v(i, 1) = pinned_[i] ? S(0) : static_cast<S>(vy_[i]);
    state.v(i, 2) = pinned_[i] ? S(0) : static_cast<S>(vz_[i]);
  }
  for (std::vector<double>* a : {&px_, &py_, &pz_, &vx_, &vy_, &vz_, &mass_}) std::vector<double>().swap(*a);
  std::vector<char>().swap(pinned_);
  Springs<S>& sp = model.springs_;
  take(springA_, sp.a);
  take(springB_, sp.b);
  take(rest_, sp.restLength);
  take(stiffness_, sp.stiffness);
  take(damping_, sp.damping);
  sp.kind = std::move(kind_);

  Triangles& tr = model.triangles_;
  const Index nt = triangleCount();
  tr.a.resize(nt);
  tr.b.resize(nt);
  tr.c.resize(nt);
  for (Index t = 0; t < nt; ++t) {
    tr.a[t] = triangles_[t][0];
    tr.b[t] = triangles_[t][1];
    tr.c[t] = triangles_[t][2];
  }
  if (isGrid) model.grid_ = std::move(grid_);

  *this = ModelBuilder<S>();
  return out;
}

template class ModelBuilder<float>;
template class ModelBuilder<double>;

}  // namespace weft
