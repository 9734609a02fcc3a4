// tests/support/cli_runner.hpp — runs a program (the `weft` command line) as a separate process
// and captures its stdout, stderr and exit code, for the tests that check the command line
// from outside (test_cli, test_scene).
#pragma once

#include <string>

namespace weft::test {

/// Where a run's stderr goes.
enum class Stderr {
  Discard,  // to /dev/null
  Merge,    // into CliRun::out, interleaved as the program wrote it (2>&1)
  Capture,  // into CliRun::err, apart from stdout
};

struct CliRun {
  int exitCode = -1;  // the exit status, or 128 + the signal that ended the program
  std::string out;    // stdout (with Stderr::Merge, stdout and stderr)
  std::string err;    // stderr with Stderr::Capture, else empty
};

/// Runs `'<program>' <args>` through the shell and waits for it. `args` is shell words: the
/// caller quotes what needs quoting. A shell that cannot be started is a test failure
/// (exitCode stays -1).
CliRun runProgram(const std::string& program, const std::string& args, Stderr stderrTo);

}  // namespace weft::test
