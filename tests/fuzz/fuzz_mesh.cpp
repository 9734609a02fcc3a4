// tests/fuzz/fuzz_mesh.cpp — a libFuzzer target for mesh import (run by tools/fuzz.sh).
//
// The first byte of every input picks the format hint, byte % 4: '0' obj, '1' ply, '2' stl,
// '3' 3ds (the seeds in tests/fuzz/seeds/mesh/ start with that digit); the rest is the
// file's contents, handed to weft::loadMeshFromMemory the way a program loads an embedded
// mesh. A std::runtime_error from the import (the documented "mesh file '...': ..."
// rejection) or a std::invalid_argument from cleanMesh / addClothMesh / build (documented
// for a bad coordinate, no triangle left, a mesh the cloth builder refuses) is the code
// doing its job; anything else escaping, a crash, a sanitizer report (ASan + UBSan build)
// or a timeout is a finding.
//
// A mesh the import accepts is cleaned (welded) with cleanMesh; when the result is small
// (at most kMaxVertices vertices, so that one input takes milliseconds) a cloth is built
// from it with addClothMesh into a ModelBuilder, in float and in double, and build() must
// then accept it: addClothMesh validates before adding, so build() throwing after it
// accepted the mesh would be a check addClothMesh misses (a finding).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "weft/io/mesh_import.hpp"
#include "weft/weft.hpp"

namespace {

constexpr std::size_t kMaxVertices = 4096;
constexpr const char* kNames[4] = {"fuzz.obj", "fuzz.ply", "fuzz.stl", "fuzz.3ds"};

template <class S>
void buildCloth(const weft::TriangleMesh& mesh) {
  weft::ModelBuilder<S> builder;
  try {
    weft::addClothMesh(builder, mesh);
  } catch (const std::invalid_argument&) {
    if (builder.particleCount() != 0) __builtin_trap();  // "a rejected mesh leaves the builder unchanged"
    return;
  }
  weft::ModelAndState<S> built = builder.build();  // must not throw: see above
  if (built.model.particleCount() != static_cast<weft::Index>(mesh.vertices.size())) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string name = kNames[data[0] % 4];
  const std::string contents(reinterpret_cast<const char*>(data) + 1, size - 1);
  weft::TriangleMesh raw;
  try {
    raw = weft::loadMeshFromMemory(contents, name);
  } catch (const std::runtime_error&) {
    return 0;
  }
  // What the import promises about an accepted mesh: triangles, every index in range.
  if (raw.triangles.empty()) __builtin_trap();
  for (const auto& t : raw.triangles)
    for (const weft::Index i : t)
      if (i < 0 || i >= static_cast<weft::Index>(raw.vertices.size())) __builtin_trap();
  weft::TriangleMesh mesh;
  weft::MeshReport report;
  try {
    mesh = weft::cleanMesh(raw, {}, &report);
  } catch (const std::invalid_argument&) {
    return 0;
  }
  if (mesh.triangles.empty() || report.outputVertices != static_cast<weft::Index>(mesh.vertices.size()) ||
      report.inputVertices != report.weldedVertices + report.unreferencedVertices + report.outputVertices ||
      report.inputTriangles != report.degenerateTriangles + report.duplicateTriangles + report.outputTriangles)
    __builtin_trap();
  if (mesh.vertices.size() <= kMaxVertices) {
    buildCloth<float>(mesh);
    buildCloth<double>(mesh);
  }
  return 0;
}
