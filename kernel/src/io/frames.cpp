#include "weft/io/frames.hpp"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <type_traits>
#include <utility>

#include "core/text.hpp"

namespace weft {

static_assert(std::endian::native == std::endian::little,
              "weft's PLY and frame-cache writers write host byte order, which must be little-endian");

namespace {

constexpr char kCacheMagic[8] = {'W', 'E', 'F', 'T', 'C', 'A', 'C', 'H'};
constexpr std::uint32_t kCacheVersion = 1;
constexpr long kCacheHeaderBytes = 32;
constexpr long kCacheFrameCountOffset = 24;

[[noreturn]] void throwIo(const std::string& what, const std::string& path, int error) {
  throw std::runtime_error(what + " '" + path + "': " + std::strerror(error));
}

const char* precisionName(std::uint32_t scalarBytes) {
  return scalarBytes == 4 ? "float" : scalarBytes == 8 ? "double" : "unknown";
}

/// A file written as `path + ".tmp"` and renamed to `path` by commit(); removed again if
/// it is destroyed before that.
class AtomicFile {
 public:
  explicit AtomicFile(std::string path) : path_(std::move(path)), tmp_(path_ + ".tmp") {
    file_ = std::fopen(tmp_.c_str(), "wb");
    if (!file_) throwIo("cannot open for writing", tmp_, errno);
  }
  ~AtomicFile() { discard(); }
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::FILE* get() const { return file_; }
  const std::string& path() const { return path_; }
  const std::string& tmpPath() const { return tmp_; }

  void write(const void* data, std::size_t bytes) {
    if (bytes > 0 && std::fwrite(data, 1, bytes, file_) != bytes) throwIo("cannot write", tmp_, errno);
  }
  /// Throws if any earlier buffered write failed.
  void check() {
    if (std::ferror(file_)) throwIo("cannot write", tmp_, errno ? errno : EIO);
  }
  /// Flushes, closes and renames; the file is then complete under path().
  void commit() {
    check();
    std::FILE* f = std::exchange(file_, nullptr);
    if (std::fclose(f) != 0) {
      const int error = errno;
      std::remove(tmp_.c_str());
      throwIo("cannot write", tmp_, error);
    }
    if (std::rename(tmp_.c_str(), path_.c_str()) != 0) {
      const int error = errno;
      std::remove(tmp_.c_str());
      throwIo("cannot rename '" + tmp_ + "' to", path_, error);
    }
  }
  void discard() {
    if (file_) {
      std::fclose(std::exchange(file_, nullptr));
      std::remove(tmp_.c_str());
    }
  }

