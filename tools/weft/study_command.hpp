// `weft study`: what accuracy costs in time, for every integrator, step, precision and
// thread count, on three scenes (a damped oscillator with an exact solution, a rope
// released from horizontal, the flag). See docs/integrators.md for a run and its reading.
#pragma once

#include <string>
#include <vector>

namespace weftcli {

struct StudyOptions {
  bool quick = false;                 // small scenes, short runs, coarse bisection (< 1 min)
  std::string out = "study";          // output directory: study.csv, study.md, study.png/.svg
  std::vector<int> threads = {1, 2};  // thread counts to time
  bool plot = true;                   // run tools/plot_study.py through /usr/bin/python3
  std::vector<std::string> scenes;    // oscillator, rope, flag (empty: all three)
  std::string schedule;               // if set, rank 0 writes each task's rank, host and time here (CSV)
};

/// Runs the study and writes its files; returns the process exit code (0 on success).
/// Under mpirun the ranks share the work and rank 0 writes the files (docs/distributed.md).
int runStudy(const StudyOptions& options);

/// Draws study.png/.svg from study.csv (tools/plot_study.py); 0 on success or when skipped.
int plotStudy(const StudyOptions& options);

}  // namespace weftcli
