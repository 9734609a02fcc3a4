// weft::io: a built-in scene read, assembled and run.
#include <cstdio>
#include <weft/io/scene.hpp>
#include <weft/weft.hpp>

int main() {
  const weft::SceneSpec spec = weft::builtinSceneSpec("ball-on-brick");
  weft::AssembledScene<double> scene = weft::assembleScene<double>(spec);
  weft::Simulation<double> sim(std::move(scene.built), scene.options);
  if (!sim.run(60).ok()) return 1;
  std::printf("%s: %d bodies, %lld contacts\n", spec.name.c_str(),
              static_cast<int>(sim.rigidWorld()->model().bodyCount()),
              static_cast<long long>(sim.rigidWorld()->lastStats().contacts));
  return sim.rigidWorld()->lastStats().contacts > 0 ? 0 : 1;
}
