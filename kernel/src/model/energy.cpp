#include "weft/model/energy.hpp"

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

}  // namespace weft
