// kernel/src/io/mesh_readers.hpp — weft's own readers for PLY, STL and OBJ files, and the
// triangulation of polygons (internal to weft::io).
//
// Design note
// -----------
// Assimp 5.2's PLY reader misbehaves on damaged files: fuzzing mesh import found it never
// returning, a segmentation fault, assertions that abort the program, a 7.6 GB allocation
// from a 324-byte file, and heap corruption. PLY and STL (the other simple format, read
// here with the same care) are simple enough to read exactly, so weft reads them itself: every count a header declares
// is checked against the bytes that follow before anything is allocated, every index
// against the vertices, every value is parsed with std::from_chars, and a damaged file is
// refused with the line or element where it went wrong. OBJ is read here too: through
// assimp every face corner became a vertex of its own (so the file's vertex order was lost)
// and every coordinate passed through float. These readers keep the file's vertices in
// order and in double, and mesh_import.cpp triangulates their polygons itself
// (triangulatePolygon): assimp 5.2's triangulation folds concave polygons.
//
// The readers take the whole file as bytes and throw std::runtime_error with a message
// that does not name the file (the caller puts "mesh file '<path>': " in front).
#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

namespace weft::io_detail {

/// A mesh as read from a file: positions, then polygons as corner counts and a flat list of
/// vertex indices (every index < vertex count; every polygon has at least one corner).
struct PolygonMesh {
  std::vector<double> xyz;               ///< 3 per vertex, as the file holds them
  std::vector<std::uint32_t> faceSizes;  ///< corners per face (1: a point, 2: a line)
  std::vector<std::uint32_t> indices;    ///< sum of faceSizes entries
  std::uint64_t emptyFaces = 0;          ///< faces of no corners the file lists (not in faceSizes)
  std::uint64_t points = 0, lines = 0;   ///< OBJ's point and line statements (not in faceSizes)
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

/// The OBJ file `bytes`: one mesh, its `v` vertices in file order (x y z, with an optional w
/// that must be 1, or with r g b colours), its `f` faces (indices i, i/t, i//n or i/t/n,
/// negative ones counted back from the last vertex read); `p` and `l` statements are
/// counted, texture coordinates, normals, groups and materials ignored.
std::vector<PolygonMesh> readObj(std::string_view bytes);
/// The format of weft's own readers that a file named `name` has by its extension ("ply",
/// "stl" or "obj", in any case), or null (assimp's formats, or no extension).
const char* ownFormatByName(std::string_view name);
/// Whether `head` (a file's first bytes) starts like an OBJ file: its first statement that is
/// not a comment is an OBJ keyword (v, vt, vn, f, o, g, mtllib, ...).
bool looksLikeObj(std::string_view head);

/// Appends the triangles of polygon `corners[0..count)` (indices into `xyz`, 3 doubles a
/// vertex) to `out`, in the polygon's winding: ear clipping in the plane of its Newell
/// normal, so a concave polygon is cut inside its outline. A polygon with no area, or one
/// that crosses itself, is still cut into count - 2 triangles (mesh cleaning then drops
/// those with no area).
void triangulatePolygon(const std::vector<double>& xyz, const std::uint32_t* corners, std::uint32_t count,
                        std::vector<std::array<std::uint32_t, 3>>& out);

/// Whether a file of `size` bytes starting with `head` (its first 84 bytes or more) is an
/// STL file: a binary one whose size is 84 + 50 n bytes for the n triangles its header
/// declares, or an ASCII one starting with "solid".
bool looksLikeStl(std::string_view head, std::uint64_t size);
/// The STL file `bytes`: one mesh per solid (binary: one), three vertices per facet, in order.
std::vector<PolygonMesh> readStl(std::string_view bytes);

}  // namespace weft::io_detail
