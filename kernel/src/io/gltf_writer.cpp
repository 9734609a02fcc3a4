#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "weft/io/gltf.hpp"

// tinygltf (Debian's libtinygltf-dev), compiled into weft::io here, in the only translation
// unit that includes it, without images (no stb) and under a namespace of weft's own: a
// program linking weft::io may use tinygltf itself (its own TINYGLTF_IMPLEMENTATION, or
// Debian's libtinygltf.so) without two definitions of one symbol. Users of weft::io need
// neither the header nor the library.
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#define tinygltf weft_tinygltf
#include <tiny_gltf.h>
#undef tinygltf

#ifndef WEFT_VERSION_STRING
#define WEFT_VERSION_STRING "unknown"
#endif

namespace weft {

static_assert(std::endian::native == std::endian::little, "the .glb binary chunk is written in host byte order");

namespace {

namespace gltf = weft_tinygltf;

/// Bytes of the JSON chunk allowed for per frame when checking the 4 GiB limit (measured:
/// about 330 per frame; this leaves room) and for the rest of the document.
constexpr std::uint64_t kJsonBytesPerFrame = 1024, kJsonBytesFixed = 64 * 1024;
constexpr std::size_t kCopyBytes = 1 << 20;

[[noreturn]] void throwIo(const std::string& what, const std::string& path, int error) {
  throw std::runtime_error(what + " '" + path + "': " + std::strerror(error));
}

std::uint64_t indexCount(const FrameTopology& topology) {
  return 3 * static_cast<std::uint64_t>(topology.triangles.size()) +
         2 * static_cast<std::uint64_t>(topology.lines.size());
}

std::string number(double value) {
  std::ostringstream out;
  out.precision(std::numeric_limits<double>::max_digits10);
  out << value;
  return out.str();
}

}  // namespace

std::uint64_t gltfBinaryBytes(Index particleCount, const FrameTopology& topology, std::int64_t frames) {
  const std::uint64_t n = particleCount > 0 ? static_cast<std::uint64_t>(particleCount) : 0;
  const std::uint64_t f = frames > 0 ? static_cast<std::uint64_t>(frames) : 0;
  return 4 * indexCount(topology) + 12 * n * f + (f > 1 ? 4 * f + 4 * f * (f - 1) : 0);
}

namespace {

/// An upper bound of the whole file's bytes for `frames` frames.
std::uint64_t fileBytesBound(Index particleCount, const FrameTopology& topology, std::int64_t frames) {
  return 28 + gltfBinaryBytes(particleCount, topology, frames) + kJsonBytesFixed +
         kJsonBytesPerFrame * static_cast<std::uint64_t>(std::max<std::int64_t>(frames, 0));
}

}  // namespace

std::int64_t gltfMaxFrames(Index particleCount, const FrameTopology& topology) {
  std::int64_t frames = kGltfMaxFrames;
  while (frames > 0 && fileBytesBound(particleCount, topology, frames) > kGltfMaxFileBytes) --frames;
  return frames;
}

template <class S>
struct GltfAnimationWriter<S>::Impl {
  std::string path, framesPath, tmpPath;
  GltfOptions options;
  Index particleCount = 0;
  FrameTopology topology;
  std::int64_t maxFrames = 0;                // gltfMaxFrames() of this model
  std::FILE* frames = nullptr;               // path + ".frames.tmp": indices, then each frame as appended
  std::vector<float> base;                   // (3 n) frame 0, x y z per particle, m
  std::vector<float> scratch;                // (3 n) one frame's deltas from frame 0, m
  std::vector<float> times;                  // key time of each frame, s
  std::vector<std::array<float, 6>> bounds;  // per frame: min x y z, max x y z of what was written, m
  bool ownsFiles = false;                    // the frame file was created: the destructor removes the temporary files
  bool closed = false;                       // close() was called (it is one attempt)
  bool committed = false;                    // the .glb is complete under path

