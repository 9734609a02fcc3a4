// tests/fuzz/checkpoint_scenes.hpp — the simulations fuzz_checkpoint restores into, and
// make_checkpoint_seeds writes its seeds from: small, and between them every section a
// checkpoint has (rk4; verlet's and implicit Euler's carry-over in float; rigid bodies with
// their warm-start caches beside a cloth; kinematic pins).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "weft/io/scene.hpp"
#include "weft/weft.hpp"

namespace fuzzcheckpoint {

struct Simulations {
  std::unique_ptr<weft::Simulation<double>> flag;          // rk4, double
  std::unique_ptr<weft::Simulation<float>> drapeVerlet;    // verlet, float, obstacles
  std::unique_ptr<weft::Simulation<float>> drapeImplicit;  // implicit Euler, float
  std::unique_ptr<weft::Simulation<double>> tablecloth;    // rigid bodies on a cloth, kinematic pins
  static constexpr int kCount = 4;
};

template <class S>
std::unique_ptr<weft::Simulation<S>> make(weft::SceneSpec spec) {
  weft::AssembledScene<S> a = weft::assembleScene<S>(spec);
  a.options.threads = 1;
  return std::make_unique<weft::Simulation<S>>(std::move(a.built), a.options);
}

inline Simulations makeSimulations() {
  Simulations s;
  s.flag = make<double>(weft::builtinSceneSpec("flag", 5));
  weft::SceneSpec drape = weft::builtinSceneSpec("drape", 6);
  drape.simulation.integrator = weft::IntegratorKind::VelocityVerlet;
  s.drapeVerlet = make<float>(drape);
  drape.simulation.integrator = weft::IntegratorKind::ImplicitEuler;
  s.drapeImplicit = make<float>(drape);
  s.tablecloth = make<double>(weft::builtinSceneSpec("tablecloth-slow", 8));
  return s;
}

/// Simulation k's checkpoint (k < Simulations::kCount).
inline std::string checkpointOf(Simulations& s, int k) {
  switch (k) {
    case 0:
      return s.flag->checkpoint();
    case 1:
      return s.drapeVerlet->checkpoint();
    case 2:
      return s.drapeImplicit->checkpoint();
    default:
      return s.tablecloth->checkpoint();
  }
}

}  // namespace fuzzcheckpoint
