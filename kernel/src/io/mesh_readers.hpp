// kernel/src/io/mesh_readers.hpp — weft's own readers for PLY and STL files (internal to weft::io).
//
// Design note
// -----------
// Assimp 5.2's PLY reader misbehaves on damaged files: fuzzing mesh import found it never
// returning, a segmentation fault, assertions that abort the program, a 7.6 GB allocation
// from a 324-byte file, and heap corruption. PLY and STL (the other simple format, read
// here with the same care) are simple enough to read exactly, so weft reads them itself: every count a header declares
// is checked against the bytes that follow before anything is allocated, every index
// against the vertices, every value is parsed with std::from_chars, and a damaged file is
// refused with the line or element where it went wrong. The readers hand their polygons to
// assimp as loaders of its own kind (mesh_import.cpp), so triangulation, the node transforms
// and everything after them stay one path for every format.
//
// The readers take the whole file as bytes and throw std::runtime_error with a message
// that does not name the file (the caller puts "mesh file '<path>': " in front).
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

namespace weft::io_detail {

/// A mesh as read from a file: positions, then polygons as corner counts and a flat list of
/// vertex indices (every index < vertex count; every polygon has at least one corner).
struct PolygonMesh {
  std::vector<float> xyz;                ///< 3 per vertex
  std::vector<std::uint32_t> faceSizes;  ///< corners per face
  std::vector<std::uint32_t> indices;    ///< sum of faceSizes entries
  std::size_t vertexCount() const { return xyz.size() / 3; }
};

/// The largest polygon the readers accept (its triangulation is quadratic in its corners).
inline constexpr std::uint32_t kMaxPolygonCorners = 4096;

/// Whether `head` (a file's first bytes) starts like a PLY file: "ply" in any case after
/// spaces or tabs, as assimp recognises one.
bool startsLikePly(std::string_view head);
/// The PLY file `bytes` (ASCII, binary little or big endian): one mesh, vertices in file
/// order, faces as listed (faces of no corners are dropped).
std::vector<PolygonMesh> readPly(std::string_view bytes);

/// Whether a file of `size` bytes starting with `head` (its first 84 bytes or more) is an
/// STL file: a binary one whose size is 84 + 50 n bytes for the n triangles its header
/// declares, or an ASCII one starting with "solid".
bool looksLikeStl(std::string_view head, std::uint64_t size);
/// The STL file `bytes`: one mesh per solid (binary: one), three vertices per facet, in order.
std::vector<PolygonMesh> readStl(std::string_view bytes);

}  // namespace weft::io_detail
