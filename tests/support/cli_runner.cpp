// tests/support/cli_runner.cpp — runProgram (cli_runner.hpp): popen for stdout, a temporary
// file for a captured stderr.
#include "support/cli_runner.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace weft::test {

CliRun runProgram(const std::string& program, const std::string& args, Stderr stderrTo) {
  CliRun r;
  std::string errFile;
  std::string redirect = " 2>/dev/null";
  if (stderrTo == Stderr::Merge) redirect = " 2>&1";
  if (stderrTo == Stderr::Capture) {
    // A file of its own (mkstemp): ctest -j runs tests of one program side by side, and the
    // temporary directory may be shared with other builds.
    std::string pattern = ::testing::TempDir() + "weft_cli_stderr_XXXXXX";
    const int fd = mkstemp(pattern.data());
    if (fd < 0) {
      ADD_FAILURE() << "mkstemp failed: " << pattern;
      return r;
    }
    close(fd);
    errFile = pattern;
    redirect = " 2>'" + errFile + "'";
  }
  const std::string command = "'" + program + "' " + args + redirect;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) {
    ADD_FAILURE() << "popen failed: " << command;
    if (!errFile.empty()) std::remove(errFile.c_str());
    return r;
  }
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) r.out.append(buffer.data(), n);
  const int status = pclose(pipe);
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  if (!errFile.empty()) {
    std::ifstream in(errFile, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    r.err = text.str();
    std::remove(errFile.c_str());
  }
  return r;
}

}  // namespace weft::test
