// weft/io/gltf.hpp — an animated run as one glTF 2.0 binary file (.glb), in weft::io.
//
// Design note
// -----------
// One self-contained .glb (glTF 2.0, binary container: a JSON chunk and one BIN chunk) that
// Blender's importer (File > Import > glTF 2.0) and other viewers play as an animation:
//
//   - one node, one mesh, one primitive: POSITION (float3) holds frame 0; the indices
//     (uint32) are the FrameTopology's triangles (mode TRIANGLES), or its lines (LINES, a
//     rope's structural springs), or none (POINTS, a model with neither);
//   - frame k >= 1 is morph target k - 1: a POSITION accessor of float3 deltas
//     x_k - x_0 (computed in double from the float frame 0, then rounded once to float);
//     every POSITION accessor has min/max, as the specification requires;
//   - one animation, channel `weights` of the node, sampler LINEAR, input the frame times
//     (State::time as float, s, strictly increasing), output one weight per target per key:
//     at key k the weight of target k - 1 is 1 and all others 0 (key 0: all 0). Between two
//     keys the mesh is the linear blend of the two frames; at a key it is the frame.
//   - the mesh's extras.targetNames name the targets "frame_000001", ... (Blender's shape
//     key names).
//
// Binary chunk layout (little-endian, every part 4-byte aligned):
//     indices (uint32, 3 per triangle or 2 per line) | frame 0 positions (12 n bytes) |
//     frame 1..F-1 deltas (12 n bytes each) | key times (4 F bytes) |
//     weights (4 F (F - 1) bytes, dense, one row of F - 1 per key)
// so its size is 4 I + 12 n F + 4 F + 4 F (F - 1): gltfBinaryBytes() computes it. A single
// frame is a still mesh: no targets, no key times, no animation.
//
// Memory and disk: append() streams each frame to `path + ".frames.tmp"`; the writer keeps
// frame 0 (12 n bytes), one frame of scratch and 28 bytes per frame (time, bounds), so RAM
// does not grow with the run. close() builds the JSON with tinygltf (about 0.5 KB per
// frame), then writes `path + ".tmp"` (GLB header, JSON chunk, BIN chunk copied from the
// frame file in 1 MiB pieces) and renames it to `path`; for that moment the disk holds the
// data twice. tinygltf's own GLB writer is not used for the binary chunk: it copies the
// whole buffer in memory and does not check its writes.
//
// Limits: at most kGltfMaxFrames frames (the weights grow as F^2 and each frame is a
// Blender shape key), and a .glb's total length must fit 32 bits (4 GiB). Errors throw:
// std::invalid_argument for bad arguments and limits, naming the field and the value;
// std::runtime_error for I/O, naming the path and strerror(errno). A writer destroyed
// before close() leaves no file (its temporary files are removed). Rigid bodies are not
// written.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "weft/core/state.hpp"
#include "weft/core/types.hpp"
#include "weft/io/frames.hpp"

namespace weft {

/// Frames one .glb holds at most (one morph target each; the weights grow as frames^2:
/// 4096 frames are 64 MiB of weights).
inline constexpr std::int64_t kGltfMaxFrames = 4096;
/// The largest .glb: its header stores the total length in 32 bits.
inline constexpr std::uint64_t kGltfMaxFileBytes = 0xFFFFFFFFull;

/// Bytes of the binary chunk for `frames` frames of `particleCount` particles joined by
/// `topology` (exact; the JSON chunk adds about 0.5 KB per frame).
std::uint64_t gltfBinaryBytes(Index particleCount, const FrameTopology& topology, std::int64_t frames);

/// The most frames one .glb holds for this model: kGltfMaxFrames, or fewer when the file
/// would pass 4 GiB (the JSON chunk counted at its upper bound of 1 KiB per frame); 0 when
/// not even one frame fits.
std::int64_t gltfMaxFrames(Index particleCount, const FrameTopology& topology);

struct GltfOptions {
  std::string name = "weft";  // the node's and the mesh's name (the object's name in Blender)
};

/// Appends frames (time and positions) and writes them as one animated .glb on close().
/// The file appears under `path` only after close(); destroying an unclosed writer removes
/// the temporary files.
template <class S>
class GltfAnimationWriter {
 public:
  /// Validates the topology against particleCount (>= 1; triangles or lines, not both) and creates the frame file
  /// `path + ".frames.tmp"` (an unwritable place fails here, before any frame).
  GltfAnimationWriter(std::string path, Index particleCount, FrameTopology topology, GltfOptions options = {});
  ~GltfAnimationWriter();
  GltfAnimationWriter(const GltfAnimationWriter&) = delete;
  GltfAnimationWriter& operator=(const GltfAnimationWriter&) = delete;

  /// Stores state.time and state.x (particleCount() rows, finite; the time, as float,
  /// later than the previous frame's).
  void append(const State<S>& state);
  /// Writes the .glb (at least one frame must have been appended) and renames it to path.
  void close();

  const std::string& path() const;
  Index particleCount() const;
  std::int64_t frameCount() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

extern template class GltfAnimationWriter<float>;
extern template class GltfAnimationWriter<double>;

}  // namespace weft
