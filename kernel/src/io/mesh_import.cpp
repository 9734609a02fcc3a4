#include "weft/io/mesh_import.hpp"

#include <assimp/BaseImporter.h>
#include <assimp/config.h>
#include <assimp/importerdesc.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <array>
#include <assimp/IOStream.hpp>
#include <assimp/IOSystem.hpp>
#include <assimp/Importer.hpp>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "io_text.hpp"
#include "mesh_readers.hpp"

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

/// weft's own readers (mesh_readers.hpp): PLY, STL and OBJ in double, file order kept.
using OwnRead = std::vector<io_detail::PolygonMesh> (*)(std::string_view bytes);

/// Keeps assimp's own loader for a format weft reads itself out of an importer: it claims
/// the format's extension and refuses every file. loadMesh hands those formats to weft's
/// readers (by extension, or by their bytes under a name assimp does not know) before an
/// importer is made, so it is a guard: reaching it is a logic error.
class OwnFormatGuard final : public Assimp::BaseImporter {
 public:
  explicit OwnFormatGuard(const char* extension) : extension_(extension) {
    desc_.mName = "weft's own reader (guard)";
    desc_.mAuthor = desc_.mMaintainer = "weft";
    desc_.mFlags = aiImporterFlags_SupportTextFlavour | aiImporterFlags_SupportBinaryFlavour;
    desc_.mFileExtensions = extension_;
  }
  const char* extension() const { return extension_; }
  bool CanRead(const std::string& file, Assimp::IOSystem* /*io*/, bool /*checkSig*/) const override {
    return SimpleExtensionCheck(file, extension_);
  }
  const aiImporterDesc* GetInfo() const override { return &desc_; }

 protected:
  void InternReadFile(const std::string& /*file*/, aiScene* /*scene*/, Assimp::IOSystem* /*io*/) override {
    throw std::logic_error(std::string("weft reads .") + extension_ + " files itself; assimp was asked");
  }

 private:
  const char* extension_;
  aiImporterDesc desc_{};
};

/// An importer without assimp's PLY, STL and OBJ loaders (OwnFormatGuard in their place).
struct Importer {
  Assimp::Importer assimp;

  Importer() {
    // A file with bones but no meshes must not turn into assimp's generated bone geometry.
    assimp.SetPropertyBool(AI_CONFIG_IMPORT_NO_SKELETON_MESHES, true);
    for (const char* extension : {"ply", "stl", "obj"}) guard(new OwnFormatGuard(extension));
  }

 private:
  void guard(OwnFormatGuard* mine) {
    std::unique_ptr<OwnFormatGuard> owned(mine);
    // Assimp's loaders for the extension are taken out (UnregisterLoader hands them back
    // to the caller to delete).
    while (Assimp::BaseImporter* theirs = assimp.GetImporter(mine->extension())) {
      if (assimp.UnregisterLoader(theirs) != AI_SUCCESS) throw std::logic_error("assimp keeps its loader");
      delete theirs;
    }
    if (assimp.RegisterLoader(owned.get()) != AI_SUCCESS) throw std::logic_error("assimp refused weft's guard");
    owned.release();  // the importer deletes its loaders
  }
};

// No aiProcess_JoinIdenticalVertices: cleanMesh welds, and reports how many it welded. No
// aiProcess_Triangulate: assimp 5.2's folds concave polygons; weft triangulates them itself
// (io_detail::triangulatePolygon).
constexpr unsigned kImportFlags = aiProcess_PreTransformVertices;

/// What a file held beside its triangles and polygons.
struct Ignored {
  std::uint64_t points = 0, lines = 0, emptyFaces = 0;
};

void checkTriangleRoom(const TriangleMesh& mesh, size_t more, const std::string& path) {
  constexpr size_t kMaxIndex = static_cast<size_t>(std::numeric_limits<Index>::max());
  if (more > kMaxIndex - mesh.triangles.size()) fail(path, "more than " + std::to_string(kMaxIndex) + " triangles");
}

