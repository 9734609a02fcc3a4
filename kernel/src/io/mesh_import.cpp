#include "weft/io/mesh_import.hpp"

#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <assimp/Importer.hpp>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "io_text.hpp"

namespace weft {

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error("mesh file '" + path + "': " + what);
}

std::string counted(size_t n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

/// Reports a missing, unopenable, unreadable or empty file, or a directory, before assimp
/// sees it (assimp's own messages for these are "Unable to open file" and "No suitable
/// reader found", which say less).
void checkReadable(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) fail(path, "is a directory, not a mesh file");
  errno = 0;
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) fail(path, std::string("cannot open: ") + std::strerror(errno));
  errno = 0;
  const int c = std::fgetc(file);
  const int error = std::ferror(file) ? errno : 0;
  std::fclose(file);
  if (error != 0) fail(path, std::string("cannot read: ") + std::strerror(error));
  if (c == EOF) fail(path, "no triangles: the file is empty (0 bytes)");
}

/// Whether `line` starts, after spaces and tabs, with the token `token` (followed by the
/// line's end or white space), as assimp's PLY reader matches header keywords.
bool startsWithToken(std::string_view line, std::string_view token) {
  const size_t start = line.find_first_not_of(" \t");
  if (start == std::string_view::npos || line.compare(start, token.size(), token) != 0) return false;
  const size_t end = start + token.size();
  return end == line.size() || line[end] == ' ' || line[end] == '\t';
}

/// Whether `line` starts, after spaces and tabs, with "ply" in any case followed by
/// anything: all assimp's PLY reader asks of a file's first bytes ("ply\xfd" is PLY to it).
bool startsLikePly(std::string_view line) {
  const size_t start = line.find_first_not_of(" \t");
  if (start == std::string_view::npos || line.size() - start < 3) return false;
  const auto lower = [](char c) { return c >= 'A' && c <= 'Z' ? static_cast<char>(c - 'A' + 'a') : c; };
  return lower(line[start]) == 'p' && lower(line[start + 1]) == 'l' && lower(line[start + 2]) == 'y';
}

/// Refuses a PLY file (its first line starting with "ply" in any case, which is what
/// assimp's PLY reader requires) whose header has no "end_header" line: assimp 5.2's PLY
/// reader never returns on such a header (an 89-byte file of a header's first six lines ran
/// for as long as it was let; then "ply\xfd" as a first line; both found by
/// tests/fuzz/fuzz_mesh.cpp).
/// `nextLine(line)` yields the file's lines, split at '\n', and returns false at the end;
/// '\r' and NUL also end a line for assimp, so they split a line here too.
/// A header that does end must be text up to its end_header line (printable ASCII, tabs,
/// line ends): assimp 5.2's PLY reader crashes on some headers with binary bytes in them
/// (a segmentation fault inside libassimp, found by fuzz_mesh), and a real header is text.
template <class NextLine>
void checkPlyHeader(const std::string& path, NextLine nextLine) {
  std::string_view text;
  bool first = true;
  std::int64_t lineNumber = 0, badLine = 0;
  int badByte = -1;
  while (nextLine(text)) {
    ++lineNumber;
    for (;;) {
      const size_t end = text.find_first_of(std::string_view("\r\0", 2));
      const std::string_view line = text.substr(0, end);
      if (first) {
        if (!startsLikePly(line)) return;  // not PLY: assimp decides
        first = false;
      } else if (startsWithToken(line, "end_header")) {
        if (badByte >= 0) {
          char hex[12];  // "0x" and up to 8 hex digits of an int, as far as the compiler can tell
          std::snprintf(hex, sizeof hex, "0x%02x", badByte);
          fail(path, std::string("PLY header has a byte that is not text (") + hex + " in line " +
                         std::to_string(badLine) + "): the file is damaged or not a PLY file");
        }
        return;
      }
      // Not the end: remember the first byte that is not text (a NUL ending it counts).
      const std::string_view scanned = end == std::string_view::npos ? line : text.substr(0, end + 1);
      for (size_t k = 0; k < scanned.size() && badByte < 0; ++k) {
        const unsigned char u = static_cast<unsigned char>(scanned[k]);
        if ((u < 32 && u != '\t' && u != '\r') || u >= 127) {
          badByte = u;
          badLine = lineNumber;
        }
      }
      if (end == std::string_view::npos) break;
      text.remove_prefix(end + 1);
    }
  }
  if (!first) fail(path, "PLY header has no end_header line (the file is truncated or not a PLY file)");
}

void checkPlyHeaderInMemory(const std::string& contents, const std::string& name) {
  std::string_view rest(contents);
  bool done = false;
  checkPlyHeader(name, [&](std::string_view& line) {
    if (done) return false;
    const size_t end = rest.find('\n');
    line = rest.substr(0, end);
    if (end == std::string_view::npos)
      done = true;
    else
      rest.remove_prefix(end + 1);
    return true;
  });
}

void checkPlyHeaderInFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string buffer;
  checkPlyHeader(path, [&](std::string_view& line) {
    if (!std::getline(in, buffer)) return false;
    line = buffer;
    return true;
  });
}

// No aiProcess_JoinIdenticalVertices: cleanMesh welds, and reports how many it welded.
constexpr unsigned kImportFlags = aiProcess_Triangulate | aiProcess_PreTransformVertices;

/// Every triangle of an imported scene; `path` names the source in messages.
TriangleMesh collectTriangles(const aiScene* scene, const std::string& path) {
  constexpr size_t kMaxIndex = static_cast<size_t>(std::numeric_limits<Index>::max());
  TriangleMesh mesh;
  size_t points = 0, lines = 0, polygons = 0;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* in = scene->mMeshes[m];
    const size_t base = mesh.vertices.size();
    if (in->mNumVertices > kMaxIndex - base)
      fail(path, "more than " + std::to_string(kMaxIndex) + " vertices (mesh " + std::to_string(m) + " has " +
                     std::to_string(in->mNumVertices) + ")");
    if (in->mNumVertices > 0 && in->mVertices == nullptr)
      fail(path,
           "mesh " + std::to_string(m) + " has " + std::to_string(in->mNumVertices) + " vertices but no positions");
    for (unsigned v = 0; v < in->mNumVertices; ++v)
      mesh.vertices.push_back({static_cast<double>(in->mVertices[v].x), static_cast<double>(in->mVertices[v].y),
                               static_cast<double>(in->mVertices[v].z)});
    for (unsigned f = 0; f < in->mNumFaces; ++f) {
      const aiFace& face = in->mFaces[f];
      if (face.mNumIndices == 1) ++points;
      if (face.mNumIndices == 2) ++lines;
      if (face.mNumIndices > 3) ++polygons;  // not after aiProcess_Triangulate; counted for the message
      if (face.mNumIndices != 3) continue;
      if (mesh.triangles.size() >= kMaxIndex) fail(path, "more than " + std::to_string(kMaxIndex) + " triangles");
      std::array<Index, 3> tri;
      for (int k = 0; k < 3; ++k) {
        const unsigned index = face.mIndices[k];
        if (index >= in->mNumVertices)
          fail(path, "mesh " + std::to_string(m) + " face " + std::to_string(f) + " corner " + std::to_string(k) +
                         ": vertex index must be < " + std::to_string(in->mNumVertices) + ", got " +
                         std::to_string(index));
        tri[k] = static_cast<Index>(base + index);
      }
      mesh.triangles.push_back(tri);
    }
  }
  if (mesh.triangles.empty()) {
    std::string found = counted(scene->mNumMeshes, "mesh", "meshes") + " with " + counted(points, "point", "points") +
                        ", " + counted(lines, "line", "lines");
    if (polygons > 0) found += ", " + counted(polygons, "polygon", "polygons");
    fail(path, "no triangles: assimp read " + found + " and " + counted(mesh.vertices.size(), "vertex", "vertices"));
  }
  return mesh;
}

void configure(Assimp::Importer& importer) {
  // A file with bones but no meshes must not turn into assimp's generated bone geometry.
  importer.SetPropertyBool(AI_CONFIG_IMPORT_NO_SKELETON_MESHES, true);
}

