#include "weft/model/builder.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace weft {

namespace {

[[noreturn]] void reject(const std::string& where, const std::string& field, double value, const std::string& rule) {
  std::ostringstream msg;
  msg.precision(17);
  msg << where << ": " << field << " must be " << rule << ", got " << value;
  throw std::invalid_argument(msg.str());
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
void ModelBuilder<S>::pin(Index i) {
  checkParticle("ModelBuilder::pin", i);
  pinned_[i] = 1;
}

template <class S>
ModelAndState<S> ModelBuilder<S>::build() {
  const Index n = particleCount();
  const Index m = springCount();
  if (n == 0) throw std::invalid_argument("ModelBuilder::build: the model has no particles");

  ModelAndState<S> out;
  Model<S>& model = out.model;
  State<S>& state = out.state;
  model.mass_.resize(n);
  model.inverseMass_.resize(n);
  state.x.resize(n, 3);
  state.v.resize(n, 3);
  for (Index i = 0; i < n; ++i) {
    model.mass_[i] = static_cast<S>(mass_[i]);
    model.inverseMass_[i] = pinned_[i] ? S(0) : static_cast<S>(1.0 / mass_[i]);
    if (!pinned_[i] && !std::isfinite(static_cast<double>(model.inverseMass_[i])))
      reject("ModelBuilder::build", indexed("mass of particle", i), mass_[i],
             "large enough that 1/mass is finite in the chosen precision");
    state.x(i, 0) = static_cast<S>(px_[i]);
    state.x(i, 1) = static_cast<S>(py_[i]);
    state.x(i, 2) = static_cast<S>(pz_[i]);
    state.v(i, 0) = pinned_[i] ? S(0) : static_cast<S>(vx_[i]);
    state.v(i, 1) = pinned_[i] ? S(0) : static_cast<S>(vy_[i]);
    state.v(i, 2) = pinned_[i] ? S(0) : static_cast<S>(vz_[i]);
  }
  Springs<S>& sp = model.springs_;
  sp.a.resize(m);
  sp.b.resize(m);
  sp.restLength.resize(m);
  sp.stiffness.resize(m);
  sp.damping.resize(m);
  sp.kind = kind_;
  for (Index s = 0; s < m; ++s) {
    sp.a[s] = springA_[s];
    sp.b[s] = springB_[s];
    sp.restLength[s] = static_cast<S>(rest_[s]);
    sp.stiffness[s] = static_cast<S>(stiffness_[s]);
    sp.damping[s] = static_cast<S>(damping_[s]);
  }

  if (grid_) {
    // The stencil strategy trusts the layout, so check it against the springs exactly.
    const GridLayout<S>& g = *grid_;
    if (static_cast<long long>(g.width) * g.height != n)
      throw std::invalid_argument("ModelBuilder::build: grid layout " + std::to_string(g.width) + " x " +
                                  std::to_string(g.height) + " does not match particle count " + std::to_string(n));
    for (const GridFamily<S>& f : g.families) {
      Index s = f.firstSpring;
      for (Index r = 0; r + f.rowOffset < g.height; ++r) {
        for (Index c = std::max(0, -f.columnOffset); c < std::min(g.width, g.width - f.columnOffset); ++c, ++s) {
          const bool ok = s < m && sp.a[s] == r * g.width + c &&
                          sp.b[s] == (r + f.rowOffset) * g.width + c + f.columnOffset &&
                          sp.restLength[s] == f.restLength && sp.stiffness[s] == f.stiffness &&
                          sp.damping[s] == f.damping;
          if (!ok)
            throw std::invalid_argument("ModelBuilder::build: spring " + std::to_string(s) +
                                        " does not match the recorded grid layout");
        }
      }
      if (s - f.firstSpring != f.springCount)
        throw std::invalid_argument("ModelBuilder::build: grid family spring count mismatch");
    }
    model.grid_ = std::move(grid_);
  }

  *this = ModelBuilder<S>();
  return out;
}

template class ModelBuilder<float>;
template class ModelBuilder<double>;

}  // namespace weft
