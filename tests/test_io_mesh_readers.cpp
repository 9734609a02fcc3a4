// tests/test_io_mesh_readers.cpp — weft's own PLY and STL readers (kernel/src/io/mesh_readers.cpp),
// through the public loadMeshFromMemory / loadMesh.
//
// What they must do: read every valid variant of the formats to the same mesh (ASCII and
// both binary byte orders, any property types and order, extra properties and elements,
// polygons triangulated as for any other format, several STL solids), and refuse a damaged
// file with the place it went wrong, before allocating what a damaged count declares.
// The expected meshes of the valid files were checked against assimp 5.2's own readers,
// which gave the same vertices and triangles.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "support/test_support.hpp"
#include "weft/io/mesh_import.hpp"
#include "weft/model/cloth_mesh.hpp"
#include "weft/model/triangle_mesh.hpp"

namespace weft::test {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;

std::string refusal(const std::string& contents, const std::string& name) {
  return thrownMessage<std::runtime_error>([&] { (void)loadMeshFromMemory(contents, name); });
}

// Six vertices and three faces (a triangle, a quad, a triangle), written every way PLY allows.
const std::vector<Vec3d> kVertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 1.5, 0.25}, {2, 0.5, 1}};
const std::vector<std::vector<int>> kFaces = {{0, 1, 2}, {0, 2, 3, 4}, {1, 5, 2}};

std::string plyHeader(const std::string& format, const std::string& vertexProperties, const std::string& faceProperties,
                      const std::string& between = "") {
  return "ply\nformat " + format + " 1.0\ncomment written by the test\nobj_info nothing\nelement vertex 6\n" +
         vertexProperties + between + "element face 3\n" + faceProperties + "end_header\n";
}

template <class T>
void put(std::string& out, T value, bool bigEndian) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if (bigEndian)
    for (size_t k = 0; k < sizeof(T) / 2; ++k) std::swap(bytes[k], bytes[sizeof(T) - 1 - k]);
  out.append(bytes, sizeof(T));
}

std::string binaryPly(bool bigEndian) {
  std::string out =
      plyHeader(bigEndian ? "binary_big_endian" : "binary_little_endian",
                "property float x\nproperty uchar red\nproperty double y\nproperty float z\nproperty short s\n",
                "property uint8 flags\nproperty list ushort int vertex_indices\nproperty list uchar float uv\n",
                "element edge 1\nproperty list uchar uint vertex_pair\n");
  for (const Vec3d& v : kVertices) {
    put(out, static_cast<float>(v.x), bigEndian);
    put(out, std::uint8_t{200}, bigEndian);
    put(out, v.y, bigEndian);
    put(out, static_cast<float>(v.z), bigEndian);
    put(out, std::int16_t{-7}, bigEndian);
  }
  put(out, std::uint8_t{2}, bigEndian);  // the edge: a list of two
  put(out, std::uint32_t{0}, bigEndian);
  put(out, std::uint32_t{5}, bigEndian);
  for (const auto& face : kFaces) {
    put(out, std::uint8_t{1}, bigEndian);
    put(out, static_cast<std::uint16_t>(face.size()), bigEndian);
    for (const int i : face) put(out, static_cast<std::int32_t>(i), bigEndian);
    put(out, std::uint8_t{2}, bigEndian);
    put(out, 0.5f, bigEndian);
    put(out, 0.25f, bigEndian);
  }
  return out;
}

std::string asciiPly(const std::string& lineEnd = "\n") {
  std::string out = plyHeader("ascii", "property uchar red\nproperty double z\nproperty float x\nproperty float y\n",
                              "property list uchar uint vertex_index\n");
  for (const Vec3d& v : kVertices)
    out += "7 " + std::to_string(v.z) + " " + std::to_string(v.x) + " " + std::to_string(v.y) + "\n";
  for (const auto& face : kFaces) {
    out += std::to_string(face.size());
    for (const int i : face) {
      out += ' ';
      out += std::to_string(i);
    }
    out += "\n";
  }
  if (lineEnd != "\n") {
    std::string converted;
    for (const char c : out) c == '\n' ? converted += lineEnd : converted += c;
    return converted;
  }
  return out;
}