  ~Impl() {
    if (frames) std::fclose(frames);
    if (ownsFiles) {
      std::remove(framesPath.c_str());
      if (!committed) std::remove(tmpPath.c_str());
    }
  }

  [[noreturn]] void fail(const std::string& what) const { throw std::invalid_argument("glTF '" + path + "': " + what); }

  void writeFrames(const void* data, std::size_t bytes) {
    if (bytes > 0 && std::fwrite(data, 1, bytes, frames) != bytes) throwIo("cannot write", framesPath, errno);
  }

  std::string json() const;
  void assemble(const std::string& document);
};

template <class S>
GltfAnimationWriter<S>::GltfAnimationWriter(std::string path, Index particleCount, FrameTopology topology,
                                            GltfOptions options)
    : impl_(std::make_unique<Impl>()) {
  Impl& w = *impl_;
  w.path = std::move(path);
  w.framesPath = w.path + ".frames.tmp";
  w.tmpPath = w.path + ".tmp";
  w.options = std::move(options);
  w.particleCount = particleCount;
  w.topology = std::move(topology);
  if (particleCount < 1)
    w.fail("particleCount = " + std::to_string(particleCount) + ": a glTF mesh needs at least one vertex");
  if (!w.topology.triangles.empty() && !w.topology.lines.empty())
    w.fail("the topology has " + std::to_string(w.topology.triangles.size()) + " triangles and " +
           std::to_string(w.topology.lines.size()) +
           " lines: the mesh is written as one primitive of one kind (give triangles or lines, not both)");
  const auto check = [&](const char* field, std::size_t item, int corner, Index value) {
    if (value < 0 || value >= particleCount)
      w.fail(std::string(field) + "[" + std::to_string(item) + "][" + std::to_string(corner) +
             "] = " + std::to_string(value) + " is not a particle index in [0, " + std::to_string(particleCount) + ")");
  };
  for (std::size_t t = 0; t < w.topology.triangles.size(); ++t)
    for (int k = 0; k < 3; ++k) check("triangles", t, k, w.topology.triangles[t][k]);
  for (std::size_t l = 0; l < w.topology.lines.size(); ++l)
    for (int k = 0; k < 2; ++k) check("lines", l, k, w.topology.lines[l][k]);
  w.maxFrames = gltfMaxFrames(particleCount, w.topology);
  if (w.maxFrames < 1)
    w.fail("one frame of " + std::to_string(particleCount) + " particles is about " +
           std::to_string(fileBytesBound(particleCount, w.topology, 1)) + " bytes, more than a .glb holds (4 GiB)");

  w.frames = std::fopen(w.framesPath.c_str(), "wb");
  if (!w.frames) throwIo("cannot open for writing", w.framesPath, errno);
  w.ownsFiles = true;
  w.base.resize(3 * static_cast<std::size_t>(particleCount));
  w.scratch.resize(w.base.size());
  std::vector<std::uint32_t> indices;
  indices.reserve(indexCount(w.topology));
  for (const auto& t : w.topology.triangles)
    for (const Index i : t) indices.push_back(static_cast<std::uint32_t>(i));
  for (const auto& l : w.topology.lines)
    for (const Index i : l) indices.push_back(static_cast<std::uint32_t>(i));
  w.writeFrames(indices.data(), indices.size() * sizeof(std::uint32_t));
}

template <class S>
GltfAnimationWriter<S>::~GltfAnimationWriter() = default;

template <class S>
const std::string& GltfAnimationWriter<S>::path() const {
  return impl_->path;
}
template <class S>
Index GltfAnimationWriter<S>::particleCount() const {
  return impl_->particleCount;
}
template <class S>
std::int64_t GltfAnimationWriter<S>::frameCount() const {
  return static_cast<std::int64_t>(impl_->times.size());
}

template <class S>
void GltfAnimationWriter<S>::append(const State<S>& state) {
  Impl& w = *impl_;
  if (w.closed) throw std::logic_error("glTF '" + w.path + "': append() after close()");
  const Index n = w.particleCount;
  if (state.x.rows() != n)
    w.fail("state.x has " + std::to_string(state.x.rows()) + " rows, the file holds " + std::to_string(n) +
           " particles");
  const std::int64_t frame = frameCount();
  if (frame + 1 > w.maxFrames)
    w.fail("frame " + std::to_string(frame) + " is one more than the " + std::to_string(w.maxFrames) +
           " frames this file holds (at most " + std::to_string(kGltfMaxFrames) +
           ", one morph target each, and 4 GiB in all): write fewer frames");
  const float time = static_cast<float>(state.time);
  if (!std::isfinite(time) || (frame > 0 && !(time > w.times.back())))
    w.fail("frame " + std::to_string(frame) + ": state.time = " + number(state.time) + " s (" + number(time) +
           " as float) is not a finite time later than the previous frame's " +
           (frame > 0 ? number(w.times.back()) : std::string("-")) + " s");
  for (int c = 0; c < 3; ++c)
    for (Index i = 0; i < n; ++i)
      if (!std::isfinite(static_cast<double>(state.x(i, c))))
        w.fail("frame " + std::to_string(frame) + ": state.x(" + std::to_string(i) + ", " + std::to_string(c) +
               ") = " + number(static_cast<double>(state.x(i, c))) + " is not finite");

  // Frame 0 as float; later frames as deltas from it, rounded once (the importer adds them
  // to the float frame 0, so x_0 + delta is within one rounding of x_k).
  std::vector<float>& out = frame == 0 ? w.base : w.scratch;
  std::array<float, 6> box;
  for (int c = 0; c < 3; ++c) {
    box[c] = std::numeric_limits<float>::infinity();
    box[3 + c] = -std::numeric_limits<float>::infinity();
  }
  for (Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      const std::size_t k = 3 * static_cast<std::size_t>(i) + c;
      const double x = static_cast<double>(state.x(i, c));
      const float v = frame == 0 ? static_cast<float>(x) : static_cast<float>(x - static_cast<double>(w.base[k]));
      if (!std::isfinite(v))
        w.fail("frame " + std::to_string(frame) + ": state.x(" + std::to_string(i) + ", " + std::to_string(c) +
               ") = " + number(x) + " does not fit a float");
      out[k] = v;
      box[c] = std::min(box[c], v);
      box[3 + c] = std::max(box[3 + c], v);
    }
  w.writeFrames(out.data(), out.size() * sizeof(float));
  w.times.push_back(time);
  w.bounds.push_back(box);
}

/// The JSON chunk: the document built with tinygltf (everything but the buffer), then the
/// one buffer, which is the .glb's binary chunk (no uri).
template <class S>
std::string GltfAnimationWriter<S>::Impl::json() const {
  const std::size_t keys = times.size(), n = static_cast<std::size_t>(particleCount);
  const std::size_t indexBytes = 4 * indexCount(topology), frameBytes = 12 * n;
  gltf::Model m;
  m.asset.version = "2.0";
  m.asset.generator = "weft " WEFT_VERSION_STRING;
  std::size_t offset = 0;
  const auto addView = [&](std::size_t length, int target) {
    gltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = offset;
    v.byteLength = length;
    v.target = target;
    offset += length;
    m.bufferViews.push_back(v);
    return static_cast<int>(m.bufferViews.size() - 1);
  };
  const auto addAccessor = [&](int view, int componentType, std::size_t count, int type, std::vector<double> min,
                               std::vector<double> max) {
    gltf::Accessor a;
    a.bufferView = view;
    a.byteOffset = 0;
    a.normalized = false;
    a.componentType = componentType;
    a.count = count;
    a.type = type;
    a.minValues = std::move(min);
    a.maxValues = std::move(max);
    a.sparse.isSparse = false;
    m.accessors.push_back(std::move(a));
    return static_cast<int>(m.accessors.size() - 1);
  };
  const auto boundsOf = [&](std::size_t frame, int first) {
    return std::vector<double>{bounds[frame][first], bounds[frame][first + 1], bounds[frame][first + 2]};
  };

  gltf::Primitive primitive;
  if (indexBytes > 0) {
    const int view = addView(indexBytes, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    primitive.indices =
        addAccessor(view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, indexBytes / 4, TINYGLTF_TYPE_SCALAR, {}, {});
  }
  primitive.mode = !topology.triangles.empty() ? TINYGLTF_MODE_TRIANGLES
                   : !topology.lines.empty()   ? TINYGLTF_MODE_LINE
                                               : TINYGLTF_MODE_POINTS;
  gltf::Mesh mesh;
  mesh.name = options.name;
  gltf::Value::Array targetNames;
  for (std::size_t k = 0; k < keys; ++k) {
    const int view = addView(frameBytes, TINYGLTF_TARGET_ARRAY_BUFFER);
    const int accessor =
        addAccessor(view, TINYGLTF_COMPONENT_TYPE_FLOAT, n, TINYGLTF_TYPE_VEC3, boundsOf(k, 0), boundsOf(k, 3));
    if (k == 0) {
      primitive.attributes["POSITION"] = accessor;
    } else {
      primitive.targets.push_back({{"POSITION", accessor}});
      mesh.weights.push_back(0.0);
      char name[32];
      std::snprintf(name, sizeof name, "frame_%06zu", k);
      targetNames.emplace_back(std::string(name));
    }
  }
  if (keys > 1) {
    gltf::Value::Object extras;
    extras["targetNames"] = gltf::Value(std::move(targetNames));
    mesh.extras = gltf::Value(std::move(extras));
  }
  mesh.primitives.push_back(std::move(primitive));
  m.meshes.push_back(std::move(mesh));

  gltf::Node node;
  node.name = options.name;
  node.mesh = 0;
  m.nodes.push_back(node);
  gltf::Scene scene;
  scene.name = options.name;
  scene.nodes.push_back(0);
  m.scenes.push_back(scene);
  m.defaultScene = 0;

  if (keys > 1) {  // one frame is a still mesh: no animation
    const int timesView = addView(4 * keys, 0);
    const int timesAccessor = addAccessor(timesView, TINYGLTF_COMPONENT_TYPE_FLOAT, keys, TINYGLTF_TYPE_SCALAR,
                                          {times.front()}, {times.back()});
    const std::size_t weights = keys * (keys - 1);
    const int weightsView = addView(4 * weights, 0);
    gltf::AnimationSampler sampler;
    sampler.input = timesAccessor;
    sampler.output = addAccessor(weightsView, TINYGLTF_COMPONENT_TYPE_FLOAT, weights, TINYGLTF_TYPE_SCALAR, {}, {});
    sampler.interpolation = "LINEAR";
    gltf::AnimationChannel channel;
    channel.sampler = 0;
    channel.target_node = 0;
    channel.target_path = "weights";
    gltf::Animation animation;
    animation.name = options.name;
    animation.samplers.push_back(sampler);
    animation.channels.push_back(channel);
    m.animations.push_back(std::move(animation));
  }

  std::ostringstream text;
  gltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&m, text, false, false))
    throw std::runtime_error("glTF '" + path + "': tinygltf could not serialise the document");
  // tinygltf writes no "buffers" for a model without buffer data: the one buffer is the
  // binary chunk, streamed from the frame file by assemble().
  nlohmann::json document = nlohmann::json::parse(text.str());
  document["buffers"] = nlohmann::json::array({{{"byteLength", offset}}});
  return document.dump();
}

