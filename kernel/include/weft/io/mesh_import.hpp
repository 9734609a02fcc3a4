// weft/io/mesh_import.hpp — triangle meshes from files, through assimp (library weft::io).
//
// Design note
// -----------
// loadMesh reads any format assimp reads (3DS — the original design's format — glTF,
// Collada, FBX, ...) into one TriangleMesh. PLY (ASCII and binary, both byte orders), STL
// (ASCII and binary) and OBJ are read by weft's own readers (assimp 5.2's PLY reader hangs,
// crashes or allocates gigabytes on damaged files; its OBJ reader gives every face corner a
// vertex of its own and rounds coordinates to float): they check every count a file declares
// against the bytes that follow before allocating, name the header line, element, facet or
// line where a damaged file goes wrong, and keep the file's vertices in its order and in
// double (a PLY `property double` or an OBJ coordinate arrives as written). A file whose
// extension assimp does not know (or that has none) goes to them when its first bytes say
// PLY or STL. Other formats go through assimp, which bakes the node transforms into the
// vertices and flattens the hierarchy (aiProcess_PreTransformVertices, so instanced meshes
// appear once per instance), in single precision (assimp's ai_real; one beyond its range
// arrives as an infinity, which cleanMesh refuses). For every format weft triangulates
// polygons itself, by ear clipping in each polygon's plane (assimp 5.2 folds concave ones),
// concatenates every mesh and keeps the triangles; points and lines are not cloth, and
// loadCleanMesh's report counts them (MeshReport::ignoredPoints, ignoredLines). assimp is
// not asked to join identical vertices: welding is cleanMesh's job, so that it can be
// counted and reported. Every face corner of a 3DS or STL file gets its own vertex (STL
// shares none), so the weld count of such a file includes those copies, not only the
// file's own duplicates.
//
// Orientation is assimp's, which is weft's (y up, gravity along -y): files in a z-up
// format are turned by their reader, e.g. the 3DS reader maps a file's (x, y, z) to
// (x, z, -y); PLY, STL and OBJ arrive as written. Units are the file's, read as metres
// (ClothMeshSpec::scale converts).
//
// Errors are std::runtime_error messages that start with "mesh file '<path>': ": the file
// is missing or cannot be opened (with strerror), is a directory, is empty, cannot be read
// (assimp's error string, or for PLY, STL and OBJ the reader's own message: "PLY header
// line 3: ...", "PLY face 7 corner 2: vertex index must be ...", "ASCII STL line 12:
// expected 'endloop', got ...", "OBJ line 4: a face names vertex 9, ..."), or has no triangles (with the numbers of
// points and lines it has instead). loadCleanMesh reports what cleanMesh finds wrong with the file's contents (a
// coordinate that is not finite, no triangle left) the same way: std::runtime_error, the
// file name in front of cleanMesh's message. A bad MeshCleanOptions is the caller's error:
// std::invalid_argument, before the file is read.
//
// weft::io is a separate library so that the kernel needs only Eigen and TBB.
#pragma once

#include <string>

#include "weft/model/triangle_mesh.hpp"

namespace weft {

/// The triangles of every mesh in the file at `path`, vertices as its reader delivers them.
TriangleMesh loadMesh(const std::string& path);

/// loadMesh, then cleanMesh with `options` (filling *report if it is not null).
TriangleMesh loadCleanMesh(const std::string& path, const MeshCleanOptions& options = {}, MeshReport* report = nullptr);

/// loadMesh for a file's contents held in memory (a mesh embedded in a program, one
/// received over a network): `name` stands for the path in messages, and its extension
/// tells the format ("torus.obj"; PLY and STL contents are also known by their first
/// bytes). Same errors as loadMesh (an empty `contents` is "the file is empty").
TriangleMesh loadMeshFromMemory(const std::string& contents, const std::string& name);
/// loadMeshFromMemory, then cleanMesh.
TriangleMesh loadCleanMeshFromMemory(const std::string& contents, const std::string& name,
                                     const MeshCleanOptions& options = {}, MeshReport* report = nullptr);

}  // namespace weft
