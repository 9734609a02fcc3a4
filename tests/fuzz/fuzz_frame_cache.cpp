// tests/fuzz/fuzz_frame_cache.cpp — a libFuzzer target for the frame cache reader (run by
// tools/fuzz.sh).
//
// Every input is written to a temporary file (one per fuzzing process, removed at exit)
// and opened with weft::FrameCacheReader<float> and <double>. A std::runtime_error from the
// constructor (the documented "frame cache '...': ..." rejection: truncated, bad magic,
// version, precision, a size that does not match the header) is the reader doing its job;
// anything else escaping, a crash, a sanitizer report (ASan + UBSan build), a timeout or
// an allocation beyond -rss_limit_mb is a finding.
//
// A cache the reader opens must match the format of weft/io/frames.hpp: the file is
// exactly 32 + F (8 + 3 n s) bytes, and frame k read back is the bytes at its offset
// (time, then the column-major coordinates). The first kMaxFrames frames are read and
// compared, when n <= kMaxParticles (the reader has already checked that the file holds
// them, so a larger n cannot make it allocate more than the input's size).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

#include "weft/io/frames.hpp"

namespace {

constexpr weft::Index kMaxFrames = 64;
constexpr weft::Index kMaxParticles = 100000;

const std::string& tempPath() {
  static const std::string path = [] {
    const char* dir = std::getenv("TMPDIR");
    std::string p =
        std::string(dir && *dir ? dir : "/tmp") + "/weft-fuzz-frame-cache-" + std::to_string(getpid()) + ".wcache";
    std::atexit([] { std::remove(tempPath().c_str()); });
    return p;
  }();
  return path;
}

template <class S>
void readAll(const std::string& path, const std::uint8_t* data, std::size_t size) {
  try {
    weft::FrameCacheReader<S> reader(path);
    const weft::Index n = reader.particleCount(), frames = reader.frameCount();
    if (n < 0 || frames < 0) __builtin_trap();
    const std::uint64_t frameBytes = 8 + 3 * static_cast<std::uint64_t>(n) * sizeof(S);
    if (size != 32 + static_cast<std::uint64_t>(frames) * frameBytes) __builtin_trap();
    if (n > kMaxParticles) return;
    weft::State<S> state;
    for (weft::Index k = 0; k < frames && k < kMaxFrames; ++k) {
      reader.read(k, state);
      const std::uint8_t* frame = data + 32 + k * frameBytes;
      if (state.x.rows() != n || state.x.cols() != 3 || std::memcmp(&state.time, frame, 8) != 0 ||
          (n > 0 && std::memcmp(state.x.data(), frame + 8, 3 * n * sizeof(S)) != 0))
        __builtin_trap();
    }
  } catch (const std::runtime_error&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string& path = tempPath();
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) std::abort();  // the harness, not the reader
  if (size > 0 && std::fwrite(data, 1, size, file) != size) std::abort();
  if (std::fclose(file) != 0) std::abort();
  readAll<float>(path, data, size);
  readAll<double>(path, data, size);
  return 0;
}