void expectTheSixVertices(const TriangleMesh& mesh, const std::string& which) {
  ASSERT_EQ(mesh.vertices.size(), kVertices.size()) << which;
  for (size_t v = 0; v < kVertices.size(); ++v) {
    EXPECT_EQ(mesh.vertices[v].x, static_cast<double>(static_cast<float>(kVertices[v].x))) << which << " vertex " << v;
    EXPECT_EQ(mesh.vertices[v].y, static_cast<double>(static_cast<float>(kVertices[v].y))) << which << " vertex " << v;
    EXPECT_EQ(mesh.vertices[v].z, static_cast<double>(static_cast<float>(kVertices[v].z))) << which << " vertex " << v;
  }
  // The quad is cut in two by weft's triangulation (ear clipping), the same for every format.
  const std::vector<std::array<Index, 3>> triangles = {{0, 1, 2}, {4, 0, 2}, {3, 4, 2}, {1, 5, 2}};
  EXPECT_EQ(mesh.triangles, triangles) << which;
}

TEST(PlyReader, AsciiAndBothBinaryByteOrdersReadTheSameMesh) {
  expectTheSixVertices(loadMeshFromMemory(asciiPly(), "mesh.ply"), "ascii");
  expectTheSixVertices(loadMeshFromMemory(asciiPly("\r\n"), "mesh.ply"), "ascii, CR LF line ends");
  expectTheSixVertices(loadMeshFromMemory(asciiPly("\r"), "mesh.ply"), "ascii, CR line ends");
  expectTheSixVertices(loadMeshFromMemory(binaryPly(false), "mesh.ply"), "binary little endian");
  expectTheSixVertices(loadMeshFromMemory(binaryPly(true), "MESH.PLY"), "binary big endian, upper-case extension");
  // No extension (or one assimp does not know): the file's first line says it is PLY.
  expectTheSixVertices(loadMeshFromMemory(binaryPly(false), "mesh"), "binary, no extension");
  // A comment in UTF-8 (exporters write user and file names there).
  std::string accented = asciiPly();
  accented.insert(accented.find("comment ") + 8,
                  "cr\xc3\xa9\xc3\xa9 par Ren\xc3\xa9"
                  "e, ");
  expectTheSixVertices(loadMeshFromMemory(accented, "mesh.ply"), "ascii, UTF-8 comment");
  accented.replace(accented.find("element vertex"), 7, "\xc3\xa9lement");
  EXPECT_THAT(refusal(accented, "mesh.ply"), HasSubstr("PLY header has a byte that is not text (0xc3 in line 5)"));
  const std::string path = ::testing::TempDir() + "weft_reader_mesh.ply";
  std::ofstream(path, std::ios::binary) << binaryPly(true);
  expectTheSixVertices(loadMesh(path), "binary big endian, from a file");
}