/// Writes tmpPath: GLB header, JSON chunk, BIN chunk (the frame file), then renames it to
/// path. On failure the partial tmpPath is removed.
template <class S>
void GltfAnimationWriter<S>::Impl::assemble(const std::string& document) {
  struct File {
    std::FILE* f = nullptr;
    ~File() {
      if (f) std::fclose(f);
    }
  } in, out;
  in.f = std::fopen(framesPath.c_str(), "rb");
  if (!in.f) throwIo("cannot open", framesPath, errno);
  if (std::fseek(in.f, 0, SEEK_END) != 0) throwIo("cannot seek in", framesPath, errno);
  const long binBytes = std::ftell(in.f);
  std::rewind(in.f);
  const std::uint64_t jsonBytes = (document.size() + 3) / 4 * 4;
  const std::uint64_t total = 12 + 8 + jsonBytes + 8 + static_cast<std::uint64_t>(std::max(binBytes, 0L));
  if (binBytes < 0 || binBytes % 4 != 0)
    throw std::runtime_error("glTF '" + path + "': the frame file '" + framesPath + "' has " +
                             std::to_string(binBytes) + " bytes, not a multiple of 4");
  if (total > kGltfMaxFileBytes)
    fail(std::to_string(total) + " bytes, more than a .glb holds (4 GiB): write fewer frames");

  out.f = std::fopen(tmpPath.c_str(), "wb");
  if (!out.f) throwIo("cannot open for writing", tmpPath, errno);
  const auto write = [&](const void* data, std::size_t bytes) {
    if (bytes > 0 && std::fwrite(data, 1, bytes, out.f) != bytes) throwIo("cannot write", tmpPath, errno);
  };
  const std::uint32_t header[3] = {0x46546C67u /* "glTF" */, 2, static_cast<std::uint32_t>(total)};
  const std::uint32_t jsonChunk[2] = {static_cast<std::uint32_t>(jsonBytes), 0x4E4F534Au /* "JSON" */};
  const std::uint32_t binChunk[2] = {static_cast<std::uint32_t>(binBytes), 0x004E4942u /* "BIN\0" */};
  std::string padded = document;
  padded.resize(jsonBytes, ' ');  // the JSON chunk is padded with spaces to 4 bytes
  write(header, sizeof header);
  write(jsonChunk, sizeof jsonChunk);
  write(padded.data(), padded.size());
  write(binChunk, sizeof binChunk);
  std::vector<char> piece(kCopyBytes);
  for (long copied = 0; copied < binBytes;) {
    const std::size_t want = static_cast<std::size_t>(std::min<long>(binBytes - copied, kCopyBytes));
    if (std::fread(piece.data(), 1, want, in.f) != want) throwIo("cannot read", framesPath, errno ? errno : EIO);
    write(piece.data(), want);
    copied += static_cast<long>(want);
  }
  const bool bad = std::ferror(out.f) != 0;
  if (std::fclose(std::exchange(out.f, nullptr)) != 0 || bad) throwIo("cannot write", tmpPath, errno ? errno : EIO);
  if (std::rename(tmpPath.c_str(), path.c_str()) != 0) throwIo("cannot rename '" + tmpPath + "' to", path, errno);
}

