// Simulation::save / load (weft/scene/simulation.hpp): the checkpoint file.
//
// Layout (weft/core/archive.hpp writes the values in the machine's byte order):
//
//   "WEFTCKPT"                       8 bytes
//   format                           u32 (Simulation::kCheckpointFormat)
//   weft version                     text ("0.1.0")
//   scalar bytes                     u32 (4: float, 8: double)
//   model fingerprint                u64 (FNV-1a of masses, springs and triangles)
//   integrator                       i32 (IntegratorKind)
//   particles, rigid bodies, kinematic pins    i64 each
//   "SIMU" state (x, v, time), dt, status, step count, statistics, clock start, pin origins
//   "INTG" the integrator's carry-over (Integrator::saveCarry)
//   "RIGD" the rigid bodies (RigidWorld::saveCarry), when there are any
//   "SELF" the self-collision candidates (SelfCollider::saveCarry), when self-collision is on
//   "END "
//   checksum                         u64, FNV-1a of every byte before it
#if defined(__unix__) || defined(__APPLE__)
#include <unistd.h>
#endif

#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <system_error>

#include "collide/self_collider.hpp"
#include "core/text.hpp"
#include "model/precision_limits.hpp"
#include "weft/scene/simulation.hpp"

#ifndef WEFT_VERSION_STRING
#error "WEFT_VERSION_STRING must be defined by the build (the project's version)"
#endif