TEST(PlyReader, DamagedFilesAreRefusedWhereTheyGoWrong) {
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz;
  const std::string faces = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  const std::string body = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  const std::string binaryHead = "ply\nformat binary_little_endian 1.0\nelement vertex 3\n" + xyz + faces;
  ASSERT_EQ(loadMeshFromMemory(head + faces + body, "good.ply").triangles.size(), 1u);
  const std::string binaryFace("\x03\0\0\0\0\x01\0\0\0\x02\0\0\0", 13);
  ASSERT_EQ(loadMeshFromMemory(binaryHead + std::string(36, '\0') + binaryFace + "\r\n", "good.ply").triangles.size(),
            1u)
      << "a binary file may end in a newline";
  const struct {
    std::string contents, expected;
  } cases[] = {
      {"solid x\n", "not a PLY file: it must start with a line 'ply', got 'solid x'"},
      {"plyx\nformat ascii 1.0\nend_header\n", "not a PLY file: it must start with a line 'ply', got 'plyx'"},
      {head, "PLY header has no end_header line"},
      {"ply\nelement vertex 3\n" + xyz + faces + body, "PLY header has no format line"},
      {"ply\nformat binary 1.0\nend_header\n",
       "PLY header line 2: format must be ascii, binary_little_endian or "
       "binary_big_endian, got 'binary'"},
      {"ply\nformat ascii 2.0\nend_header\n", "PLY header line 2: format version must be 1.0, got '2.0'"},
      {"ply\nformat ascii 1.0\nelement vertex 2.5\n" + xyz + faces, "PLY header line 3: an element line is"},
      {"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "PLY header line 3: a property before any element"},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty flt x\nend_header\n",
       "PLY header line 4: property type must be one of"},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty list float int x\nend_header\n",
       "PLY header line 4: a list's count type must be a whole-number type"},
      {"ply\nformat ascii 1.0\nvertices 3\nend_header\n", "PLY header line 3: unknown keyword 'vertices'"},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n" + faces + body,
       "PLY header line 3: the vertex element has no property 'z'"},
      {"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n3 0 1 2\n",
       "PLY header has no 'vertex' element"},
      {head + "element face 1\nproperty list uchar float vertex_indices\nend_header\n" + body,
       "PLY header line 7: face property 'vertex_indices' must be a list of whole numbers"},
      {head + "element face 1\nproperty uchar n\nend_header\n" + body,
       "PLY header line 7: the face element has no 'vertex_indices' (or 'vertex_index') list property"},
      {head + faces + "0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n",
       "PLY line 11: vertex 1 property 'y' must be a number, got 'zero'"},
      {head + faces + "0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n",
       "PLY line 13: entry 1 of face 0 property 'vertex_indices' must be a whole number, got '1.5'"},
      {head + faces + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
       "PLY face 0 corner 2: vertex index must be >= 0 and < 3 (the vertex count), got 3"},
      {head + faces + "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", "PLY face 0 corner 1: vertex index must be >= 0"},
      {head + faces + "0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n",
       "PLY face 0 property 'vertex_indices': a list's count must be >= 0, got -3"},
      {head + faces + "0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "PLY file ends before entry 2 of face 0"},
      {head + faces + body + "3 0 1 2\n", "PLY line 14: '3' after the last element the header declares"},
      // In a binary file too (a trailing newline is allowed: above).
      {binaryHead + std::string(36, '\0') + binaryFace + binaryFace,
       "PLY file: 13 bytes after the last element the header declares, from byte " +
           std::to_string(binaryHead.size() + 49) + " of the file"},
      {"ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + "end_header\n" + "0 0 0\n1 0 0\n0 1 0\n",
       "no triangles: the PLY file has 3 vertices and no face element"},
      {head + "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0\n",
       "no triangles: the PLY file has 3 vertices and 1 faces, none with a corner"},
      // Counts the bytes cannot hold are refused before anything is allocated for them.
      {"ply\nformat ascii 1.0\nelement vertex 4000000000\n" + xyz + faces + body,
       "PLY header line 3: 4000000000 'vertex' entries need at least 6 bytes each, but only 26 bytes of the file are "
       "left for them"},
      {"ply\nformat binary_little_endian 1.0\nelement vertex 3\n" + xyz + faces + std::string(36, '\0'),
       "PLY header line 7: 1 'face' entries need at least 1 bytes each, but only 0 bytes of the file are left"},
      {"ply\nformat binary_little_endian 1.0\nelement vertex 3\n" + xyz + "end_header\n" + std::string(35, '\0'),
       "PLY header line 3: 3 'vertex' entries need at least 12 bytes each, but only 35 bytes"},
      {binaryHead + std::string(36, '\0') + std::string("\xff\xff\xff\x7f", 4),
       "PLY file ends before entry 0 of face 0 property 'vertex_indices' (byte " +
           std::to_string(binaryHead.size() + 37) + " of the file)"},
      // Counts and indices are whole numbers a double holds exactly.
      {head + faces + "0 0 0\n1 0 0\n0 1 0\nnan 0 1 2\n",
       "PLY line 13: the count of face 0 property 'vertex_indices' must be a "
       "whole number, got 'nan'"},
      {head + faces + "0 0 0\n1 0 0\n0 1 0\n3 0 inf 2\n",
       "PLY line 13: entry 1 of face 0 property 'vertex_indices' must be a "
       "whole number, got 'inf'"},
      {head + faces + "0 0 0\n1 0 0\n0 1 0\n3 0 1e19 2\n",
       "PLY line 13: entry 1 of face 0 property 'vertex_indices' must be a "
       "whole number, got '1e19'"},
      {head + faces + "0 0 0\n1 0 0\n0 1 0\n1e19 0 1 2\n",
       "PLY line 13: the count of face 0 property 'vertex_indices' must be a "
       "whole number, got '1e19'"},
  };
  for (const auto& c : cases)
    EXPECT_THAT(refusal(c.contents, "bad.ply"), HasSubstr("mesh file 'bad.ply': " + c.expected));
  // A polygon of more corners than weft triangulates.
  std::string big =
      head + "element face 1\nproperty list ushort int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n5000";
  for (int k = 0; k < 5000; ++k) {
    big += ' ';
    big += std::to_string(k % 3);
  }
  EXPECT_THAT(refusal(big, "big.ply"), HasSubstr("PLY face 0 has 5000 corners; weft reads polygons of up to 4096"));
}