/// The triangles of weft's own readers' polygons, the vertices in the file's order and in
/// double; points and lines counted in *ignored.
TriangleMesh trianglesOf(std::vector<io_detail::PolygonMesh> meshes, const std::string& path, Ignored* ignored) {
  constexpr size_t kMaxIndex = static_cast<size_t>(std::numeric_limits<Index>::max());
  TriangleMesh mesh;
  Ignored found;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  for (io_detail::PolygonMesh& in : meshes) {
    const size_t base = mesh.vertices.size();
    if (in.vertexCount() > kMaxIndex - base) fail(path, "more than " + std::to_string(kMaxIndex) + " vertices");
    for (size_t v = 0; v < in.vertexCount(); ++v)
      mesh.vertices.push_back({in.xyz[3 * v], in.xyz[3 * v + 1], in.xyz[3 * v + 2]});
    found.points += in.points;
    found.lines += in.lines;
    found.emptyFaces += in.emptyFaces;
    size_t next = 0;
    for (const std::uint32_t size : in.faceSizes) {
      if (size == 1) ++found.points;
      if (size == 2) ++found.lines;
      triangles.clear();
      io_detail::triangulatePolygon(in.xyz, in.indices.data() + next, size, triangles);
      next += size;
      checkTriangleRoom(mesh, triangles.size(), path);
      for (const auto& t : triangles)
        mesh.triangles.push_back(
            {static_cast<Index>(base + t[0]), static_cast<Index>(base + t[1]), static_cast<Index>(base + t[2])});
    }
    in = {};  // each mesh's polygons are let go as soon as its triangles are made
  }
  if (mesh.triangles.empty())
    fail(path, "no triangles: the file has " + counted(found.points, "point", "points") + ", " +
                   counted(found.lines, "line", "lines") + " and " +
                   counted(mesh.vertices.size(), "vertex", "vertices"));
  if (ignored != nullptr) *ignored = found;
  return mesh;
}

/// weft's own reader for a file named `name` with first bytes `head` of `size` bytes: by
/// extension (ply, stl, obj), or for a name assimp does not know by the bytes (PLY, STL,
/// OBJ); null for the formats assimp reads.
OwnRead ownReader(const std::string& name, std::string_view head, std::uint64_t size) {
  if (const char* format = io_detail::ownFormatByName(name))
    return format[0] == 'p' ? io_detail::readPly : format[0] == 's' ? io_detail::readStl : io_detail::readObj;
  const std::string extension = std::filesystem::path(name).extension().string();
  Assimp::Importer probe;
  if (!extension.empty() && probe.IsExtensionSupported(extension)) return nullptr;
  if (io_detail::startsLikePly(head)) return io_detail::readPly;
  if (io_detail::looksLikeStl(head, size)) return io_detail::readStl;
  if (io_detail::looksLikeObj(head)) return io_detail::readObj;
  return nullptr;
}

