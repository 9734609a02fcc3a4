// tests/fuzz/fuzz_checkpoint.cpp — a libFuzzer target for checkpoints (run by tools/fuzz.sh).
//
// The first byte of an input picks one of the simulations of checkpoint_scenes.hpp (bits
// 0-1) and whether the checksum is recomputed before restoring (bit 2: then the mutations
// reach the sections behind it, as a file made on purpose would). Simulation::restore must
// accept the rest or throw std::runtime_error; a refused checkpoint must leave the
// simulation bitwise as it was, and an accepted one must step without a crash or a
// sanitizer report. Anything else (another exception, a crash, a changed state, a timeout)
// is a finding.
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>

#include "checkpoint_scenes.hpp"

namespace {

fuzzcheckpoint::Simulations& simulations() {
  static fuzzcheckpoint::Simulations s = [] {
    fuzzcheckpoint::Simulations made = fuzzcheckpoint::makeSimulations();
    (void)made.flag->run(3);  // a few steps: carry-over and caches in use
    (void)made.drapeVerlet->run(3);
    (void)made.drapeImplicit->run(3);
    (void)made.tablecloth->run(3);
    return made;
  }();
  return s;
}

template <class S>
void check(weft::Simulation<S>& sim, const std::string& bytes) {
  const std::string before = sim.checkpoint();
  try {
    sim.restore(bytes, "fuzz");
  } catch (const std::runtime_error&) {
    if (sim.checkpoint() != before) __builtin_trap();  // a refused checkpoint changed the simulation
    return;
  }
  (void)sim.step();  // may fail (a status), never crash
  sim.restore(before, "baseline");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const int which = data[0] & 3;
  std::string bytes(reinterpret_cast<const char*>(data + 1), size - 1);
  if ((data[0] & 4) && bytes.size() >= 8) {
    const std::uint64_t sum = weft::fnv1a64(bytes.data(), bytes.size() - 8);
    std::memcpy(bytes.data() + bytes.size() - 8, &sum, 8);
  }
  fuzzcheckpoint::Simulations& s = simulations();
  switch (which) {
    case 0:
      check(*s.flag, bytes);
      break;
    case 1:
      check(*s.drapeVerlet, bytes);
      break;
    case 2:
      check(*s.drapeImplicit, bytes);
      break;
    default:
      check(*s.tablecloth, bytes);
      break;
  }
  return 0;
}