template <class S>
void GltfAnimationWriter<S>::close() {
  Impl& w = *impl_;
  if (w.closed) throw std::logic_error("glTF '" + w.path + "': close() called twice");
  if (w.times.empty()) throw std::logic_error("glTF '" + w.path + "': close() before any frame was appended");
  w.closed = true;  // one attempt: after a failure the destructor removes what is left
  // The rest of the binary chunk (with two frames or more): key times, then the weights,
  // one row per key (at key k, 1 for target k - 1).
  const std::size_t keys = w.times.size();
  if (keys > 1) {
    w.writeFrames(w.times.data(), keys * sizeof(float));
    std::vector<float> row(keys - 1, 0.0f);
    for (std::size_t k = 0; k < keys; ++k) {
      if (k > 0) row[k - 1] = 1.0f;
      w.writeFrames(row.data(), row.size() * sizeof(float));
      if (k > 0) row[k - 1] = 0.0f;
    }
  }
  std::FILE* frames = std::exchange(w.frames, nullptr);
  const bool bad = std::ferror(frames) != 0;
  if (std::fclose(frames) != 0 || bad) throwIo("cannot write", w.framesPath, errno ? errno : EIO);
  w.assemble(w.json());
  w.committed = true;
}

template class GltfAnimationWriter<float>;
template class GltfAnimationWriter<double>;

}  // namespace weft
