// tests/fuzz/make_frame_cache_seeds.cpp — writes the seeds of fuzz_frame_cache with
// weft::FrameCacheWriter (not run by tools/fuzz.sh: the seeds are committed in
// tests/fuzz/seeds/frame_cache/; rerun it if the cache format changes):
//
//   cmake --build build-fuzz --target make_frame_cache_seeds
//   build-fuzz/tests/fuzz/make_frame_cache_seeds tests/fuzz/seeds/frame_cache
#include <cstdio>
#include <string>

#include "weft/io/frames.hpp"

namespace {

template <class S>
void write(const std::string& path, weft::Index particles, int frames) {
  weft::FrameCacheWriter<S> writer(path, particles);
  weft::State<S> state;
  state.x.resize(particles, 3);
  for (int f = 0; f < frames; ++f) {
    state.time = 0.01 * f;
    for (weft::Index i = 0; i < particles; ++i)
      for (int c = 0; c < 3; ++c) state.x(i, c) = static_cast<S>(0.1 * i + c - 0.5 * f);
    writer.append(state);
  }
  writer.close();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIRECTORY\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  write<float>(dir + "/float-4x3.wcache", 4, 3);
  write<double>(dir + "/double-4x3.wcache", 4, 3);
  write<double>(dir + "/double-9x1.wcache", 9, 1);
  write<float>(dir + "/float-0x2.wcache", 0, 2);
  write<double>(dir + "/double-empty.wcache", 5, 0);
  return 0;
}
