// The memory of the weft process, as `weft run` and `weft soak` report it (Linux).
#pragma once

#include <sys/resource.h>
#include <unistd.h>

#include <fstream>

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define WEFT_SANITIZER_HEAP 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define WEFT_SANITIZER_HEAP 1
#endif
#endif
#if defined(WEFT_SANITIZER_HEAP)
#include <cstddef>
// The sanitizers' allocator (declared here: GCC 12 ships no allocator_interface.h).
extern "C" std::size_t __sanitizer_get_current_allocated_bytes();
#elif defined(__GLIBC__)
#include <malloc.h>
#endif

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

/// Bytes the process holds from its allocator now (what `new` and `malloc` handed out and
/// were not given back), or -1 where the allocator does not say. Unlike resident memory it
/// does not grow when pages reserved earlier are first touched: a buffer sized at
/// construction counts in full from then on, so growth in it is an allocation.
inline double heapBytes() {
#if defined(WEFT_SANITIZER_HEAP)
  return static_cast<double>(__sanitizer_get_current_allocated_bytes());
#elif defined(__GLIBC__)
  const struct mallinfo2 info = mallinfo2();  // every arena: small blocks and mmapped ones
  return static_cast<double>(info.uordblks) + static_cast<double>(info.hblkhd);
#else
  return -1;
#endif
}

}  // namespace weftcli
