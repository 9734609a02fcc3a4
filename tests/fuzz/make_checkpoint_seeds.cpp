// tests/fuzz/make_checkpoint_seeds.cpp — writes the seeds of fuzz_checkpoint into a
// directory: each simulation of checkpoint_scenes.hpp after 0 and 3 steps, with the first
// byte choosing it, with and without the checksum recomputed. tools/fuzz.sh runs it before
// every fuzzing run (checkpoints belong to the build that writes them, so seeds are not
// committed).
#include <cstdio>
#include <fstream>
#include <string>

#include "checkpoint_scenes.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIRECTORY\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  fuzzcheckpoint::Simulations s = fuzzcheckpoint::makeSimulations();
  for (int steps = 0; steps <= 3; steps += 3) {
    if (steps > 0) {
      (void)s.flag->run(steps);
      (void)s.drapeVerlet->run(steps);
      (void)s.drapeImplicit->run(steps);
      (void)s.tablecloth->run(steps);
    }
    for (int k = 0; k < fuzzcheckpoint::Simulations::kCount; ++k)
      for (int reseal = 0; reseal < 2; ++reseal) {
        const char first = static_cast<char>(k | (reseal << 2));
        std::ofstream out(
            dir + "/sim" + std::to_string(k) + "-step" + std::to_string(steps) + (reseal ? "-resealed" : "") + ".bin",
            std::ios::binary);
        out << first << fuzzcheckpoint::checkpointOf(s, k);
      }
  }
  return 0;
}
