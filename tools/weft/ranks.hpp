// The processes of one `weft study`: one process on its own, or the ranks of an MPI job
// (`mpirun -np N weft study ...`, docs/distributed.md). The only code of weft that
// includes <mpi.h> is ranks.cpp, compiled with MPI when CMake found it (WEFT_HAVE_MPI); the
// kernel library never links MPI.
//
// When MPI starts: only when the process was launched by an MPI launcher (mpirun/mpiexec or
// a PMIx/PMI launcher such as srun: the environment says so), and only for the command that
// asks for it (`weft study`). A plain `weft study` or `weft run` never touches MPI: Open MPI's
// singleton start-up would be slow and, in a container without a network, can fail.
//
// Thread level: MPI_THREAD_FUNNELED. Only the main thread calls MPI (between the study's
// runs, never inside one); the simulation's oneTBB workers never do, so FUNNELED is all it
// needs, and it is the level Open MPI provides without the locks of MPI_THREAD_MULTIPLE.
//
// Waiting: a rank that finished its share waits in a non-blocking barrier, tested every
// millisecond with a sleep in between, instead of a blocking collective that Open MPI
// busy-polls: on a machine whose cores the other ranks are timing runs on, a spinning rank
// would take a core away from them and distort their timings.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace weftcli {

class Ranks {
 public:
  /// Joins the MPI job this process was launched in, if any (and weft was built with
  /// MPI); otherwise a single rank. MPI is finalised by the destructor or finish().
  static Ranks join();
  Ranks(Ranks&& other) noexcept;
  Ranks& operator=(Ranks&&) = delete;
  Ranks(const Ranks&) = delete;
  ~Ranks();

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool root() const { return rank_ == 0; }
  bool distributed() const { return mpi_; }
  const std::string& host() const { return host_; }  // this machine's host name

  /// Every rank passes its bytes; every rank gets every rank's, in rank order. A rank
  /// that arrives early waits without spinning (see the note above).
  std::vector<std::string> allGather(const std::string& mine) const;
  /// Rank 0's value, on every rank.
  int broadcast(int value) const;
  /// Ends every rank of the job with this exit code (after a message on this rank's
  /// stderr); a single rank just exits.
  [[noreturn]] void abort(int exitCode) const;
  /// Finalises MPI now (before forking a plotting process, say); no call after this.
  void finish();

 private:
  Ranks() = default;
  void politeBarrier() const;
  int rank_ = 0;
  int size_ = 1;
  bool mpi_ = false;  // MPI initialised by this object and not yet finalised
  std::string host_;
};

/// The host name of this machine (gethostname), "unknown" if it has none.
std::string hostName();

/// Bytes of plain values and strings, in the order written; read back in the same order on
/// any rank (all ranks of one job run the same binary on the same architecture).
class Packer {
 public:
  template <class T>
  void put(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes_.append(reinterpret_cast<const char*>(&value), sizeof value);
  }
  void put(std::string_view text) {
    put<std::uint64_t>(text.size());
    bytes_.append(text.data(), text.size());
  }
  void put(const std::string& text) { put(std::string_view(text)); }
  void put(const char* text) { put(std::string_view(text)); }
  const std::string& bytes() const { return bytes_; }

 private:
  std::string bytes_;
};

class Unpacker {
 public:
  explicit Unpacker(std::string_view bytes) : bytes_(bytes) {}
  template <class T>
  T get();
  std::string getString();
  bool done() const { return at_ == bytes_.size(); }

 private:
  void need(std::size_t n) const;
  std::string_view bytes_;
  std::size_t at_ = 0;
};

template <class T>
T Unpacker::get() {
  static_assert(std::is_trivially_copyable_v<T>);
  need(sizeof(T));
  T value;
  std::memcpy(&value, bytes_.data() + at_, sizeof value);
  at_ += sizeof value;
  return value;
}

}  // namespace weftcli
