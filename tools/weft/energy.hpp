// Energies of a state, in double, for the command line's summaries and the study.
#pragma once

#include "weft/weft.hpp"

namespace weftcli {

struct Energy {
  double kinetic = 0, spring = 0, gravity = 0;  // J
  double total() const { return kinetic + spring + gravity; }
};

/// Kinetic energy of every particle, spring energy of every spring, and the gravity
/// potential -m g.x of the free particles.
template <class S>
Energy energy(const weft::Model<S>& model, const weft::State<S>& state, const weft::Vec3d& g) {
  Energy e;
  for (weft::Index i = 0; i < model.particleCount(); ++i) {
    const double m = model.mass()[i];
    const double v2 = static_cast<double>(state.v.row(i).squaredNorm());
    e.kinetic += 0.5 * m * v2;
    if (!model.isPinned(i))
      e.gravity -= m * (g.x * double(state.x(i, 0)) + g.y * double(state.x(i, 1)) + g.z * double(state.x(i, 2)));
  }
  const auto& sp = model.springs();
  for (weft::Index s = 0; s < sp.count(); ++s) {
    const double len = static_cast<double>((state.x.row(sp.a[s]) - state.x.row(sp.b[s])).norm());
    const double d = len - double(sp.restLength[s]);
    e.spring += 0.5 * double(sp.stiffness[s]) * d * d;
  }
  return e;
}

}  // namespace weftcli
