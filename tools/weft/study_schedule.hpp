// How `weft study` spreads its work over the ranks of an MPI job (docs/distributed.md).
//
// The study runs in three phases, each a list of independent tasks whose results the next
// phase needs: the references (one per scene), the largest stable steps (one bisection per
// scene x integrator x precision), the sweep's points (one per scene x integrator x
// precision x dt or tolerance, timed on every thread count). Within a phase the tasks are
// assigned statically, largest first (LPT: sorted by an estimated cost, each given to the
// rank with the least estimated work so far), and each rank runs its share largest first;
// then every rank gets every result. Static, not a master handing out tasks: no rank serves
// requests while it times a run, no MPI call happens inside a timed run, and the assignment
// is a function of the sweep alone (the same on every rank, reproducible). What it costs
// when the estimates are off is measured in docs/distributed.md.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "ranks.hpp"

namespace weftcli {

struct StudyTask {
  std::string name;  // "limit rope rk4 double", ...: for the schedule file and messages
  double cost = 0;   // estimated cost, any unit common to the phase (work ~ spring force evaluations)
};

/// Who ran a task and how long it took.
struct TaskRecord {
  std::string phase, name;
  double cost = 0;
  int rank = 0;
  std::string host;
  double wall = 0;  // s
};

/// The rank of each task: largest estimated cost first (ties: lower index), each to the
/// rank with the least estimated cost so far (ties: lower rank).
std::vector<int> assignLargestFirst(const std::vector<StudyTask>& tasks, int rankCount);

/// Runs this rank's share of `tasks` through `work(index)` (which returns the task's
/// result as bytes), largest first, then exchanges: returns every task's result, in task
/// order, on every rank, and appends every task's record to `records`. Rank 0 prints the
/// phase's progress and balance on stderr.
std::vector<std::string> runSpread(const Ranks& ranks, const std::string& phase, const std::vector<StudyTask>& tasks,
                                   const std::function<std::string(std::size_t)>& work,
                                   std::vector<TaskRecord>& records);

}  // namespace weftcli
