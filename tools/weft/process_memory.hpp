// The memory of the weft process, as `weft run` and `weft soak` report it (Linux).
#pragma once

#include <sys/resource.h>
#include <unistd.h>

#include <fstream>

namespace weftcli {

/// The process's peak resident memory so far, MB (getrusage).
inline double peakResidentMegabytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

/// Resident memory of this process now, bytes (/proc/self/statm; 0 if unreadable).
inline double residentBytes() {
  std::ifstream statm("/proc/self/statm");
  double pages = 0, resident = 0;
  if (!(statm >> pages >> resident)) return 0;
  return resident * static_cast<double>(sysconf(_SC_PAGESIZE));
}

}  // namespace weftcli