 private:
  std::string path_;
  std::string tmp_;
  std::FILE* file_ = nullptr;
};

/// Every index of the topology must name a row of x.
template <class S>
void validateTopology(const std::string& path, const Vec3Array<S>& x, const FrameTopology& topology) {
  const Index n = static_cast<Index>(x.rows());
  const auto check = [&](const char* field, std::size_t item, int corner, Index value) {
    if (value < 0 || value >= n) {
      std::ostringstream msg;
      msg << "writing '" << path << "': " << field << "[" << item << "][" << corner << "] = " << value
          << " is not a particle index in [0, " << n << ")";
      throw std::invalid_argument(msg.str());
    }
  };
  for (std::size_t t = 0; t < topology.triangles.size(); ++t)
    for (int k = 0; k < 3; ++k) check("triangles", t, k, topology.triangles[t][k]);
  for (std::size_t l = 0; l < topology.lines.size(); ++l)
    for (int k = 0; k < 2; ++k) check("lines", l, k, topology.lines[l][k]);
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Topology
// ---------------------------------------------------------------------------------------

template <class S>
FrameTopology frameTopology(const Model<S>& model) {
  FrameTopology topology;
  const Triangles& tr = model.triangles();
  const auto key = [](Index a, Index b) {
    return static_cast<std::uint64_t>(std::min(a, b)) << 32 | static_cast<std::uint64_t>(std::max(a, b));
  };
  std::vector<std::uint64_t> edges;  // the triangles' edges, sorted
  topology.triangles.reserve(static_cast<std::size_t>(tr.count()));
  edges.reserve(3 * static_cast<std::size_t>(tr.count()));
  for (Index t = 0; t < tr.count(); ++t) {
    topology.triangles.push_back({tr.a[t], tr.b[t], tr.c[t]});
    edges.insert(edges.end(), {key(tr.a[t], tr.b[t]), key(tr.b[t], tr.c[t]), key(tr.c[t], tr.a[t])});
  }
  std::sort(edges.begin(), edges.end());
  // Ropes, links from a rope to a cloth and stitches between cloths: the structural springs
  // that are no triangle's edge.
  const Springs<S>& springs = model.springs();
  for (Index s = 0; s < springs.count(); ++s)
    if (springs.kind[s] == SpringClass::Structural &&
        !std::binary_search(edges.begin(), edges.end(), key(springs.a[s], springs.b[s])))
      topology.lines.push_back({springs.a[s], springs.b[s]});
  return topology;
}

// ---------------------------------------------------------------------------------------
// OBJ and PLY
// ---------------------------------------------------------------------------------------

template <class S>
void writeObj(const std::string& path, const Vec3Array<S>& x, const FrameTopology& topology) {
  validateTopology(path, x, topology);
  AtomicFile file(path);
  std::FILE* f = file.get();
  constexpr int digits = std::numeric_limits<S>::max_digits10;
  std::fprintf(f, "# weft frame: %lld vertices, %zu triangles, %zu lines\n", static_cast<long long>(x.rows()),
               topology.triangles.size(), topology.lines.size());
  for (Index i = 0; i < x.rows(); ++i)
    std::fprintf(f, "v %.*g %.*g %.*g\n", digits, static_cast<double>(x(i, 0)), digits, static_cast<double>(x(i, 1)),
                 digits, static_cast<double>(x(i, 2)));
  for (const auto& t : topology.triangles) std::fprintf(f, "f %d %d %d\n", t[0] + 1, t[1] + 1, t[2] + 1);
  for (const auto& l : topology.lines) std::fprintf(f, "l %d %d\n", l[0] + 1, l[1] + 1);
  file.commit();
}

template <class S>
void writePly(const std::string& path, const Vec3Array<S>& x, const FrameTopology& topology) {
  validateTopology(path, x, topology);
  AtomicFile file(path);
  std::FILE* f = file.get();
  const char* type = std::is_same_v<S, float> ? "float" : "double";
  std::fprintf(f, "ply\nformat binary_little_endian 1.0\ncomment weft frame\n");
  std::fprintf(f, "element vertex %lld\nproperty %s x\nproperty %s y\nproperty %s z\n",
               static_cast<long long>(x.rows()), type, type, type);
  if (!topology.triangles.empty())
    std::fprintf(f, "element face %zu\nproperty list uchar int vertex_indices\n", topology.triangles.size());
  if (!topology.lines.empty())
    std::fprintf(f, "element edge %zu\nproperty int vertex1\nproperty int vertex2\n", topology.lines.size());
  std::fprintf(f, "end_header\n");
  for (Index i = 0; i < x.rows(); ++i) {
    const S p[3] = {x(i, 0), x(i, 1), x(i, 2)};
    file.write(p, sizeof p);
  }
  for (const auto& t : topology.triangles) {
    const unsigned char three = 3;
    const std::int32_t v[3] = {t[0], t[1], t[2]};
    file.write(&three, 1);
    file.write(v, sizeof v);
  }
  for (const auto& l : topology.lines) {
    const std::int32_t v[2] = {l[0], l[1]};
    file.write(v, sizeof v);
  }
  file.commit();
}

// ---------------------------------------------------------------------------------------
// Frame cache
// ---------------------------------------------------------------------------------------

template <class S>
FrameCacheWriter<S>::FrameCacheWriter(std::string path, Index particleCount)
    : path_(std::move(path)), tmpPath_(path_ + ".tmp"), particleCount_(particleCount) {
  if (particleCount < 0) {
    std::ostringstream msg;
    msg << "frame cache '" << path_ << "': particleCount = " << particleCount << " is negative";
    throw std::invalid_argument(msg.str());
  }
  file_ = std::fopen(tmpPath_.c_str(), "wb");
  if (!file_) throwIo("cannot open for writing", tmpPath_, errno);
  unsigned char header[kCacheHeaderBytes] = {};
  const std::uint32_t fields[4] = {kCacheVersion, static_cast<std::uint32_t>(sizeof(S)),
                                   static_cast<std::uint32_t>(particleCount), 0};
  const std::uint64_t frames = 0;
  std::memcpy(header, kCacheMagic, sizeof kCacheMagic);
  std::memcpy(header + 8, fields, sizeof fields);
  std::memcpy(header + kCacheFrameCountOffset, &frames, sizeof frames);
  if (std::fwrite(header, 1, sizeof header, file_) != sizeof header) {
    const int error = errno;
    std::fclose(std::exchange(file_, nullptr));
    std::remove(tmpPath_.c_str());
    throwIo("cannot write", tmpPath_, error);
  }
}

template <class S>
FrameCacheWriter<S>::~FrameCacheWriter() {
  if (file_) {
    std::fclose(std::exchange(file_, nullptr));
    std::remove(tmpPath_.c_str());
  }
}

template <class S>
void FrameCacheWriter<S>::append(const State<S>& state) {
  if (!file_) throw std::logic_error("frame cache '" + path_ + "': append() after close()");
  if (state.x.rows() != particleCount_) {
    std::ostringstream msg;
    msg << "frame cache '" << path_ << "': state.x has " << state.x.rows() << " rows, the cache holds "
        << particleCount_ << " particles";
    throw std::invalid_argument(msg.str());
  }
  const double time = state.time;
  const std::size_t coordinates = 3 * static_cast<std::size_t>(particleCount_);
  if (std::fwrite(&time, sizeof time, 1, file_) != 1 ||
      (coordinates > 0 && std::fwrite(state.x.data(), sizeof(S), coordinates, file_) != coordinates))
    throwIo("cannot write", tmpPath_, errno);
  ++frameCount_;
}

template <class S>
void FrameCacheWriter<S>::close() {
  if (!file_) throw std::logic_error("frame cache '" + path_ + "': close() called twice");
  const std::uint64_t frames = static_cast<std::uint64_t>(frameCount_);
  int error = 0;
  if (std::fseek(file_, kCacheFrameCountOffset, SEEK_SET) != 0 || std::fwrite(&frames, sizeof frames, 1, file_) != 1 ||
      std::ferror(file_))
    error = errno ? errno : EIO;
  if (std::fclose(std::exchange(file_, nullptr)) != 0 && error == 0) error = errno;
  if (error != 0) {
    std::remove(tmpPath_.c_str());
    throwIo("cannot write", tmpPath_, error);
  }
  if (std::rename(tmpPath_.c_str(), path_.c_str()) != 0) {
    error = errno;
    std::remove(tmpPath_.c_str());
    throwIo("cannot rename '" + tmpPath_ + "' to", path_, error);
  }
}

template <class S>
FrameCacheReader<S>::FrameCacheReader(std::string path) : path_(std::move(path)) {
  file_ = std::fopen(path_.c_str(), "rb");
  if (!file_) throwIo("cannot open frame cache", path_, errno);
  const auto fail = [&](const std::string& what) {
    std::fclose(std::exchange(file_, nullptr));
    throw std::runtime_error("frame cache '" + path_ + "': " + what);
  };
  if (std::fseek(file_, 0, SEEK_END) != 0) {
    const int error = errno;
    std::fclose(std::exchange(file_, nullptr));
    throwIo("cannot seek in frame cache", path_, error);
  }
  const long size = std::ftell(file_);
  std::rewind(file_);
  unsigned char header[kCacheHeaderBytes] = {};
  if (size < kCacheHeaderBytes || std::fread(header, 1, sizeof header, file_) != sizeof header)
    fail("truncated: " + std::to_string(size) + " bytes, shorter than the " + std::to_string(kCacheHeaderBytes) +
         "-byte header");
  if (std::memcmp(header, kCacheMagic, sizeof kCacheMagic) != 0) {
    const std::string magic = detail::escaped(std::string_view(reinterpret_cast<const char*>(header), 8));
    fail("bad magic \"" + magic + "\", expected \"WEFTCACH\": not a weft frame cache");
  }
  std::uint32_t fields[4];
  std::uint64_t frames = 0;
  std::memcpy(fields, header + 8, sizeof fields);
  std::memcpy(&frames, header + kCacheFrameCountOffset, sizeof frames);
  const std::uint32_t version = fields[0], scalarBytes = fields[1], particles = fields[2];
  if (version != kCacheVersion)
    fail("version = " + std::to_string(version) + ", this weft reads version " + std::to_string(kCacheVersion));
  if (scalarBytes != 4 && scalarBytes != 8)
    fail("scalar size = " + std::to_string(scalarBytes) + " bytes, expected 4 (float) or 8 (double)");
  if (scalarBytes != sizeof(S))
    fail(std::string("stores ") + precisionName(scalarBytes) + " positions (scalar size " +
         std::to_string(scalarBytes) + "), read as " + precisionName(sizeof(S)));
  if (particles > static_cast<std::uint32_t>(std::numeric_limits<Index>::max()))
    fail("particle count = " + std::to_string(particles) + " exceeds 2^31 - 1");
  const std::uint64_t frameBytes = 8 + 3 * static_cast<std::uint64_t>(particles) * scalarBytes;
  const std::uint64_t body = static_cast<std::uint64_t>(size) - kCacheHeaderBytes;
  if (frames > static_cast<std::uint64_t>(std::numeric_limits<Index>::max()) || frames > body / frameBytes ||
      body != frames * frameBytes) {
    // Expected size without overflow: frames is bounded by the file size unless the header is corrupt.
    std::ostringstream msg;
    msg << "size mismatch: header says " << frames << " frames of " << particles << " particles ("
        << precisionName(scalarBytes) << "), expected ";
    if (frames <= (std::numeric_limits<std::uint64_t>::max() - kCacheHeaderBytes) / frameBytes)
      msg << kCacheHeaderBytes + frames * frameBytes << " bytes";
    else
      msg << "more than 2^64 bytes";
    // frames > body / frameBytes, not body < frames * frameBytes: that product may wrap.
    msg << ", the file has " << size << " bytes" << (frames > body / frameBytes ? " (truncated)" : "");
    fail(msg.str());
  }
  particleCount_ = static_cast<Index>(particles);
  frameCount_ = static_cast<Index>(frames);
}

template <class S>
FrameCacheReader<S>::~FrameCacheReader() {
  if (file_) std::fclose(file_);
}

template <class S>
void FrameCacheReader<S>::read(Index frame, State<S>& out) {
  if (frame < 0 || frame >= frameCount_) {
    std::ostringstream msg;
    msg << "frame cache '" << path_ << "': frame = " << frame << " is not in [0, " << frameCount_ << ")";
    throw std::out_of_range(msg.str());
  }
  const std::size_t coordinates = 3 * static_cast<std::size_t>(particleCount_);
  const long offset = kCacheHeaderBytes + static_cast<long>(frame) * static_cast<long>(8 + coordinates * sizeof(S));
  if (out.x.rows() != particleCount_) out.x.resize(particleCount_, 3);
  double time = 0;
  if (std::fseek(file_, offset, SEEK_SET) != 0 || std::fread(&time, sizeof time, 1, file_) != 1 ||
      (coordinates > 0 && std::fread(out.x.data(), sizeof(S), coordinates, file_) != coordinates))
    throwIo("cannot read frame " + std::to_string(frame) + " of frame cache", path_, std::ferror(file_) ? errno : EIO);
  out.time = time;
}

template FrameTopology frameTopology(const Model<float>&);
template FrameTopology frameTopology(const Model<double>&);
template void writeObj(const std::string&, const Vec3Array<float>&, const FrameTopology&);
template void writeObj(const std::string&, const Vec3Array<double>&, const FrameTopology&);
template void writePly(const std::string&, const Vec3Array<float>&, const FrameTopology&);
template void writePly(const std::string&, const Vec3Array<double>&, const FrameTopology&);
template class FrameCacheWriter<float>;
template class FrameCacheWriter<double>;
template class FrameCacheReader<float>;
template class FrameCacheReader<double>;

}  // namespace weft
