// Ranks (ranks.hpp): MPI when built with it (WEFT_HAVE_MPI) and launched by an MPI
// launcher, a single rank otherwise.
#include "ranks.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <iostream>
#include <stdexcept>
#include <thread>

#ifdef WEFT_HAVE_MPI
#include <mpi.h>
#endif

namespace weftcli {

std::string hostName() {
  char name[256] = {};
  if (gethostname(name, sizeof name - 1) != 0 || name[0] == '\0') return "unknown";
  return name;
}

std::string Unpacker::getString() {
  const auto size = get<std::uint64_t>();
  need(size);
  std::string text(bytes_.substr(at_, size));
  at_ += size;
  return text;
}

void Unpacker::need(std::size_t n) const {
  if (n > bytes_.size() - at_)
    throw std::runtime_error("study: a rank's results are shorter than they should be (" + std::to_string(n) +
                             " more bytes needed at byte " + std::to_string(at_) + " of " +
                             std::to_string(bytes_.size()) + ")");
}

namespace {
#ifdef WEFT_HAVE_MPI
/// Launched by mpirun/mpiexec (Open MPI sets OMPI_COMM_WORLD_SIZE) or by a PMIx/PMI
/// launcher (srun, MPICH's hydra).
bool launchedByMpi() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE"})
    if (std::getenv(name)) return true;
  return false;
}

void check(int code, const char* what) {
  if (code == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING] = {};
  int length = 0;
  MPI_Error_string(code, text, &length);
  throw std::runtime_error(std::string("study: ") + what + " failed: " + text);
}
#endif
}  // namespace

Ranks Ranks::join() {
  Ranks ranks;
  ranks.host_ = hostName();
#ifdef WEFT_HAVE_MPI
  int initialised = 0;
  MPI_Initialized(&initialised);
  if (!initialised && launchedByMpi()) {
    int provided = 0;
    if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
      throw std::runtime_error("study: MPI_Init_thread failed");
    ranks.mpi_ = true;
    if (provided < MPI_THREAD_FUNNELED) {
      std::cerr << "weft study: this MPI provides no MPI_THREAD_FUNNELED (only the main thread calls MPI, "
                   "the simulation's worker threads never do)\n";
      ranks.abort(2);
    }
    MPI_Comm_rank(MPI_COMM_WORLD, &ranks.rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &ranks.size_);
  }
#endif
  return ranks;
}

Ranks::Ranks(Ranks&& other) noexcept
    : rank_(other.rank_), size_(other.size_), mpi_(other.mpi_), host_(std::move(other.host_)) {
  other.mpi_ = false;
}

Ranks::~Ranks() { finish(); }

void Ranks::finish() {
#ifdef WEFT_HAVE_MPI
  if (mpi_) MPI_Finalize();
#endif
  mpi_ = false;
}

void Ranks::politeBarrier() const {
#ifdef WEFT_HAVE_MPI
  MPI_Request request;
  check(MPI_Ibarrier(MPI_COMM_WORLD, &request), "MPI_Ibarrier");
  for (;;) {
    int done = 0;
    check(MPI_Test(&request, &done, MPI_STATUS_IGNORE), "MPI_Test");
    if (done) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
#endif
}

std::vector<std::string> Ranks::allGather(const std::string& mine) const {
  if (!mpi_) return {mine};
#ifdef WEFT_HAVE_MPI
  // Everyone is here after the barrier, so the blocking collectives below do not spin long.
  politeBarrier();
  const auto size = static_cast<long long>(mine.size());
  std::vector<long long> sizes(static_cast<std::size_t>(size_));
  check(MPI_Allgather(&size, 1, MPI_LONG_LONG, sizes.data(), 1, MPI_LONG_LONG, MPI_COMM_WORLD), "MPI_Allgather");
  std::vector<int> counts(sizes.size()), offsets(sizes.size());
  long long total = 0;
  for (std::size_t r = 0; r < sizes.size(); ++r) {
    if (sizes[r] > (1LL << 30) || total > (1LL << 30))  // MPI counts are int
      throw std::runtime_error("study: a rank's results exceed 1 GiB");
    counts[r] = static_cast<int>(sizes[r]);
    offsets[r] = static_cast<int>(total);
    total += sizes[r];
  }
  std::string all(static_cast<std::size_t>(total), '\0');
  check(MPI_Allgatherv(mine.data(), counts[static_cast<std::size_t>(rank_)], MPI_BYTE, all.data(), counts.data(),
                       offsets.data(), MPI_BYTE, MPI_COMM_WORLD),
        "MPI_Allgatherv");
  std::vector<std::string> parts;
  for (std::size_t r = 0; r < sizes.size(); ++r) parts.push_back(all.substr(offsets[r], counts[r]));
  return parts;
#else
  return {mine};
#endif
}

int Ranks::broadcast(int value) const {
#ifdef WEFT_HAVE_MPI
  if (mpi_) {
    politeBarrier();
    check(MPI_Bcast(&value, 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Bcast");
  }
#endif
  return value;
}

void Ranks::abort(int exitCode) const {
  std::cerr.flush();
#ifdef WEFT_HAVE_MPI
  if (mpi_) MPI_Abort(MPI_COMM_WORLD, exitCode);
#endif
  std::exit(exitCode);
}

}  // namespace weftcli
