#include "weft/model/energy.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace weft {

template <class S>
Energy energy(const Model<S>& model, const State<S>& state, const Vec3d& g) {
  const Index n = model.particleCount();
  if (state.x.rows() != n || state.v.rows() != n)
    throw std::invalid_argument("energy: the state has " + std::to_string(state.x.rows()) + " positions and " +
                                std::to_string(state.v.rows()) + " velocities, the model " + std::to_string(n) +
                                " particles");
  Energy e;
  for (Index i = 0; i < n; ++i) {
    const double m = static_cast<double>(model.mass()[i]);
    const double v2 = static_cast<double>(state.v.row(i).squaredNorm());
    e.kinetic += 0.5 * m * v2;
    if (!model.isPinned(i))
      e.gravity -= m * (g.x * double(state.x(i, 0)) + g.y * double(state.x(i, 1)) + g.z * double(state.x(i, 2)));
  }
  const auto& sp = model.springs();
  for (Index s = 0; s < sp.count(); ++s) {
    const double len = static_cast<double>((state.x.row(sp.a[s]) - state.x.row(sp.b[s])).norm());
    const double d = len - double(sp.restLength[s]);
    e.spring += 0.5 * double(sp.stiffness[s]) * d * d;
  }
  return e;
}

template Energy energy(const Model<float>&, const State<float>&, const Vec3d&);
template Energy energy(const Model<double>&, const State<double>&, const Vec3d&);

template <class S>
Stretch stretch(const Model<S>& model, const State<S>& state, SpringClass kind) {
  const Index n = model.particleCount();
  if (state.x.rows() != n)
    throw std::invalid_argument("stretch: the state has " + std::to_string(state.x.rows()) + " positions, the model " +
                                std::to_string(n) + " particles");
  const int k = static_cast<int>(kind);
  if (k < 0 || k >= kSpringClassCount)
    throw std::invalid_argument("stretch: kind must be structural, shear or bend; got " + std::to_string(k));
  const auto& sp = model.springs();
  Stretch out;
  double largest = -std::numeric_limits<double>::infinity(), sum = 0;
  Index longest = -1;
  for (Index s = 0; s < sp.count(); ++s) {
    if (sp.kind[static_cast<std::size_t>(s)] != kind || !(sp.restLength[s] > S(0))) continue;
    const double dx = double(state.x(sp.a[s], 0)) - double(state.x(sp.b[s], 0));
    const double dy = double(state.x(sp.a[s], 1)) - double(state.x(sp.b[s], 1));
    const double dz = double(state.x(sp.a[s], 2)) - double(state.x(sp.b[s], 2));
    const double e = std::sqrt(dx * dx + dy * dy + dz * dz) / double(sp.restLength[s]) - 1.0;
    if (!std::isnan(largest) && (std::isnan(e) || e > largest)) {  // a non-finite state gives a NaN maximum
      largest = e;
      longest = s;
    }
    sum += e;
    ++out.springs;
  }
  if (out.springs > 0) {
    out.max = largest;
    out.longest = longest;
    out.mean = sum / static_cast<double>(out.springs);
  }
  return out;
}

template Stretch stretch(const Model<float>&, const State<float>&, SpringClass);
template Stretch stretch(const Model<double>&, const State<double>&, SpringClass);

}  // namespace weft
