#include "weft/io/mesh_import.hpp"

#include <assimp/BaseImporter.h>
#include <assimp/config.h>
#include <assimp/importerdesc.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

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

/// One of weft's own readers (mesh_readers.hpp: PLY, STL) as an assimp loader. Importer
/// takes assimp's loader for the format out of the importer and puts this one in, so that
/// assimp's readers for these formats never see a file, while its post-processing
/// (triangulation, node transforms) runs on what weft read as on any other format.
class WeftLoader final : public Assimp::BaseImporter {
 public:
  using Read = std::vector<io_detail::PolygonMesh> (*)(std::string_view bytes);

  WeftLoader(const char* name, const char* extension, Read read) : read_(read), extension_(extension) {
    desc_.mName = name;
    desc_.mAuthor = "weft";
    desc_.mMaintainer = "weft";
    desc_.mComments = "weft's own reader (kernel/src/io/mesh_readers.cpp)";
    desc_.mFlags = aiImporterFlags_SupportTextFlavour | aiImporterFlags_SupportBinaryFlavour;
    desc_.mFileExtensions = extension_;
  }

  const char* extension() const { return extension_; }
  /// The message of the last file this loader refused ("" if none).
  const std::string& error() const { return error_; }

  /// By extension only: a PLY or STL file under another name gets its format's hint from
  /// sniffedHint before assimp sees it, so asking the bytes again here would repeat that.
  bool CanRead(const std::string& file, Assimp::IOSystem* /*io*/, bool /*checkSig*/) const override {
    return SimpleExtensionCheck(file, extension_);
  }

  const aiImporterDesc* GetInfo() const override { return &desc_; }

 protected:
  void InternReadFile(const std::string& file, aiScene* scene, Assimp::IOSystem* io) override {
    error_.clear();
    try {
      std::vector<io_detail::PolygonMesh> meshes;
      {  // the file's bytes are let go before the scene is made
        std::unique_ptr<Assimp::IOStream> stream(io->Open(file, "rb"));
        if (!stream) throw std::runtime_error("cannot open it");
        std::string bytes(stream->FileSize(), '\0');
        if (stream->Read(bytes.data(), 1, bytes.size()) != bytes.size()) throw std::runtime_error("cannot read it");
        meshes = read_(bytes);
      }
      fill(*scene, std::move(meshes));
    } catch (const std::exception& e) {
      error_ = e.what();
      throw;  // assimp's ReadFile catches it and returns no scene
    }
  }

 private:
  /// The meshes into `scene`, as an assimp reader leaves them: one node naming every mesh,
  /// one default material.
  static void fill(aiScene& scene, std::vector<io_detail::PolygonMesh> meshes) {
    scene.mMaterials = new aiMaterial*[1];
    scene.mMaterials[0] = new aiMaterial();
    scene.mNumMaterials = 1;
    scene.mRootNode = new aiNode();
    scene.mMeshes = new aiMesh*[meshes.size()];
    scene.mRootNode->mMeshes = new unsigned[meshes.size()];
    for (io_detail::PolygonMesh& in : meshes) {
      aiMesh* out = new aiMesh();
      scene.mMeshes[scene.mNumMeshes] = out;
      scene.mRootNode->mMeshes[scene.mNumMeshes] = scene.mNumMeshes;
      ++scene.mNumMeshes;
      ++scene.mRootNode->mNumMeshes;
      out->mVertices = new aiVector3D[in.vertexCount()];
      out->mNumVertices = static_cast<unsigned>(in.vertexCount());
      for (size_t v = 0; v < in.vertexCount(); ++v)
        out->mVertices[v] = aiVector3D(in.xyz[3 * v], in.xyz[3 * v + 1], in.xyz[3 * v + 2]);
      out->mFaces = new aiFace[in.faceSizes.size()];
      out->mNumFaces = static_cast<unsigned>(in.faceSizes.size());
      size_t next = 0;
      for (size_t f = 0; f < in.faceSizes.size(); ++f) {
        aiFace& face = out->mFaces[f];
        face.mIndices = new unsigned[in.faceSizes[f]];
        face.mNumIndices = in.faceSizes[f];
        std::copy_n(in.indices.begin() + static_cast<std::ptrdiff_t>(next), in.faceSizes[f], face.mIndices);
        next += in.faceSizes[f];
      }
      in = {};  // each mesh's copy is let go as soon as assimp's is made
    }
  }