/// Every triangle of an imported scene; `path` names the source in messages.
TriangleMesh collectTriangles(const aiScene* scene, const std::string& path, Ignored* ignored) {
  constexpr size_t kMaxIndex = static_cast<size_t>(std::numeric_limits<Index>::max());
  TriangleMesh mesh;
  size_t points = 0, lines = 0, polygons = 0;
  std::vector<double> xyz;  // a mesh's vertices, for triangulatePolygon
  std::vector<std::uint32_t> corners;
  std::vector<std::array<std::uint32_t, 3>> cut;
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
    xyz.clear();
    for (unsigned f = 0; f < in->mNumFaces; ++f) {
      const aiFace& face = in->mFaces[f];
      if (face.mNumIndices == 1) ++points;
      if (face.mNumIndices == 2) ++lines;
      if (face.mNumIndices > 3) ++polygons;
      if (face.mNumIndices < 3) continue;
      if (face.mNumIndices > io_detail::kMaxPolygonCorners)
        fail(path, "mesh " + std::to_string(m) + " face " + std::to_string(f) + " has " +
                       std::to_string(face.mNumIndices) + " corners; weft reads polygons of up to " +
                       std::to_string(io_detail::kMaxPolygonCorners));
      corners.clear();
      for (unsigned k = 0; k < face.mNumIndices; ++k) {
        const unsigned index = face.mIndices[k];
        if (index >= in->mNumVertices)
          fail(path, "mesh " + std::to_string(m) + " face " + std::to_string(f) + " corner " + std::to_string(k) +
                         ": vertex index must be < " + std::to_string(in->mNumVertices) + ", got " +
                         std::to_string(index));
        corners.push_back(index);
      }
      if (face.mNumIndices > 3 && xyz.empty())
        for (unsigned v = 0; v < in->mNumVertices; ++v)
          xyz.insert(xyz.end(), {static_cast<double>(in->mVertices[v].x), static_cast<double>(in->mVertices[v].y),
                                 static_cast<double>(in->mVertices[v].z)});
      cut.clear();
      if (face.mNumIndices == 3)
        cut.push_back({corners[0], corners[1], corners[2]});
      else
        io_detail::triangulatePolygon(xyz, corners.data(), face.mNumIndices, cut);
      checkTriangleRoom(mesh, cut.size(), path);
      for (const auto& t : cut)
        mesh.triangles.push_back(
            {static_cast<Index>(base + t[0]), static_cast<Index>(base + t[1]), static_cast<Index>(base + t[2])});
    }
  }
  if (ignored != nullptr) {
    ignored->points = points;
    ignored->lines = lines;
  }
  if (mesh.triangles.empty()) {
    std::string found = counted(scene->mNumMeshes, "mesh", "meshes") + " with " + counted(points, "point", "points") +
                        ", " + counted(lines, "line", "lines");
    if (polygons > 0) found += ", " + counted(polygons, "polygon", "polygons");
    fail(path, "no triangles: assimp read " + found + " and " + counted(mesh.vertices.size(), "vertex", "vertices"));
  }
  return mesh;
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
const aiScene* postProcessed(Importer& reader, const aiScene* raw, const std::string& path) {
  Assimp::Importer& importer = reader.assimp;
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

/// loadMesh, with what the file held beside its faces in *ignored.
TriangleMesh loadCounted(const std::string& path, Ignored* ignored) {
  checkReadable(path);
  std::string contents;
  {
    std::ifstream in(path, std::ios::binary);
    char head[256];
    in.read(head, sizeof head);
    const std::uint64_t size = static_cast<std::uint64_t>(std::filesystem::file_size(path));
    const OwnRead read = ownReader(path, std::string_view(head, static_cast<size_t>(in.gcount())), size);
    if (read == nullptr) {
      Importer importer;
      return collectTriangles(postProcessed(importer, importer.assimp.ReadFile(path, 0), path), path, ignored);
    }
    in.clear();  // a file shorter than the head read above has its end-of-file state set
    in.seekg(0);
    contents.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (!in.good() && !in.eof()) fail(path, std::string("cannot read: ") + std::strerror(errno));
    try {
      std::vector<io_detail::PolygonMesh> meshes = read(contents);
      std::string().swap(contents);  // the bytes are let go before the triangles are made
      return trianglesOf(std::move(meshes), path, ignored);
    } catch (const std::runtime_error& e) {
      if (std::string_view(e.what()).rfind("mesh file '", 0) == 0) throw;
      fail(path, e.what());
    }
  }
}

/// loadMeshFromMemory, with what the file held beside its faces in *ignored.
TriangleMesh loadCountedFromMemory(const std::string& contents, const std::string& name, Ignored* ignored) {
  if (contents.empty()) fail(name, "no triangles: the file is empty (0 bytes)");
  const OwnRead read = ownReader(name, std::string_view(contents).substr(0, 256), contents.size());
  if (read != nullptr) {
    std::vector<io_detail::PolygonMesh> meshes;
    try {
      meshes = read(contents);
    } catch (const std::runtime_error& e) {
      fail(name, e.what());
    }
    return trianglesOf(std::move(meshes), name, ignored);
  }
  Importer importer;
  const std::string extension = std::filesystem::path(name).extension().string();
  const std::string hint = extension.empty() ? std::string() : extension.substr(1);
  const aiScene* raw = importer.assimp.ReadFileFromMemory(contents.data(), contents.size(), 0, hint.c_str());
  return collectTriangles(postProcessed(importer, raw, name), name, ignored);
}

/// The cleaned mesh, the counts of what the file held beside its faces added to *report.
TriangleMesh cleanedWithIgnored(const TriangleMesh& raw, const std::string& path, const MeshCleanOptions& options,
                                MeshReport* report, const Ignored& ignored) {
  TriangleMesh out = cleaned(raw, path, options, report);
  if (report != nullptr) {
    report->ignoredPoints = static_cast<std::int64_t>(ignored.points);
    report->ignoredLines = static_cast<std::int64_t>(ignored.lines);
    report->emptyFaces = static_cast<std::int64_t>(ignored.emptyFaces);
  }
  return out;
}

}  // namespace

TriangleMesh loadMesh(const std::string& path) { return loadCounted(path, nullptr); }

TriangleMesh loadMeshFromMemory(const std::string& contents, const std::string& name) {
  return loadCountedFromMemory(contents, name, nullptr);
}

TriangleMesh loadCleanMeshFromMemory(const std::string& contents, const std::string& name,
                                     const MeshCleanOptions& options, MeshReport* report) {
  checkCleanOptions(options);
  Ignored ignored;
  const TriangleMesh raw = loadCountedFromMemory(contents, name, &ignored);
  return cleanedWithIgnored(raw, name, options, report, ignored);
}

TriangleMesh loadCleanMesh(const std::string& path, const MeshCleanOptions& options, MeshReport* report) {
  checkCleanOptions(options);
  Ignored ignored;
  const TriangleMesh raw = loadCounted(path, &ignored);
  return cleanedWithIgnored(raw, path, options, report, ignored);
}

}  // namespace weft
