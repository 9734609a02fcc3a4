// tests/test_cli_mpi.cpp — `mpirun -np 2 weft study` writes the files a single process writes
// (docs/distributed.md), but for what depends on the clock or the machine. Registered only when
// CMake found MPI; WEFT_CLI_PATH is the binary, WEFT_MPIEXEC the launcher.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "support/cli_runner.hpp"

#ifndef WEFT_CLI_PATH
#error "WEFT_CLI_PATH must name the weft binary"
#endif
#ifndef WEFT_MPIEXEC
#error "WEFT_MPIEXEC must name mpirun"
#endif

namespace weft::test {
namespace {

std::vector<std::string> lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> out;
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

std::vector<std::string> split(const std::string& line, char separator) {
  std::vector<std::string> cells;
  std::stringstream in(line);
  for (std::string cell; std::getline(in, cell, separator);) cells.push_back(cell);
  return cells;
}

/// The study's CSV without the columns that depend on the clock or the machine.
std::vector<std::vector<std::string>> csvWithoutTimings(const std::string& path) {
  const std::vector<std::string> text = lines(path);
  std::vector<std::vector<std::string>> rows;
  if (text.empty()) return rows;
  const std::vector<std::string> header = split(text[0], ',');
  std::vector<bool> keep;
  for (const std::string& column : header)
    keep.push_back(column != "wall_seconds" && column != "wall_per_simulated_second" && column != "host");
  for (const std::string& line : text) {
    const std::vector<std::string> cells = split(line, ',');
    EXPECT_EQ(cells.size(), header.size()) << path << ": " << line;
    std::vector<std::string> kept;
    for (std::size_t c = 0; c < cells.size() && c < keep.size(); ++c)
      if (keep[c]) kept.push_back(cells[c]);
    rows.push_back(kept);
  }
  return rows;
}

/// The study's Markdown with the table "Cheapest run reaching each error" reduced to its
/// first two cells (scene, error target): which run is cheapest is decided by wall time,
/// so it may differ between any two runs, on one process or several.
std::vector<std::string> markdownWithoutTimings(const std::string& path) {
  std::vector<std::string> out;
  bool cheapest = false;
  for (const std::string& line : lines(path)) {
    if (line.rfind("## ", 0) == 0) cheapest = line.find("Cheapest run") != std::string::npos;
    if (cheapest && line.rfind("| ", 0) == 0 && line.find("| error <=") == std::string::npos) {
      const std::vector<std::string> cells = split(line, '|');
      out.push_back(cells.size() > 2 ? cells[1] + "|" + cells[2] : line);
    } else {
      out.push_back(line);
    }
  }
  return out;
}

TEST(CliMpi, StudyOnTwoRanksWritesWhatOneProcessWrites) {
  // Two scenes (the oscillator and the rope, whose reference is a run), one thread per run: a
  // second on one process, the same spread over two ranks (more ranks than cores is allowed).
  const std::string sweep = "study --quick --scene oscillator rope --threads 1 --no-plot";
  const std::string one = ::testing::TempDir() + "weft_study_mpi_one";
  const std::string two = ::testing::TempDir() + "weft_study_mpi_two";
  const CliRun single = runProgram(WEFT_CLI_PATH, sweep + " --out '" + one + "'", Stderr::Merge);
  ASSERT_EQ(single.exitCode, 0) << single.out;
  // CI runs as root: Open MPI refuses root unless told (the variables only allow it). Under
  // AddressSanitizer, Open MPI's own leaks are suppressed by their Open MPI frames
  // (tests/lsan.supp), which only the slow unwinder finds (the option is ignored without ASan).
  const CliRun spread = runProgram(
      "env",
      "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
      "ASAN_OPTIONS=\"${ASAN_OPTIONS:+$ASAN_OPTIONS:}fast_unwind_on_malloc=0\" '" WEFT_MPIEXEC
      "' -np 2 --oversubscribe '" +
          std::string(WEFT_CLI_PATH) + "' " + sweep + " --schedule '" + two + "/schedule.csv' --out '" + two + "'",
      Stderr::Merge);
  ASSERT_EQ(spread.exitCode, 0) << spread.out;
  EXPECT_NE(spread.out.find("on 2 ranks"), std::string::npos) << "the ranks did not share the work:\n" << spread.out;

  const auto csvOne = csvWithoutTimings(one + "/study.csv");
  const auto csvTwo = csvWithoutTimings(two + "/study.csv");
  ASSERT_GT(csvOne.size(), 20u);
  ASSERT_EQ(csvOne.size(), csvTwo.size());
  for (std::size_t r = 0; r < csvOne.size(); ++r) EXPECT_EQ(csvOne[r], csvTwo[r]) << "study.csv line " << r + 1;

  const auto mdOne = markdownWithoutTimings(one + "/study.md");
  const auto mdTwo = markdownWithoutTimings(two + "/study.md");
  ASSERT_GT(mdOne.size(), 20u);
  ASSERT_EQ(mdOne.size(), mdTwo.size());
  for (std::size_t l = 0; l < mdOne.size(); ++l) EXPECT_EQ(mdOne[l], mdTwo[l]) << "study.md line " << l + 1;

  // Both ranks ran tasks, and every row says where it was timed.
  const std::vector<std::string> schedule = lines(two + "/schedule.csv");
  ASSERT_GT(schedule.size(), 1u);
  bool rank[2] = {false, false};
  for (std::size_t l = 1; l < schedule.size(); ++l) {
    const std::vector<std::string> cells = split(schedule[l], ',');
    ASSERT_EQ(cells.size(), 6u) << schedule[l];
    rank[cells[3] == "1"] = true;
  }
  EXPECT_TRUE(rank[0] && rank[1]) << "every task ran on one rank";
  const std::vector<std::string> header = split(lines(two + "/study.csv").at(0), ',');
  std::size_t host = 0;
  while (host < header.size() && header[host] != "host") ++host;
  ASSERT_LT(host, header.size()) << "study.csv has no host column";
  for (const std::string& line : lines(two + "/study.csv")) EXPECT_FALSE(split(line, ',').at(host).empty()) << line;
}

}  // namespace
}  // namespace weft::test