// Found by fuzz_mesh: a 324-byte PLY file whose vertex line holds an 89-digit number made
// assimp 5.2's PLY reader ask for 7.6 GB. weft's reader refuses it at its first line.
TEST(PlyReader, FuzzedFileThatMadeAssimpAllocateGigabytesIsRefused) {
  std::ifstream in(
      std::string(WEFT_TEST_DATA_DIR) + "/../fuzz/regressions/mesh/ply-long-number-allocates-gigabytes.ply",
      std::ios::binary);
  const std::string input((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_EQ(input.substr(0, 4), "1ply");
  EXPECT_THAT(refusal(input.substr(1), "fuzzed.ply"), HasSubstr("mesh file 'fuzzed.ply': not a PLY file"));
  // Its body's 89-digit coordinate in a file whose header is whole: read as a float beyond
  // range (an infinity), then refused by the cleaning, naming the vertex.
  const std::string longNumber(89, '8');
  const std::string file =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 " +
      longNumber + "\n1 0 0\n0 1 0\n3 0 1 2\n";
  EXPECT_TRUE(std::isinf(loadMeshFromMemory(file, "long.ply").vertices[0].z));
  EXPECT_THAT(thrownMessage<std::runtime_error>([&] { (void)loadCleanMeshFromMemory(file, "long.ply"); }),
              AllOf(HasSubstr("mesh file 'long.ply': "), HasSubstr("vertices[0].z must be finite, got inf")));
}

// STL: three vertices per facet, in order (welding is cleanMesh's job).

const std::vector<std::array<Vec3d, 3>> kFacets = {
    {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}}}, {{{0, 0, 0}, {1, 1, 0}, {0, 1, 0}}}, {{{1, 0, 0}, {2, 0.5, 1}, {1, 1, 0}}}};

std::string binaryStl(const std::string& header = "binary") {
  std::string out = header;
  out.resize(80, ' ');
  put(out, static_cast<std::uint32_t>(kFacets.size()), false);
  for (const auto& facet : kFacets) {
    for (const float n : {0.f, 0.f, 1.f}) put(out, n, false);
    for (const Vec3d& v : facet)
      for (const double c : {v.x, v.y, v.z}) put(out, static_cast<float>(c), false);
    put(out, std::uint16_t{0}, false);
  }
  return out;
}

std::string asciiFacets(size_t from, size_t to) {
  std::string out;
  for (size_t f = from; f < to; ++f) {
    out += " facet normal 0 0 1\n  outer loop\n";
    for (const Vec3d& v : kFacets[f])
      out += "   vertex " + std::to_string(v.x) + " " + std::to_string(v.y) + " " + std::to_string(v.z) + "\n";
    out += "  endloop\n endfacet\n";
  }
  return out;
}

void expectTheThreeFacets(const TriangleMesh& mesh, const std::string& which) {
  ASSERT_EQ(mesh.vertices.size(), 9u) << which;
  ASSERT_EQ(mesh.triangles.size(), 3u) << which;
  for (size_t f = 0; f < 3; ++f)
    for (size_t k = 0; k < 3; ++k) {
      const Vec3d& v = mesh.vertices[static_cast<size_t>(mesh.triangles[f][k])];
      EXPECT_EQ(v.x, static_cast<double>(static_cast<float>(kFacets[f][k].x))) << which;
      EXPECT_EQ(v.y, static_cast<double>(static_cast<float>(kFacets[f][k].y))) << which;
      EXPECT_EQ(v.z, static_cast<double>(static_cast<float>(kFacets[f][k].z))) << which;
      EXPECT_EQ(mesh.triangles[f][k], static_cast<Index>(3 * f + k)) << which;
    }
}

