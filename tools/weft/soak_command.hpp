// `weft soak`: long runs of every built-in scene on 1 and 2 threads — no NaN, energy
// bounded where the physics bounds it, no memory growth after the first steps, the same
// final hash on both thread counts. docs/benchmarks.md has a run and its table.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace weftcli {

struct SoakOptions {
  double seconds = 60;                // simulated seconds per scene (each scene stops earlier at maxSteps)
  std::int64_t maxSteps = 1000000;    // steps per scene at most
  std::vector<std::string> scenes;    // built-in scene names (empty: all)
  std::vector<int> threads = {1, 2};  // thread counts: every one must give the same final hash
  std::string out;                    // also write the Markdown table here (empty: stdout only)
};

/// Runs the soak and prints one Markdown table row per scene; returns 0 when every check
/// holds, 1 otherwise (the table's last column says which failed).
int runSoak(const SoakOptions& options);

}  // namespace weftcli