namespace weft {

namespace {

constexpr char kMagic[8] = {'W', 'E', 'F', 'T', 'C', 'K', 'P', 'T'};

template <class S>
std::uint64_t modelFingerprint(const Model<S>& m) {
  std::uint64_t h = fnv1a64(nullptr, 0);
  const auto add = [&](const auto& a) {
    const std::int64_t n = a.size();
    h = fnv1a64(&n, sizeof n, h);
    h = fnv1a64(a.data(), static_cast<std::size_t>(a.size()) * sizeof(*a.data()), h);
  };
  add(m.mass());
  add(m.inverseMass());
  add(m.springs().a);
  add(m.springs().b);
  add(m.springs().restLength);
  add(m.springs().stiffness);
  add(m.springs().damping);
  add(m.triangles().a);
  add(m.triangles().b);
  add(m.triangles().c);
  return h;
}

std::string hex(std::uint64_t v) {
  char buffer[24];
  std::snprintf(buffer, sizeof buffer, "%016llx", static_cast<unsigned long long>(v));
  return buffer;
}

const char* precisionName(std::uint32_t bytes) { return bytes == 4 ? "float" : bytes == 8 ? "double" : "unknown"; }

[[noreturn]] void fileError(const std::string& path, const std::string& what) {
  throw std::runtime_error("checkpoint '" + path + "': " + what);
}

}  // namespace

template <class S>
template <class Archive, class Self>
void Simulation<S>::transfer(Archive& a, Self& self) {
  a.field(self.state_.x, "positions");
  a.field(self.state_.v, "velocities");
  a.field(self.state_.time, "time");
  a.field(self.options_.dt, "time step");
  a.field(self.status_, "status");
  a.field(self.stepCount_, "step count");
  a.field(self.lastWork_, "the last step's work");
  a.field(self.totalWork_, "the run's work");
  a.field(self.lastCollision_, "the last step's collisions");
  a.field(self.totalCollision_, "the run's collisions");
  a.field(self.lastSelf_, "the last step's self-collisions");
  a.field(self.totalSelf_, "the run's self-collisions");
  a.field(self.lastCoupling_, "the last step's particle-body contacts");
  a.field(self.totalCoupling_, "the run's particle-body contacts");
  a.field(self.clockStart_, "clock start");
}

template <class S>
std::string Simulation<S>::checkpoint() const {
  std::string bytes;
  ArchiveWriter out(bytes);
  out.bytes(kMagic, sizeof kMagic);
  out.value(kCheckpointFormat);
  out.text(WEFT_VERSION_STRING);
  out.value(static_cast<std::uint32_t>(sizeof(S)));
  out.value(modelFingerprint(*model_));
  out.value(static_cast<std::int32_t>(options_.integrator));
  out.value(static_cast<std::int64_t>(model_->particleCount()));
  out.value(static_cast<std::int64_t>(rigid_ ? rigid_->model().bodyCount() : 0));
  out.value(static_cast<std::int64_t>(tracks_.size()));

  out.section("SIMU");
  transfer(out, *this);
  std::vector<Vec3d> origins;
  origins.reserve(tracks_.size());
  for (const KinematicTrack& t : tracks_) origins.push_back(t.reference);
  out.vector(origins);

  out.section("INTG");
  integrator_->saveCarry(out);
  if (rigid_) rigid_->saveCarry(out);
  if (self_) self_->saveCarry(out);
  out.section("END ");
  const std::uint64_t checksum = fnv1a64(bytes.data(), bytes.size());
  out.value(checksum);
  return bytes;
}

template <class S>
void Simulation<S>::restore(std::string_view bytes, const std::string& source) {
  ArchiveReader in(bytes, source);
  if (bytes.size() < sizeof kMagic + 4 + 8 || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
    in.fail("not a weft checkpoint (no WEFTCKPT header)");
  char magic[8];
  in.bytes(magic, sizeof magic);
  const auto format = in.value<std::uint32_t>();
  if (format != kCheckpointFormat)
    in.fail("checkpoint format " + std::to_string(format) + ", this weft reads format " +
            std::to_string(kCheckpointFormat));
  std::uint64_t stored = 0;
  std::memcpy(&stored, bytes.data() + bytes.size() - sizeof stored, sizeof stored);
  const std::uint64_t computed = fnv1a64(bytes.data(), bytes.size() - sizeof stored);
  if (stored != computed)
    in.fail("damaged: the checksum is " + hex(computed) + ", the file says " + hex(stored) +
            " (changed or cut short after it was written)");
  const std::string version = in.text("weft version", 64);
  if (version != WEFT_VERSION_STRING)
    in.fail("written by weft " + version + ", this is weft " + WEFT_VERSION_STRING +
            " (a checkpoint resumes only on the version that wrote it)");
  const auto scalar = in.value<std::uint32_t>();
  if (scalar != sizeof(S))
    in.fail(std::string("written in ") + precisionName(scalar) + " precision, this simulation is " +
            precisionName(sizeof(S)));
  const auto fingerprint = in.value<std::uint64_t>();
  if (fingerprint != modelFingerprint(*model_))
    in.fail("written for another model (fingerprint " + hex(fingerprint) + ", this simulation's model " +
            hex(modelFingerprint(*model_)) + "): other particles, masses, springs or triangles");
  const auto integrator = in.value<std::int32_t>();
  if (integrator != static_cast<std::int32_t>(options_.integrator)) {
    const bool known = integrator >= 0 && integrator < static_cast<std::int32_t>(std::size(kAllIntegrators));
    in.fail(std::string("written by the integrator ") +
            (known ? integratorName(static_cast<IntegratorKind>(integrator)) : std::to_string(integrator).c_str()) +
            ", this simulation uses " + integratorName(options_.integrator));
  }
  const auto particles = in.value<std::int64_t>(), bodies = in.value<std::int64_t>(), pins = in.value<std::int64_t>();
  const std::int64_t ownBodies = rigid_ ? rigid_->model().bodyCount() : 0;
  if (particles != model_->particleCount())
    in.fail(std::to_string(particles) + " particles in the file, " + std::to_string(model_->particleCount()) +
            " in this simulation");
  if (bodies != ownBodies)
    in.fail(std::to_string(bodies) + " rigid bodies in the file, " + std::to_string(ownBodies) + " in this simulation");
  if (pins != static_cast<std::int64_t>(tracks_.size()))
    in.fail(std::to_string(pins) + " kinematic pins in the file, " + std::to_string(tracks_.size()) +
            " in this simulation");

  // What follows was written by this version for this model: it is read into the
  // Simulation directly, and should a section still be malformed (a file made to pass the
  // checks above) the Simulation is put back as it was.
  const std::string before = checkpoint();
  nowIntersections_ = -1;  // (the state is about to change, even if the load is refused)
  try {
    in.section("SIMU");
    transfer(in, *this);
    std::vector<Vec3d> origins;
    in.vector(origins, "kinematic pin origins");
    if (origins.size() != tracks_.size()) in.fail("kinematic pin origins: " + std::to_string(origins.size()));
    for (size_t k = 0; k < tracks_.size(); ++k) {
      const Vec3d& o = origins[k];
      if (!(std::isfinite(o.x) && std::isfinite(o.y) && std::isfinite(o.z)))
        in.fail("kinematic pin origin " + std::to_string(k) + " is not finite");
      tracks_[k].reference = o;
    }
    if (!detail::PrecisionLimits<S>::timeStep(options_.dt))
      in.fail("the time step " + detail::number(options_.dt) + " s is not " +
              detail::PrecisionLimits<S>::timeStepRule());
    if (!std::isfinite(state_.time) || !std::isfinite(clockStart_)) in.fail("the time is not finite");
    if (stepCount_ < 0) in.fail("a negative step count, " + std::to_string(stepCount_));
    const int code = static_cast<int>(status_.code);
    if (code < 0 || code > static_cast<int>(StepCode::TooManyCandidates))
      in.fail("an unknown step status, " + std::to_string(code));
    in.checkFlag(lastWork_, offsetof(StepWork, failed), "the last step's work");
    in.checkFlag(totalWork_, offsetof(StepWork, failed), "the run's work");
    if (!state_.x.allFinite() || !state_.v.allFinite()) in.fail("the state is not finite");
    in.section("INTG");
    integrator_->loadCarry(in);
    if (rigid_) rigid_->loadCarry(in);
    if (self_) self_->loadCarry(in);
    in.section("END ");
    if (in.remaining() != sizeof(std::uint64_t)) in.fail(std::to_string(in.remaining() - 8) + " bytes too many");
    // What the warnings compare the run with: the state loaded (not when putting back the
    // state before a refused load, whose start stays as it was).
    if (!rollingBack_) recordStart();
  } catch (...) {
    // (Once only: should the state before loading not load back, nothing more can be
    // tried, and its error goes up rather than another attempt.)
    if (rollingBack_) throw;
    rollingBack_ = true;
    try {
      restore(before, "the state before loading");
    } catch (...) {
      rollingBack_ = false;
      throw;
    }
    rollingBack_ = false;
    throw;
  }
}

namespace {
bool syncToDisk(std::FILE* file) {
#if defined(__unix__) || defined(__APPLE__)
  return ::fsync(::fileno(file)) == 0;
#else
  (void)file;
  return true;
#endif
}
}  // namespace

template <class S>
void Simulation<S>::save(const std::string& path) const {
  const std::string bytes = checkpoint();
  const std::string temporary = path + ".tmp";
  std::FILE* file = std::fopen(temporary.c_str(), "wb");
  if (file == nullptr) fileError(path, "cannot write " + temporary + ": " + std::strerror(errno));
  // On the disk before the rename: otherwise a power loss can leave the new name on an empty
  // file and the previous checkpoint gone.
  const bool written =
      std::fwrite(bytes.data(), 1, bytes.size(), file) == bytes.size() && std::fflush(file) == 0 && syncToDisk(file);
  const int error = written ? 0 : errno;
  if (std::fclose(file) != 0 || !written) {
    std::remove(temporary.c_str());
    fileError(path, "cannot write " + temporary + ": " + std::strerror(error != 0 ? error : errno));
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    const int e = errno;
    std::remove(temporary.c_str());
    fileError(path, std::string("cannot rename the temporary file into place: ") + std::strerror(e));
  }
}

template <class S>
void Simulation<S>::load(const std::string& path) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) fileError(path, "is a directory, not a checkpoint file");
  std::ifstream in(path, std::ios::binary);
  if (!in) fileError(path, std::string("cannot open: ") + std::strerror(errno));
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) fileError(path, "cannot read");
  restore(bytes, path);
}

template std::string Simulation<float>::checkpoint() const;
template std::string Simulation<double>::checkpoint() const;
template void Simulation<float>::restore(std::string_view, const std::string&);
template void Simulation<double>::restore(std::string_view, const std::string&);
template void Simulation<float>::save(const std::string&) const;
template void Simulation<double>::save(const std::string&) const;
template void Simulation<float>::load(const std::string&);
template void Simulation<double>::load(const std::string&);

}  // namespace weft
