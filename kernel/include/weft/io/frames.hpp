// weft/io/frames.hpp — simulation frames out: OBJ and PLY meshes, a binary frame cache.
//
// Design note
// -----------
// A frame is the particle positions of one State. What joins them is the FrameTopology,
// derived once from the Model: a cloth gives its triangles (Model::triangles(); a grid
// has two per cell, wound consistently: (a, b, e) and (a, e, d) for the cell a = (r, c),
// b = (r, c+1), d = (r+1, c), e = (r+1, c+1)); a model without triangles (a rope) gives
// its Structural springs as line segments.
//
// Every writer writes to `path + ".tmp"` and renames it to `path` only once the file is
// complete and closed, so a failure (disk full, a bad directory, an exception mid-way)
// never leaves a file that looks complete; the partial ".tmp" is removed. I/O errors
// throw std::runtime_error naming the path and strerror(errno); bad arguments (an index
// out of range, a state of the wrong size) throw std::invalid_argument.
//
// OBJ (ASCII): "v x y z" per particle with max_digits10 of S significant digits (parses
// back to the same S), then "f a b c" per triangle and "l a b" per line, 1-based.
//
// PLY (binary_little_endian 1.0): element vertex with properties x y z of type float or
// double according to S; element face (property list uchar int vertex_indices) when there
// are triangles; element edge (property int vertex1, property int vertex2) when there are
// lines. 0-based indices, as PLY has them.
//
// Frame cache (".wcache"), little-endian throughout (weft only builds on little-endian
// hosts; a static_assert enforces it):
//
//     offset  size  field
//     0       8     magic "WEFTCACH"
//     8       4     u32 version = 1
//     12      4     u32 scalar size in bytes: 4 (float) or 8 (double)
//     16      4     u32 particle count n (< 2^31)
//     20      4     u32 reserved, 0
//     24      8     u64 frame count F (written by close(); 0 while the file is open)
//     32            F frames of (8 + 3 n s) bytes each:
//                     f64 time, s
//                     n x-coordinates, then n y, then n z (the column-major State::x), each s bytes
//
// The file size is therefore exactly 32 + F (8 + 3 n s); the reader checks that, so a
// truncated cache is reported rather than read. FrameCacheWriter::append writes straight
// from State::x (no allocation, no conversion); the reader checks the scalar size against
// S, so a float cache read as double fails naming the file and the stored precision.
#pragma once

#include <array>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "weft/core/state.hpp"
#include "weft/core/types.hpp"
#include "weft/model/model.hpp"

namespace weft {

/// What joins the particles of a frame: triangles (grid models) or lines (others), with
/// 0-based particle indices.
struct FrameTopology {
  std::vector<std::array<Index, 3>> triangles;
  std::vector<std::array<Index, 2>> lines;
};

/// The model's triangles (cloth), and as lines the Structural springs that are no triangle's
/// edge (ropes, links from a rope to a cloth, stitches between cloths).
template <class S>
FrameTopology frameTopology(const Model<S>& model);

/// Writes the positions x (n x 3) and the topology as an ASCII OBJ file.
template <class S>
void writeObj(const std::string& path, const Vec3Array<S>& x, const FrameTopology& topology);

/// Writes the positions x (n x 3) and the topology as a binary little-endian PLY file.
template <class S>
void writePly(const std::string& path, const Vec3Array<S>& x, const FrameTopology& topology);

/// Appends frames (time and positions) to a frame cache. The file appears under `path`
/// only after close(); destroying an unclosed writer removes the partial ".tmp" file.
template <class S>
class FrameCacheWriter {
 public:
  /// Creates `path + ".tmp"` and writes the header. particleCount >= 0.
  FrameCacheWriter(std::string path, Index particleCount);
  ~FrameCacheWriter();
  FrameCacheWriter(const FrameCacheWriter&) = delete;
  FrameCacheWriter& operator=(const FrameCacheWriter&) = delete;

  /// Stores state.time and state.x (which must have particleCount() rows).
  void append(const State<S>& state);
  /// Writes the frame count into the header, closes the file and renames it to path.
  void close();

  const std::string& path() const { return path_; }
  Index particleCount() const { return particleCount_; }
  std::int64_t frameCount() const { return frameCount_; }

 private:
  std::string path_;
  std::string tmpPath_;
  std::FILE* file_ = nullptr;
  Index particleCount_ = 0;
  std::int64_t frameCount_ = 0;
};

/// Reads a frame cache written by FrameCacheWriter<S> (same S). The constructor validates
/// the whole header against the file size; read() is random access.
template <class S>
class FrameCacheReader {
 public:
  explicit FrameCacheReader(std::string path);
  ~FrameCacheReader();
  FrameCacheReader(const FrameCacheReader&) = delete;
  FrameCacheReader& operator=(const FrameCacheReader&) = delete;

  Index frameCount() const { return frameCount_; }
  Index particleCount() const { return particleCount_; }
  const std::string& path() const { return path_; }

  /// Fills out.x (resized to particleCount() x 3 if needed) and out.time with frame
  /// `frame` in [0, frameCount()); out.v is left as it is.
  void read(Index frame, State<S>& out);

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
  Index particleCount_ = 0;
  Index frameCount_ = 0;
};

extern template FrameTopology frameTopology(const Model<float>&);
extern template FrameTopology frameTopology(const Model<double>&);
extern template void writeObj(const std::string&, const Vec3Array<float>&, const FrameTopology&);
extern template void writeObj(const std::string&, const Vec3Array<double>&, const FrameTopology&);
extern template void writePly(const std::string&, const Vec3Array<float>&, const FrameTopology&);
extern template void writePly(const std::string&, const Vec3Array<double>&, const FrameTopology&);
extern template class FrameCacheWriter<float>;
extern template class FrameCacheWriter<double>;
extern template class FrameCacheReader<float>;
extern template class FrameCacheReader<double>;

}  // namespace weft
