#include "weft/scene/builtin_scenes.hpp"

#include <algorithm>
#include <stdexcept>

namespace weft {

const char* builtinSceneName(BuiltinScene scene) {
  switch (scene) {
    case BuiltinScene::Flag:
      return "flag";
    case BuiltinScene::Rope:
      return "rope";
  }
  return "unknown";
}

BuiltinScene parseBuiltinScene(const std::string& name) {
  if (name == "flag") return BuiltinScene::Flag;
  if (name == "rope") return BuiltinScene::Rope;
  throw std::invalid_argument("scene must be one of flag, rope; got '" + name + "'");
}

ClothGridSpec flagSpec(Index size) {
  ClothGridSpec spec;
  spec.width = size;
  spec.height = size;
  spec.origin = {0, 0, 0};
  spec.rowAxis = {1, 0, 0};
  spec.columnAxis = {0, 0, 1};
  spec.spacing = size >= 2 ? 1.0 / static_cast<double>(size - 1) : 1.0;
  spec.totalMass = 0.5;
  spec.structural = {500, 0.02};
  spec.shear = {250, 0.01};
  spec.bend = {50, 0.002};
  return spec;
}

RopeSpec ropeSpec(Index particleCount) {
  RopeSpec spec;
  spec.particleCount = particleCount;
  spec.origin = {0, 0, 0};
  spec.direction = {1, 0, 0};
  spec.length = 1;
  spec.totalMass = 0.1;
  spec.structural = {2000, 0.02};
  spec.bendSprings = true;
  spec.bend = {100, 0.002};
  return spec;
}

template <class S>
ModelAndState<S> makeFlag(Index size) {
  const ClothGridSpec spec = flagSpec(size);
  ModelBuilder<S> builder;
  addClothGrid(builder, spec);
  builder.pin(gridIndex(spec, 0, 0));
  builder.pin(gridIndex(spec, 0, spec.width - 1));
  return builder.build();
}

template <class S>
ModelAndState<S> makeRope(Index particleCount) {
  ModelBuilder<S> builder;
  addRope(builder, ropeSpec(particleCount));
  builder.pin(0);
  return builder.build();
}

template <class S>
ModelAndState<S> makeBuiltinScene(BuiltinScene scene, Index size) {
  return scene == BuiltinScene::Flag ? makeFlag<S>(size) : makeRope<S>(size);
}

// The flag's grid side and the rope's particle count happen to be the same.
Index defaultSceneSize(BuiltinScene) { return 64; }

double defaultTimeStep(BuiltinScene scene, Index size) {
  // The reference step, measured at the default size for the flag and the rope alike (see
  // docs/integrators.md); the highest frequency scales like the particle count per unit
  // length.
  const double reference = 2e-4;
  const double scale = static_cast<double>(defaultSceneSize(scene)) / static_cast<double>(std::max<Index>(size, 2));
  return reference * std::min(1.0, scale);
}

template ModelAndState<float> makeFlag(Index);
template ModelAndState<double> makeFlag(Index);
template ModelAndState<float> makeRope(Index);
template ModelAndState<double> makeRope(Index);
template ModelAndState<float> makeBuiltinScene(BuiltinScene, Index);
template ModelAndState<double> makeBuiltinScene(BuiltinScene, Index);

}  // namespace weft