/// What assimp's post-processing (triangulation, pre-transformed vertices) assumes of the
/// scene its reader made, checked on that raw scene before the post-processing runs: positions
/// for every vertex, corners for every face, every index in range, nodes naming existing
/// meshes. Assimp 5.2's readers can break these on a damaged file, and its post-processing
/// then aborts the program (Debian's build keeps its assertions: a PLY declaring 2 vertices
/// and indexing 4 stopped fuzz_mesh in TriangulateProcess.cpp with "numOut !=
/// pMesh->mNumFaces"). A mesh's primitive-type flags are set from its faces, which is what
/// the triangulation reads to decide whether there are polygons to split.
void checkRawScene(aiScene& scene, const std::string& path) {
  if (scene.mNumMeshes > 0 && scene.mMeshes == nullptr)
    fail(path, "assimp read " + counted(scene.mNumMeshes, "mesh", "meshes") + " but returned none");
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) {
    aiMesh* mesh = scene.mMeshes[m];
    const std::string where = "mesh " + std::to_string(m);
    if (mesh == nullptr) fail(path, where + " is missing");
    if (mesh->mNumVertices > 0 && mesh->mVertices == nullptr)
      fail(path, where + " has " + std::to_string(mesh->mNumVertices) + " vertices but no positions");
    if (mesh->mNumFaces > 0 && mesh->mFaces == nullptr)
      fail(path, where + " has " + std::to_string(mesh->mNumFaces) + " faces but no face list");
    unsigned types = 0;
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices == 0 || face.mIndices == nullptr)
        fail(path, where + " face " + std::to_string(f) + " has no corners");
      for (unsigned k = 0; k < face.mNumIndices; ++k)
        if (face.mIndices[k] >= mesh->mNumVertices)
          fail(path, where + " face " + std::to_string(f) + " corner " + std::to_string(k) +
                         ": vertex index must be < " + std::to_string(mesh->mNumVertices) + ", got " +
                         std::to_string(face.mIndices[k]));
      types |= face.mNumIndices == 1   ? aiPrimitiveType_POINT
               : face.mNumIndices == 2 ? aiPrimitiveType_LINE
               : face.mNumIndices == 3 ? aiPrimitiveType_TRIANGLE
                                       : aiPrimitiveType_POLYGON;
    }
    mesh->mPrimitiveTypes = types;
  }
  // The node tree, iteratively (a damaged file must not exhaust the stack): every mesh a
  // node names exists.
  std::vector<const aiNode*> pending;
  if (scene.mRootNode != nullptr) pending.push_back(scene.mRootNode);
  while (!pending.empty()) {
    const aiNode* node = pending.back();
    pending.pop_back();
    if (node->mNumMeshes > 0 && node->mMeshes == nullptr) fail(path, "a node names meshes but lists none");
    for (unsigned k = 0; k < node->mNumMeshes; ++k)
      if (node->mMeshes[k] >= scene.mNumMeshes)
        fail(path, "a node names mesh " + std::to_string(node->mMeshes[k]) + " of " +
                       counted(scene.mNumMeshes, "mesh", "meshes"));
    if (node->mNumChildren > 0 && node->mChildren == nullptr) fail(path, "a node has children but lists none");
    for (unsigned k = 0; k < node->mNumChildren; ++k)
      if (node->mChildren[k] != nullptr) pending.push_back(node->mChildren[k]);
  }
}

/// The scene assimp's reader returned (`raw`, null when it refused the file), checked by
/// checkRawScene and then triangulated and flattened (kImportFlags).
const aiScene* postProcessed(Assimp::Importer& importer, const aiScene* raw, const std::string& path) {
  if (raw == nullptr) fail(path, std::string("assimp cannot read it: ") + importer.GetErrorString());
  // The importer owns the scene and hands it out as const; it is not a const object, and
  // ApplyPostProcessing below rewrites it in place anyway.
  checkRawScene(const_cast<aiScene&>(*raw), path);
  const aiScene* scene = importer.ApplyPostProcessing(kImportFlags);
  if (scene == nullptr) fail(path, std::string("assimp cannot read it: ") + importer.GetErrorString());
  return scene;
}

TriangleMesh cleaned(const TriangleMesh& raw, const std::string& path, const MeshCleanOptions& options,
                     MeshReport* report) {
  try {
    return cleanMesh(raw, options, report);
  } catch (const std::invalid_argument& e) {
    fail(path, e.what());
  }
}

void checkCleanOptions(const MeshCleanOptions& options) {
  if (!(std::isfinite(options.weldTolerance) && options.weldTolerance >= 0))
    throw std::invalid_argument("loadCleanMesh: MeshCleanOptions.weldTolerance must be finite and >= 0 (m), got " +
                                io_detail::fmt(options.weldTolerance));
}

}  // namespace

TriangleMesh loadMesh(const std::string& path) {
  checkReadable(path);
  checkPlyHeaderInFile(path);
  Assimp::Importer importer;
  configure(importer);
  return collectTriangles(postProcessed(importer, importer.ReadFile(path, 0), path), path);
}

TriangleMesh loadMeshFromMemory(const std::string& contents, const std::string& name) {
  if (contents.empty()) fail(name, "no triangles: the file is empty (0 bytes)");
  checkPlyHeaderInMemory(contents, name);
  const std::string extension = std::filesystem::path(name).extension().string();
  const std::string hint = extension.empty() ? std::string() : extension.substr(1);
  Assimp::Importer importer;
  configure(importer);
  const aiScene* raw = importer.ReadFileFromMemory(contents.data(), contents.size(), 0, hint.c_str());
  return collectTriangles(postProcessed(importer, raw, name), name);
}

TriangleMesh loadCleanMeshFromMemory(const std::string& contents, const std::string& name,
                                     const MeshCleanOptions& options, MeshReport* report) {
  checkCleanOptions(options);
  return cleaned(loadMeshFromMemory(contents, name), name, options, report);
}

TriangleMesh loadCleanMesh(const std::string& path, const MeshCleanOptions& options, MeshReport* report) {
  checkCleanOptions(options);
  return cleaned(loadMesh(path), path, options, report);
}

}  // namespace weft