  Read read_;
  const char* extension_;
  aiImporterDesc desc_{};
  std::string error_;
};

/// An importer whose PLY and STL loaders are weft's (WeftLoader) instead of assimp's.
struct Importer {
  Assimp::Importer assimp;
  WeftLoader* ply = nullptr;  // owned by `assimp` (it deletes its loaders)
  WeftLoader* stl = nullptr;

  Importer() {
    // A file with bones but no meshes must not turn into assimp's generated bone geometry.
    assimp.SetPropertyBool(AI_CONFIG_IMPORT_NO_SKELETON_MESHES, true);
    ply = replace(new WeftLoader("weft PLY reader", "ply", io_detail::readPly));
    stl = replace(new WeftLoader("weft STL reader", "stl", io_detail::readStl));
  }

  /// The message weft's own reader gave for the file it last refused ("" if none did).
  std::string readerError() const { return !ply->error().empty() ? ply->error() : stl->error(); }

 private:
  WeftLoader* replace(WeftLoader* mine) {
    std::unique_ptr<WeftLoader> owned(mine);
    // Assimp's loaders for the extension are taken out (UnregisterLoader hands them back
    // to the caller to delete).
    while (Assimp::BaseImporter* theirs = assimp.GetImporter(mine->extension())) {
      if (assimp.UnregisterLoader(theirs) != AI_SUCCESS) throw std::logic_error("assimp keeps its loader");
      delete theirs;
    }
    if (assimp.RegisterLoader(owned.get()) != AI_SUCCESS) throw std::logic_error("assimp refused weft's loader");
    return owned.release();
  }
};

/// The format hint for a file whose name's extension assimp does not know (or that has
/// none) but whose first bytes say PLY or STL: "ply" or "stl", so that weft's reader reads
/// it (assimp would otherwise ask its other loaders first, in its own order, whether the
/// bytes are theirs); "" otherwise, and for every name with a known extension.
std::string sniffedHint(const Importer& importer, const std::string& name, std::string_view head, std::uint64_t size) {
  const std::string extension = std::filesystem::path(name).extension().string();
  if (!extension.empty() && importer.assimp.IsExtensionSupported(extension)) return {};
  if (io_detail::startsLikePly(head)) return "ply";
  if (io_detail::looksLikeStl(head, size)) return "stl";
  return {};
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
  if (raw == nullptr) {
    const std::string ours = reader.readerError();
    if (!ours.empty()) fail(path, ours);
    fail(path, std::string("assimp cannot read it: ") + importer.GetErrorString());
  }
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
  Importer importer;
  {
    // A PLY or STL file under another name is read from memory with its format's hint.
    std::ifstream in(path, std::ios::binary);
    char head[256];
    in.read(head, sizeof head);
    const std::string hint = sniffedHint(importer, path, std::string_view(head, static_cast<size_t>(in.gcount())),
                                         static_cast<std::uint64_t>(std::filesystem::file_size(path)));
    if (!hint.empty()) {
      in.clear();  // a file shorter than the head read above has its end-of-file state set
      in.seekg(0);
      const std::string contents((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      const aiScene* raw = importer.assimp.ReadFileFromMemory(contents.data(), contents.size(), 0, hint.c_str());
      return collectTriangles(postProcessed(importer, raw, path), path);
    }
  }
  return collectTriangles(postProcessed(importer, importer.assimp.ReadFile(path, 0), path), path);
}

TriangleMesh loadMeshFromMemory(const std::string& contents, const std::string& name) {
  if (contents.empty()) fail(name, "no triangles: the file is empty (0 bytes)");
  Importer importer;
  const std::string extension = std::filesystem::path(name).extension().string();
  std::string hint = sniffedHint(importer, name, std::string_view(contents).substr(0, 256), contents.size());
  if (hint.empty() && !extension.empty()) hint = extension.substr(1);
  const aiScene* raw = importer.assimp.ReadFileFromMemory(contents.data(), contents.size(), 0, hint.c_str());
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