TEST(StlReader, AsciiBinaryAndSeveralSolidsReadTheSameFacets) {
  expectTheThreeFacets(loadMeshFromMemory(binaryStl(), "part.stl"), "binary");
  // A binary file whose 80-byte header starts with "solid": its size says binary.
  expectTheThreeFacets(loadMeshFromMemory(binaryStl("solid but binary"), "part.stl"), "binary, header 'solid'");
  expectTheThreeFacets(loadMeshFromMemory("solid part\n" + asciiFacets(0, 3) + "endsolid part\n", "part.stl"), "ascii");
  expectTheThreeFacets(
      loadMeshFromMemory("solid a\n" + asciiFacets(0, 2) + "endsolid a\nsolid b\n" + asciiFacets(2, 3) + "endsolid b\n",
                         "part.stl"),
      "ascii, two solids");
  std::string upper = "SOLID PART\n" + asciiFacets(0, 3) + "ENDSOLID PART\n";
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  expectTheThreeFacets(loadMeshFromMemory(upper, "part.stl"), "ascii, upper-case keywords");
  expectTheThreeFacets(loadMeshFromMemory("solid part\n" + asciiFacets(0, 3), "part.stl"), "ascii, no endsolid");
  expectTheThreeFacets(loadMeshFromMemory(binaryStl(), "part"), "binary, no extension");
}

TEST(StlReader, DamagedFilesAreRefusedWhereTheyGoWrong) {
  const std::string three = asciiFacets(0, 1);
  std::string cutBinary = binaryStl();
  cutBinary.pop_back();
  std::string zero = binaryStl();
  zero.resize(80);
  put(zero, std::uint32_t{0}, false);
  const struct {
    std::string contents, expected;
  } cases[] = {
      {"solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 1 1 0\n"
       "   vertex 0 1 0\n  endloop\n endfacet\nendsolid x\n",
       "ASCII STL line 7: facet 0 has more than 3 vertices (STL facets are triangles)"},
      {"solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n endfacet\n",
       "ASCII STL line 6: expected 'vertex', got 'endfacet'"},
      {"solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 nan? 0\n",
       "ASCII STL line 5: a vertex's y must be a number, got 'nan?'"},
      {"solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0",
       "ASCII STL line 5: a vertex's z must be a number, got the end of the file"},
      {"solid x\n" + three + "solid\n", "ASCII STL line 9: expected 'facet' or 'endsolid', got 'solid'"},
      {"solid x\n" + three + "endsolid x\ngarbage\n", "ASCII STL line 10: expected 'solid', got 'garbage'"},
      {"solid x\nendsolid x\n", "no triangles: the ASCII STL file has no facets"},
      {zero, "no triangles: the binary STL file declares 0 triangles"},
      {cutBinary,
       "not an STL file: it does not start with 'solid' (ASCII), and as a binary STL its header declares 3 triangles, "
       "which take 234 bytes, but the file has 233"},
      {"v 0 0 0\n",
       "not an STL file: it does not start with 'solid' (ASCII) and is shorter than a binary STL's 84-byte "
       "header (8 bytes)"},
  };
  for (const auto& c : cases)
    EXPECT_THAT(refusal(c.contents, "bad.stl"), HasSubstr("mesh file 'bad.stl': " + c.expected));
}

// A PLY or STL file whose name has no extension, or one assimp does not know, is read by
// weft's reader when its first bytes say which it is (assimp would ask its other loaders
// first: a PLY whose comment says "Blender" must not go to its Blender loader).
TEST(PlyReader, FilesUnderOtherNamesAreReadByWhatTheirBytesSay) {
  std::string blender = asciiPly();
  blender.insert(blender.find("comment "), "comment Created by Blender 4.2 - www.blender.org\n");
  for (const char* name : {"scan", "scan.txt", "scan.data"}) {
    expectTheSixVertices(loadMeshFromMemory(blender, name), name);
    const std::string path = ::testing::TempDir() + "weft_reader_" + name;
    std::ofstream(path, std::ios::binary) << blender;
    expectTheSixVertices(loadMesh(path), path);
  }
  const std::string stl = "solid part\n" + asciiFacets(0, 3) + "endsolid part\n";
  expectTheThreeFacets(loadMeshFromMemory(stl, "part.txt"), "ascii STL named .txt");
  const std::string path = ::testing::TempDir() + "weft_reader_part";
  std::ofstream(path, std::ios::binary) << stl;
  expectTheThreeFacets(loadMesh(path), "ascii STL without extension, from a file");
  // A header that never ends, a megabyte long: refused, holding nothing per line.
  EXPECT_THAT(refusal("ply\n" + std::string(1 << 20, '\n'), "long.ply"),
              HasSubstr("PLY header has no end_header line"));
}

