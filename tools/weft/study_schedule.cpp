// The study's tasks over the ranks (study_schedule.hpp).
#include "study_schedule.hpp"

#include <algorithm>
#include <chrono>
#include <iostream>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace weftcli {

std::vector<int> assignLargestFirst(const std::vector<StudyTask>& tasks, int rankCount) {
  std::vector<std::size_t> order(tasks.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return tasks[a].cost > tasks[b].cost; });
  std::vector<double> load(static_cast<std::size_t>(std::max(rankCount, 1)), 0.0);
  std::vector<int> owner(tasks.size(), 0);
  for (const std::size_t t : order) {
    const auto least = static_cast<std::size_t>(std::min_element(load.begin(), load.end()) - load.begin());
    owner[t] = static_cast<int>(least);
    load[least] += tasks[t].cost;
  }
  return owner;
}

std::vector<std::string> runSpread(const Ranks& ranks, const std::string& phase, const std::vector<StudyTask>& tasks,
                                   const std::function<std::string(std::size_t)>& work,
                                   std::vector<TaskRecord>& records) {
  using Clock = std::chrono::steady_clock;
  const std::vector<int> owner = assignLargestFirst(tasks, ranks.size());
  std::vector<std::size_t> mine;
  for (std::size_t t = 0; t < tasks.size(); ++t)
    if (owner[t] == ranks.rank()) mine.push_back(t);
  std::stable_sort(mine.begin(), mine.end(),
                   [&](std::size_t a, std::size_t b) { return tasks[a].cost > tasks[b].cost; });

  const auto started = Clock::now();
  auto lastReport = started;
  // This rank's results: (index, wall seconds, result bytes) per task.
  Packer packed;
  packed.put(ranks.host());
  packed.put<std::uint64_t>(mine.size());
  for (std::size_t k = 0; k < mine.size(); ++k) {
    const std::size_t t = mine[k];
    const auto start = Clock::now();
    const std::string result = work(t);
    const double wall = std::chrono::duration<double>(Clock::now() - start).count();
    packed.put<std::uint64_t>(t);
    packed.put(wall);
    packed.put(result);
    if (ranks.root() && Clock::now() - lastReport > std::chrono::seconds(2)) {
      lastReport = Clock::now();
      std::cerr << "study: " << phase << ": " << k + 1 << " of " << mine.size() << " task(s) of rank 0 done ("
                << std::chrono::duration<double>(lastReport - started).count() << " s)" << std::endl;
    }
  }
  const std::vector<std::string> parts = ranks.allGather(packed.bytes());
  const double phaseWall = std::chrono::duration<double>(Clock::now() - started).count();
  std::vector<std::string> results(tasks.size());
  std::vector<bool> seen(tasks.size(), false);
  std::vector<double> busyOf(parts.size(), 0.0);
  for (std::size_t r = 0; r < parts.size(); ++r) {
    Unpacker in(parts[r]);
    const std::string host = in.getString();
    const auto count = in.get<std::uint64_t>();
    for (std::uint64_t k = 0; k < count; ++k) {
      const auto t = in.get<std::uint64_t>();
      const double wall = in.get<double>();
      if (t >= tasks.size() || seen[t] || owner[t] != static_cast<int>(r))
        throw std::runtime_error("study: rank " + std::to_string(r) + " returned a task it was not given (" +
                                 std::to_string(t) + ")");
      seen[t] = true;
      results[t] = in.getString();
      busyOf[r] += wall;
      records.push_back({phase, tasks[t].name, tasks[t].cost, static_cast<int>(r), host, wall});
    }
  }
  if (std::find(seen.begin(), seen.end(), false) != seen.end())
    throw std::runtime_error("study: a task of phase '" + phase + "' came back from no rank");
  if (ranks.root()) {
    std::ostringstream line;
    line.precision(3);
    line << "study: " << phase << ": " << tasks.size() << " task(s) in " << phaseWall << " s";
    if (ranks.size() > 1) {
      line << " on " << ranks.size() << " ranks, busy";
      for (const double b : busyOf) line << ' ' << b;
      line << " s";
    }
    std::cerr << line.str() << std::endl;
  }
  return results;
}

}  // namespace weftcli