/// An input of tests/fuzz/fuzz_mesh.cpp kept in tests/fuzz/regressions/mesh/, without its
/// first byte (the target's format choice: '1' ply, '2' stl).
std::string fuzzInput(const std::string& name, char format) {
  std::ifstream in(std::string(WEFT_TEST_DATA_DIR) + "/../fuzz/regressions/mesh/" + name, std::ios::binary);
  const std::string input((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(input.substr(0, 1), std::string(1, format)) << name;
  return input.substr(1);
}

// Found by fuzz_mesh once weft read binary STL itself: facets 1e-30 m across (masses of
// 5e-61 kg, whose inverse no float holds) and coordinates of 1e30 m (whose squares none
// does). The float cloth is refused by addClothMesh, naming the vertex, instead of being
// accepted and then refused by ModelBuilder::build; in double both build. (The mass case
// alone: ClothMeshTest.RejectsBadSpecsAndMeshesLeavingTheBuilderUnchanged.)
TEST(StlReader, FuzzedMeshesAFloatClothCannotHoldAreRefusedByAddClothMesh) {
  const struct {
    const char* file;
    const char* expected;
  } cases[] = {{"stl-tiny-triangles-float-mass-overflows.stl", "in float precision"},
               {"stl-far-coordinates-beyond-float-bound.stl", "m in float precision"}};
  for (const auto& c : cases) {
    const TriangleMesh mesh = loadCleanMeshFromMemory(fuzzInput(c.file, '2'), "fuzzed.stl");
    ModelBuilder<float> single;
    EXPECT_THAT(thrownMessage<std::invalid_argument>([&] { (void)addClothMesh(single, mesh); }),
                AllOf(HasSubstr("addClothMesh: "), HasSubstr(c.expected)))
        << c.file;
    EXPECT_EQ(single.particleCount(), 0) << c.file;
    ModelBuilder<double> twice;
    addClothMesh(twice, mesh);
    EXPECT_EQ(twice.build().model.particleCount(), static_cast<Index>(mesh.vertices.size())) << c.file;
  }
}

// ---------------------------------------------------------------------------------------
// OBJ, and polygons cut into triangles

/// Twice the signed area of triangle t projected on the xy plane.
double twiceAreaXy(const TriangleMesh& mesh, const std::array<Index, 3>& t) {
  const Vec3d &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
  return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

// A concave L-shaped hexagon of area 3 (counter-clockwise in xy): its 4 triangles lie inside
// its outline, all turned the polygon's way, their areas summing to 3 (assimp 5.2 cut it into
// triangles of total area 4, one of them folded back). The same from OBJ and PLY, and with the
// polygon's corners starting at each of its six vertices.
TEST(PolygonTriangulation, AConcavePolygonIsCutInsideItsOutline) {
  const std::vector<Vec3d> corners = {{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {1, 2, 0}, {0, 2, 0}};
  for (int start = 0; start < 6; ++start) {
    std::string obj, ply =
                         "ply\nformat ascii 1.0\nelement vertex 6\nproperty double x\nproperty double y\n"
                         "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    // (Appended piece by piece: a chain of operator+ on temporaries trips GCC 12's -Wrestrict.)
    for (const Vec3d& v : corners) {
      std::ostringstream line;
      line << v.x << " " << v.y << " " << v.z << "\n";
      obj += "v ";
      obj += line.str();
      ply += line.str();
    }
    obj += "f";
    ply += "6";
    for (int k = 0; k < 6; ++k) {
      obj += ' ';
      obj += std::to_string((start + k) % 6 + 1);
      ply += ' ';
      ply += std::to_string((start + k) % 6);
    }
    ply += "\n";
    for (const auto& [contents, name] : {std::pair{obj, std::string("l.obj")}, std::pair{ply, std::string("l.ply")}}) {
      SCOPED_TRACE(name + " starting at corner " + std::to_string(start));
      const TriangleMesh mesh = loadMeshFromMemory(contents, name);
      ASSERT_EQ(mesh.triangles.size(), 4u);
      double area = 0;
      for (const auto& t : mesh.triangles) {
        const double twice = twiceAreaXy(mesh, t);
        EXPECT_GT(twice, 0) << "a triangle turned against the polygon";
        area += twice / 2;
        // Inside the L: the centroid is not in the missing square [1, 2] x [1, 2].
        const double cx = (mesh.vertices[t[0]].x + mesh.vertices[t[1]].x + mesh.vertices[t[2]].x) / 3;
        const double cy = (mesh.vertices[t[0]].y + mesh.vertices[t[1]].y + mesh.vertices[t[2]].y) / 3;
        EXPECT_FALSE(cx > 1 && cy > 1) << "centroid (" << cx << ", " << cy << ") outside the outline";
      }
      EXPECT_DOUBLE_EQ(area, 3.0);
    }
  }
}

// A polygon built against ear clipping: a 16-pointed star drawn twice around, the second lap
// turned by half a point, 4096 corners (the most a face may have). It has no ear, so every
// cut is a fallback; the cutting must stay fast (a fuzzer's input gets 10 s) and give
// count - 2 triangles. (Its triangles overlap: it crosses itself; cleaning keeps them.)
TEST(PolygonTriangulation, ASelfCrossingPolygonIsCutQuickly) {
  const int corners = 4096, points = 16;
  std::string obj;
  for (int k = 0; k < corners; ++k) {
    const int lap = k / (corners / 2), j = k % (corners / 2);
    const double angle = 2 * 3.141592653589793 * (j + 0.5 * lap) / (corners / 2);
    const double radius = (j % (corners / 2 / points / 2) == 0) ? 2.0 : 1.0 + 0.5 * lap;
    std::ostringstream line;
    line.precision(17);
    line << "v " << radius * std::cos(angle) << " " << radius * std::sin(angle) << " 0\n";
    obj += line.str();
  }
  obj += "f";
  for (int k = 1; k <= corners; ++k) {
    obj += ' ';
    obj += std::to_string(k);
  }
  obj += '\n';
  EXPECT_EQ(loadMeshFromMemory(obj, "star.obj").triangles.size(), static_cast<size_t>(corners - 2));
}

// Faces name the file's vertices, which keep the file's order (through assimp each face
// corner became a vertex, numbered by face: a pin on vertex 0 held another vertex), and their
// coordinates as written (through assimp they passed through float).
TEST(ObjReader, VerticesKeepTheFilesOrderAndDigits) {
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0.1 1.000000001 1\nf 4 3 2\nf 4 2 1\n";
  const TriangleMesh raw = loadMeshFromMemory(obj, "order.obj");
  ASSERT_EQ(raw.vertices.size(), 4u);
  EXPECT_EQ(raw.vertices[0].x, 0.0);
  EXPECT_EQ(raw.vertices[3].x, 0.1);
  EXPECT_EQ(raw.vertices[3].y, 1.000000001);
  const std::vector<std::array<Index, 3>> triangles = {{3, 2, 1}, {3, 1, 0}};
  EXPECT_EQ(raw.triangles, triangles);
  const TriangleMesh clean = loadCleanMeshFromMemory(obj, "order.obj");
  EXPECT_EQ(clean.vertices[0].x, 0.0);
  EXPECT_EQ(clean.vertices[0].z, 0.0) << "the file's first vertex is the cleaned mesh's first";
  // A PLY double property arrives as written too.
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
      "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0.1 0 0\n1.000000001 0 0\n0 1 0\n3 0 1 2\n";
  const TriangleMesh fromPly = loadMeshFromMemory(ply, "double.ply");
  EXPECT_EQ(fromPly.vertices[0].x, 0.1);
  EXPECT_EQ(fromPly.vertices[1].x, 1.000000001);
}

TEST(ObjReader, EveryFormOfAFaceCornerAndOfAVertexIsRead) {
  // i, i/t, i//n, i/t/n; negative indices count back from the last vertex read; a line
  // continued with a backslash; w = 1, colours after the position, comments.
  const std::string obj =
      "# a comment\nmtllib none.mtl\no square\nv 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 1 1 0\nvt 0 0\nvn 0 0 1\n"
      "g half\ns off\nusemtl none\nf 1/1 2/1/1 3//1\nv 0 1 0\nf -4 -2 \\\n -1\n";
  const TriangleMesh mesh = loadMeshFromMemory(obj, "forms.obj");
  ASSERT_EQ(mesh.vertices.size(), 4u);
  const std::vector<std::array<Index, 3>> triangles = {{0, 1, 2}, {0, 2, 3}};
  EXPECT_EQ(mesh.triangles, triangles);
  EXPECT_EQ(mesh.vertices[1].x, 1.0) << "the colour is not read as a coordinate";
}

TEST(ObjReader, LineEndsCommentsAndNamesAreReadAsTheyAreMeant) {
  const std::vector<std::array<Index, 3>> one = {{0, 1, 2}};
  // Lone CR line ends (classic Mac OS), and CR LF.
  EXPECT_EQ(loadMeshFromMemory("# cr\rv 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\r", "cr.obj").triangles, one);
  EXPECT_EQ(loadMeshFromMemory("v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n", "crlf.obj").triangles, one);
  // A comment ending in a backslash does not continue onto the next line.
  const TriangleMesh commented =
      loadMeshFromMemory("# from C:\\models\\\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n", "c.obj");
  EXPECT_EQ(commented.vertices.size(), 3u);
  EXPECT_EQ(commented.triangles, one);
  // A continuation on the last line ends with the file.
  EXPECT_EQ(loadMeshFromMemory("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 \\", "end.obj").triangles, one);
  // OBJ contents under a name assimp does not know are read by weft's reader too (the file's
  // shared vertices, not a vertex per face corner).
  const std::string quad = "# a quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";
  EXPECT_EQ(loadMeshFromMemory(quad, "mesh.cloth").vertices.size(), 4u);
  EXPECT_EQ(loadMeshFromMemory(quad, "mesh").vertices.size(), 4u);
}

TEST(ObjReader, PointsAndLinesAreCountedInTheReport) {
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 5 5 5\nv 6 6 6\nf 1 2 3\nl 4 5\np 5\np 4 5\n";
  MeshReport report;
  const TriangleMesh mesh = loadCleanMeshFromMemory(obj, "lines.obj", {}, &report);
  EXPECT_EQ(mesh.triangles.size(), 1u);
  EXPECT_EQ(report.ignoredLines, 1);
  EXPECT_EQ(report.ignoredPoints, 3);
  EXPECT_THAT(report.summary(), HasSubstr("3 points ignored; 1 line ignored"));
  // A PLY face of no corner is counted too.
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n0\n";
  (void)loadCleanMeshFromMemory(ply, "empty-face.ply", {}, &report);
  EXPECT_EQ(report.emptyFaces, 1);
  EXPECT_THAT(report.summary(), HasSubstr("1 face with no corner ignored"));
}

TEST(ObjReader, DamagedFilesAreRefusedWhereTheyGoWrong) {
  const std::string three = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  const struct {
    std::string contents, expected;
  } cases[] = {
      {three + "v 2 2 2 2\nf 1 2 3\n",
       "OBJ line 4: vertex 3 has w = 2; weft reads vertices with w = 1 (dividing by w would change the file's "
       "coordinates)"},
      {three + "v 1 2\nf 1 2 3\n", "OBJ line 4: a vertex has 2 numbers; expected 3 (x y z)"},
      {three + "v 1 two 3\nf 1 2 3\n", "OBJ line 4: vertex 3 entry 1 must be a number, got 'two'"},
      {three + "f 1 2 0\n",
       "OBJ line 4: corner 2 of a face must be a vertex number (1 is the first, -1 the last read), "
       "got '0'"},
      {three + "f 1 2 x/1\n", "OBJ line 4: corner 2 of a face must be a vertex number"},
      {three + "f 1 2 -4\n", "OBJ line 4: corner 2 of a face is vertex -4, but 3 vertices are read so far"},
      {three + "f 1 2 4\n", "OBJ line 4: a face names vertex 4, but the file has 3 vertices"},
      {three + "f 1 2 99999999999\n", "OBJ line 4: corner 2 of a face is vertex 99999999999; weft reads up to"},
      {three + "f\n", "OBJ line 4: 'f' with no vertex"},
      {three + "l 1 2\np 3\n", "no triangles: the OBJ file has 3 vertices, 1 point, 1 line and no faces"},
      {three + "v 1 2 3 0.5 0.5 0.5 1\nf 1 2 3\n", "OBJ line 4: a vertex has 7 numbers"},
      {three + "f 1 2 -9223372036854775808\n", "OBJ line 4: corner 2 of a face is vertex -9223372036854775808, but 3"},
      {three + "f 1 2 +-1\n", "OBJ line 4: corner 2 of a face must be a vertex number"},
  };
  for (const auto& c : cases)
    EXPECT_THAT(refusal(c.contents, "bad.obj"), AllOf(HasSubstr("mesh file 'bad.obj': "), HasSubstr(c.expected)))
        << c.contents;
  // A face of up to 4096 corners is read; more are refused.
  std::string big = three + "f";
  for (int k = 0; k < 4097; ++k) {
    big += ' ';
    big += std::to_string(k % 3 + 1);
  }
  EXPECT_THAT(refusal(big + "\n", "big.obj"), HasSubstr("a face has 4097 corners; weft reads polygons of up to 4096"));
}

}  // namespace
}  // namespace weft::test
