// tests/test_io.cpp — frames out: topology, OBJ, PLY, the binary frame cache and (when
// weft::io is built: WEFT_TEST_GLTF) the animated glTF, read back with tinygltf.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "support/test_support.hpp"

#ifdef WEFT_TEST_GLTF
#include <weft/io/gltf.hpp>

// The reader: tinygltf compiled here, apart from the copy inside weft::io (which lives in a
// namespace of its own), so the file is read by code that did not write it.
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>
#endif

namespace weft::test {
namespace {

namespace fs = std::filesystem;

/// A fresh path under the test temp directory (any old file of that name removed).
std::string tempPath(const std::string& name) {
  const std::string path = ::testing::TempDir() + "weft_io_" + name;
  fs::remove(path);
  fs::remove(path + ".tmp");
  return path;
}

std::string readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

template <class S>
S parseScalar(const std::string& text) {
  if constexpr (std::is_same_v<S, float>)
    return std::strtof(text.c_str(), nullptr);
  else
    return std::strtod(text.c_str(), nullptr);
}

/// A 4 x 4 flag after a few steps: coordinates with all their digits in use.
template <class S>
std::pair<Model<S>, State<S>> movedFlag(Index size = 4) {
  SimulationOptions options;
  options.threads = 1;
  options.dt = defaultTimeStep(BuiltinScene::Flag, size);
  Simulation<S> sim(makeFlag<S>(size), options);
  EXPECT_TRUE(sim.run(7).ok());
  return {sim.model(), sim.state()};
}

template <class S>
class FramesTyped : public ::testing::Test {};
TYPED_TEST_SUITE(FramesTyped, ScalarTypes);

TEST(Frames, GridTopologyIsTwoConsistentlyWoundTrianglesPerCell) {
  const ModelAndState<double> flag = makeFlag<double>(4);
  const FrameTopology t = frameTopology(flag.model);
  EXPECT_EQ(t.triangles.size(), 18u);
  EXPECT_TRUE(t.lines.empty());
  // Consistent winding: no directed edge is used twice (a shared edge runs once each way).
  std::set<std::pair<Index, Index>> directed;
  for (const auto& tri : t.triangles)
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(directed.insert({tri[k], tri[(k + 1) % 3]}).second) << tri[k] << " -> " << tri[(k + 1) % 3];
      EXPECT_GE(tri[k], 0);
      EXPECT_LT(tri[k], 16);
    }
}

// A scene with a cloth and a rope: the frame holds both, the cloth's triangles and the rope's
// links as lines (and a link from the rope to the cloth), none of the cloth's own springs.
TEST(Frames, AClothAndARopeAreBothInTheFrame) {
  ModelBuilder<double> b;
  ClothGridSpec grid;
  grid.width = grid.height = 3;
  addClothGrid(b, grid);  // particles 0..8, 8 triangles
  RopeSpec rope;
  rope.particleCount = 4;
  rope.origin = {0, -1, 0};
  addRope(b, rope);                                         // particles 9..12, 3 links
  b.addSpring(0, 9, {10, 0}, SpringClass::Structural, -1);  // the rope hangs from the cloth
  b.addSpring(2, 6, {10, 0}, SpringClass::Structural, -1);  // a stitch across the cloth: no edge
  const ModelAndState<double> built = b.build();
  const FrameTopology t = frameTopology(built.model);
  EXPECT_EQ(t.triangles.size(), 8u);
  ASSERT_EQ(t.lines.size(), 5u);
  for (const auto& l : t.lines)
    EXPECT_TRUE(l[0] >= 9 || l[1] >= 9 || (l[0] == 2 && l[1] == 6)) << l[0] << " - " << l[1];
  // The glTF writer holds one kind of primitive: both are refused, not one dropped.
  const std::string both = thrownMessage<std::invalid_argument>(
      [&] { GltfAnimationWriter<double> w(tempPath("both.glb"), built.model.particleCount(), t); });
  EXPECT_NE(both.find("8 triangles and 5 lines"), std::string::npos) << both;
}

TYPED_TEST(FramesTyped, ObjOfAFlagHasEveryVertexAndFaceAndParsesBackExactly) {
  using S = TypeParam;
  const auto [model, state] = movedFlag<S>();
  const std::string path = tempPath(std::string("flag_") + scalarName<S>() + ".obj");
  writeObj(path, state.x, frameTopology(model));
  EXPECT_FALSE(fs::exists(path + ".tmp"));

  std::ifstream in(path);
  std::string line;
  std::vector<std::array<S, 3>> vertices;
  int faces = 0;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string tag;
    fields >> tag;
    if (tag == "v") {
      std::array<std::string, 3> text;
      fields >> text[0] >> text[1] >> text[2];
      vertices.push_back({parseScalar<S>(text[0]), parseScalar<S>(text[1]), parseScalar<S>(text[2])});
    } else if (tag == "f") {
      int a = 0, b = 0, c = 0;
      fields >> a >> b >> c;
      EXPECT_TRUE(a >= 1 && a <= 16 && b >= 1 && b <= 16 && c >= 1 && c <= 16) << line;
      ++faces;
    } else {
      EXPECT_TRUE(tag.empty() || tag[0] == '#') << "unexpected line: " << line;
    }
  }
  ASSERT_EQ(vertices.size(), 16u);
  EXPECT_EQ(faces, 18);
  for (Index i = 0; i < 16; ++i)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(vertices[i][c], state.x(i, c)) << "particle " << i << " axis " << c;
}

TEST(Frames, ObjOfARopeHasItsStructuralSpringsAsLines) {
  const ModelAndState<double> rope = makeRope<double>(5);
  const std::string path = tempPath("rope.obj");
  writeObj(path, rope.state.x, frameTopology(rope.model));
  std::ifstream in(path);
  std::string line;
  std::vector<std::string> lines;
  int vertices = 0;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) == 0) ++vertices;
    if (line.rfind("l ", 0) == 0) lines.push_back(line);
    EXPECT_NE(line.rfind("f ", 0), 0u) << "a rope has no faces: " << line;
  }
  EXPECT_EQ(vertices, 5);
  EXPECT_EQ(lines, (std::vector<std::string>{"l 1 2", "l 2 3", "l 3 4", "l 4 5"}));
}

TYPED_TEST(FramesTyped, PlyHeaderCountsAndBinaryBodyReadBackExactly) {
  using S = TypeParam;
  const auto [model, state] = movedFlag<S>();
  const FrameTopology topology = frameTopology(model);
  const std::string path = tempPath(std::string("flag_") + scalarName<S>() + ".ply");
  writePly(path, state.x, topology);
  const std::string data = readAll(path);
  const std::string endHeader = "end_header\n";
  const std::size_t bodyStart = data.find(endHeader);
  ASSERT_NE(bodyStart, std::string::npos);
  const std::string header = data.substr(0, bodyStart + endHeader.size());
  const std::string type = std::is_same_v<S, float> ? "float" : "double";
  EXPECT_EQ(header.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u) << header;
  for (const std::string& expected :
       {std::string("element vertex 16\n"), "property " + type + " x\n", "property " + type + " y\n",
        "property " + type + " z\n", std::string("element face 18\n"),
        std::string("property list uchar int vertex_indices\n")})
    EXPECT_NE(header.find(expected), std::string::npos) << "missing '" << expected << "' in\n" << header;
  EXPECT_EQ(header.find("element edge"), std::string::npos) << header;

  const char* p = data.data() + header.size();
  const std::size_t bodyBytes = 16 * 3 * sizeof(S) + 18 * (1 + 3 * sizeof(std::int32_t));
  ASSERT_EQ(data.size() - header.size(), bodyBytes);
  for (Index i = 0; i < 16; ++i)
    for (int c = 0; c < 3; ++c) {
      S value;
      std::memcpy(&value, p, sizeof value);
      p += sizeof value;
      EXPECT_EQ(value, state.x(i, c)) << "particle " << i << " axis " << c;
    }
  for (const auto& tri : topology.triangles) {
    EXPECT_EQ(static_cast<unsigned char>(*p), 3u);
    ++p;
    std::int32_t v[3];
    std::memcpy(v, p, sizeof v);
    p += sizeof v;
    EXPECT_EQ(v[0], tri[0]);
    EXPECT_EQ(v[1], tri[1]);
    EXPECT_EQ(v[2], tri[2]);
  }
}

TEST(Frames, PlyOfARopeHasAnEdgeElement) {
  const ModelAndState<float> rope = makeRope<float>(6);
  const std::string path = tempPath("rope.ply");
  writePly(path, rope.state.x, frameTopology(rope.model));
  const std::string data = readAll(path);
  const std::string header = data.substr(0, data.find("end_header\n") + 11);
  EXPECT_NE(header.find("element edge 5\nproperty int vertex1\nproperty int vertex2\n"), std::string::npos) << header;
  EXPECT_EQ(header.find("element face"), std::string::npos) << header;
  EXPECT_EQ(data.size() - header.size(), 6 * 3 * sizeof(float) + 5 * 2 * sizeof(std::int32_t));
}

TYPED_TEST(FramesTyped, CacheRoundTripIsBitwiseOverSeveralFrames) {
  using S = TypeParam;
  SimulationOptions options;
  options.threads = 1;
  options.dt = defaultTimeStep(BuiltinScene::Flag, 6);
  Simulation<S> sim(makeFlag<S>(6), options);
  const std::string path = tempPath(std::string("round_trip_") + scalarName<S>() + ".wcache");
  std::vector<State<S>> written;
  {
    FrameCacheWriter<S> writer(path, sim.model().particleCount());
    for (int frame = 0; frame < 5; ++frame) {
      if (frame > 0) {
        ASSERT_TRUE(sim.run(3).ok());
      }
      writer.append(sim.state());
      written.push_back(sim.state());
    }
    EXPECT_FALSE(fs::exists(path)) << "the cache appears only when closed";
    writer.close();
  }
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  FrameCacheReader<S> reader(path);
  EXPECT_EQ(reader.frameCount(), 5);
  EXPECT_EQ(reader.particleCount(), 36);
  State<S> out;
  for (const Index frame : {4, 0, 2, 1, 3}) {  // random access
    reader.read(frame, out);
    const State<S>& expected = written[frame];
    ASSERT_EQ(out.x.rows(), 36);
    EXPECT_EQ(out.time, expected.time) << "frame " << frame;
    EXPECT_EQ(std::memcmp(out.x.data(), expected.x.data(), sizeof(S) * expected.x.size()), 0) << "frame " << frame;
  }
  reader.read(4, out);
  EXPECT_NEAR(out.time, 12 * options.dt, 1e-15) << "the last frame is after 4 x 3 steps";
  EXPECT_THROW(reader.read(5, out), std::out_of_range);
}

TEST(Frames, UnclosedCacheLeavesNoFile) {
  const std::string path = tempPath("unclosed.wcache");
  {
    FrameCacheWriter<double> writer(path, 4);
    writer.append(makeRope<double>(4).state);
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_FALSE(fs::exists(path + ".tmp"));
}

/// A closed double cache of the 4-particle rope with `frames` frames.
std::string writeRopeCache(const std::string& name, int frames) {
  const std::string path = tempPath(name);
  const ModelAndState<double> rope = makeRope<double>(4);
  FrameCacheWriter<double> writer(path, 4);
  for (int i = 0; i < frames; ++i) writer.append(rope.state);
  writer.close();
  return path;
}

TEST(Frames, FloatCacheReadAsDoubleFailsNamingThePrecision) {
  const std::string path = tempPath("float.wcache");
  const ModelAndState<float> rope = makeRope<float>(4);
  FrameCacheWriter<float> writer(path, 4);
  writer.append(rope.state);
  writer.close();
  const std::string message = thrownMessage<std::runtime_error>([&] { FrameCacheReader<double> reader(path); });
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find("float"), std::string::npos) << message;
  EXPECT_NE(message.find("double"), std::string::npos) << message;
}

TEST(Frames, TruncatedCacheFailsNamingTheFileAndBothSizes) {
  const std::string path = writeRopeCache("truncated.wcache", 3);
  const std::uintmax_t full = fs::file_size(path);
  EXPECT_EQ(full, 32u + 3 * (8 + 3 * 4 * 8));
  fs::resize_file(path, full - 5);
  const std::string message = thrownMessage<std::runtime_error>([&] { FrameCacheReader<double> reader(path); });
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find(std::to_string(full)), std::string::npos) << "expected size: " << message;
  EXPECT_NE(message.find(std::to_string(full - 5)), std::string::npos) << "actual size: " << message;

  fs::resize_file(path, 10);  // not even a header
  const std::string shortMessage = thrownMessage<std::runtime_error>([&] { FrameCacheReader<double> reader(path); });
  EXPECT_NE(shortMessage.find(path), std::string::npos) << shortMessage;
  EXPECT_NE(shortMessage.find("truncated"), std::string::npos) << shortMessage;
}

TEST(Frames, BadMagicFailsNamingTheFile) {
  const std::string path = writeRopeCache("bad_magic.wcache", 1);
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.write("WEFTCASH", 8);
  }
  const std::string message = thrownMessage<std::runtime_error>([&] { FrameCacheReader<double> reader(path); });
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find("magic"), std::string::npos) << message;
  EXPECT_NE(message.find("WEFTCASH"), std::string::npos) << message;
  {  // bytes that are not printable are quoted as \xNN
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.write(
        "WEFT\x01\xff"
        "AB",
        8);
  }
  const std::string escaped = thrownMessage<std::runtime_error>([&] { FrameCacheReader<double> reader(path); });
  EXPECT_NE(escaped.find("bad magic \"WEFT\\x01\\xffAB\""), std::string::npos) << escaped;
}

// The header of fuzz_frame_cache's seeds with the sizes of a corrupt file: the reader must
// compare them with the file's length before it allocates or reads anything.
TEST(Frames, HeaderClaimingHugeSizesFailsWithoutAllocating) {
  const auto cache = [](const std::string& name, std::uint32_t particles, std::uint64_t frames, std::size_t body) {
    const std::string path = tempPath(name);
    std::string bytes("WEFTCACH", 8);
    const std::uint32_t fields[4] = {1, 8, particles, 0};
    bytes.append(reinterpret_cast<const char*>(fields), sizeof fields);
    bytes.append(reinterpret_cast<const char*>(&frames), sizeof frames);
    bytes.append(body, '\0');
    std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
  };
  // 2^31 - 1 particles in one frame (48 GiB) claimed by a 40-byte file.
  std::string path = cache("huge_particles.wcache", 0x7fffffff, 1, 8);
  std::string message = thrownMessage<std::runtime_error>([&] { FrameCacheReader<double> reader(path); });
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find("size mismatch: header says 1 frames of 2147483647 particles"), std::string::npos) << message;
  EXPECT_NE(message.find("expected 51539607568 bytes, the file has 40 bytes (truncated)"), std::string::npos)
      << message;
  // Frame counts whose expected size overflows 64 bits are reported as such, and as
  // truncated even when frames x frameBytes wraps to less than the file's body (here
  // 177372539170284151 x 104 = 2^64 + 88 bytes, and the body is 104 bytes).
  for (const std::uint64_t frames : {~std::uint64_t{0}, std::uint64_t{177372539170284151u}}) {
    path = cache("huge_frames.wcache", 4, frames, 104);
    message = thrownMessage<std::runtime_error>([&] { FrameCacheReader<double> reader(path); });
    EXPECT_NE(message.find("header says " + std::to_string(frames) + " frames of 4 particles"), std::string::npos)
        << message;
    EXPECT_NE(message.find("expected more than 2^64 bytes, the file has 136 bytes (truncated)"), std::string::npos)
        << message;
  }
  // More particles than an Index holds.
  path = cache("too_many_particles.wcache", 0x80000000u, 0, 0);
  message = thrownMessage<std::runtime_error>([&] { FrameCacheReader<double> reader(path); });
  EXPECT_NE(message.find("particle count = 2147483648 exceeds 2^31 - 1"), std::string::npos) << message;
}

TEST(Frames, WritingIntoAMissingDirectoryThrowsNamingThePathAndLeavesNoFile) {
  const std::string dir = ::testing::TempDir() + "weft_io_no_such_directory";
  fs::remove_all(dir);
  const ModelAndState<double> flag = makeFlag<double>(3);
  const FrameTopology topology = frameTopology(flag.model);
  const std::vector<std::pair<std::string, std::function<void(const std::string&)>>> writers = {
      {"frame.obj", [&](const std::string& p) { writeObj(p, flag.state.x, topology); }},
      {"frame.ply", [&](const std::string& p) { writePly(p, flag.state.x, topology); }},
      {"frames.wcache", [&](const std::string& p) { FrameCacheWriter<double> writer(p, 9); }},
  };
  for (const auto& [name, write] : writers) {
    const std::string path = dir + "/" + name;
    const std::string message = thrownMessage<std::runtime_error>([&] { write(path); });
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_NE(message.find(std::strerror(ENOENT)), std::string::npos) << message;
    EXPECT_FALSE(fs::exists(path));
    EXPECT_FALSE(fs::exists(path + ".tmp"));
  }
  EXPECT_FALSE(fs::exists(dir));
}

TEST(Frames, TopologyIndexOutOfRangeIsRejectedNamingTheField) {
  const ModelAndState<double> rope = makeRope<double>(3);
  FrameTopology bad;
  bad.lines.push_back({0, 7});
  const std::string path = tempPath("bad_topology.obj");
  const std::string message = thrownMessage<std::invalid_argument>([&] { writeObj(path, rope.state.x, bad); });
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find("lines"), std::string::npos) << message;
  EXPECT_NE(message.find("7"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(path));
}

#ifdef WEFT_TEST_GLTF
// ---------------------------------------------------------------------------------------
// glTF
// ---------------------------------------------------------------------------------------

/// The elements of a tightly packed float or uint32 accessor, as double.
std::vector<double> accessorValues(const tinygltf::Model& m, int index) {
  const tinygltf::Accessor& a = m.accessors.at(static_cast<std::size_t>(index));
  const tinygltf::BufferView& v = m.bufferViews.at(static_cast<std::size_t>(a.bufferView));
  const std::vector<unsigned char>& data = m.buffers.at(static_cast<std::size_t>(v.buffer)).data;
  const std::size_t components = a.type == TINYGLTF_TYPE_VEC3 ? 3 : 1;
  EXPECT_EQ(v.byteStride, 0u);
  EXPECT_LE(v.byteOffset + a.byteOffset + 4 * components * a.count, data.size());
  EXPECT_LE(a.byteOffset + 4 * components * a.count, v.byteLength);
  std::vector<double> values(components * a.count);
  const unsigned char* p = data.data() + v.byteOffset + a.byteOffset;
  for (std::size_t k = 0; k < values.size(); ++k) {
    if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) {
      float f;
      std::memcpy(&f, p + 4 * k, 4);
      values[k] = f;
    } else {
      EXPECT_EQ(a.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
      std::uint32_t u;
      std::memcpy(&u, p + 4 * k, 4);
      values[k] = u;
    }
  }
  return values;
}

/// Reads a .glb with tinygltf; fails the test on any error.
tinygltf::Model loadGlb(const std::string& path) {
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string error, warning;
  const bool ok = loader.LoadBinaryFromFile(&m, &error, &warning, path);
  EXPECT_TRUE(ok) << path << ": " << error;
  EXPECT_TRUE(warning.empty()) << warning;
  return m;
}

/// A POSITION accessor's min and max must be exactly the bounds of its values (glTF 2.0).
void expectBoundsAreExact(const tinygltf::Model& m, int index) {
  const tinygltf::Accessor& a = m.accessors.at(static_cast<std::size_t>(index));
  const std::vector<double> v = accessorValues(m, index);
  ASSERT_EQ(a.minValues.size(), 3u);
  ASSERT_EQ(a.maxValues.size(), 3u);
  for (std::size_t c = 0; c < 3; ++c) {
    double lo = v[c], hi = v[c];
    for (std::size_t i = c; i < v.size(); i += 3) {
      lo = std::min(lo, v[i]);
      hi = std::max(hi, v[i]);
    }
    EXPECT_EQ(a.minValues[c], lo) << "accessor " << index << " axis " << c;
    EXPECT_EQ(a.maxValues[c], hi) << "accessor " << index << " axis " << c;
  }
}

/// Frames that remove their files before and after.
std::string gltfPath(const std::string& name) {
  const std::string path = tempPath(name);
  fs::remove(path + ".frames.tmp");
  return path;
}

void expectNoTemporaries(const std::string& path) {
  EXPECT_FALSE(fs::exists(path + ".tmp")) << path << ".tmp left behind";
  EXPECT_FALSE(fs::exists(path + ".frames.tmp")) << path << ".frames.tmp left behind";
}

// A flag run written every 3 steps: read back with tinygltf, the base mesh plus the morph
// targets, weighted as the animation's keys say (what an importer does), give each frame's
// positions within one float rounding, at the frame's time.
TYPED_TEST(FramesTyped, GltfPlaysBackEveryFrameOfTheRun) {
  using S = TypeParam;
  SimulationOptions options;
  options.threads = 1;
  options.dt = defaultTimeStep(BuiltinScene::Flag, 6);
  Simulation<S> sim(makeFlag<S>(6), options);
  const FrameTopology topology = frameTopology(sim.model());
  const std::string path = gltfPath(std::string("flag_") + scalarName<S>() + ".glb");
  std::vector<State<S>> written;
  {
    GltfAnimationWriter<S> writer(path, sim.model().particleCount(), topology, GltfOptions{"flag"});
    for (int frame = 0; frame < 5; ++frame) {
      if (frame > 0) {
        ASSERT_TRUE(sim.run(3).ok());
      }
      writer.append(sim.state());
      written.push_back(sim.state());
    }
    EXPECT_EQ(writer.frameCount(), 5);
    EXPECT_FALSE(fs::exists(path)) << "the file must appear only once closed";
    writer.close();
  }
  expectNoTemporaries(path);
  const std::size_t F = written.size(), n = 36;
  // The GLB header: magic, version 2, the file's length.
  const std::string bytes = readAll(path);
  ASSERT_GE(bytes.size(), 12u);
  std::uint32_t header[3];
  std::memcpy(header, bytes.data(), sizeof header);
  EXPECT_EQ(bytes.substr(0, 4), "glTF");
  EXPECT_EQ(header[1], 2u);
  EXPECT_EQ(header[2], bytes.size());
  const tinygltf::Model m = loadGlb(path);
  if (::testing::Test::HasFailure()) return;
  ASSERT_EQ(m.buffers.size(), 1u);
  EXPECT_EQ(m.buffers[0].data.size(), gltfBinaryBytes(36, topology, 5));
  EXPECT_EQ(m.asset.version, "2.0");
  ASSERT_EQ(m.scenes.size(), 1u);
  ASSERT_EQ(m.nodes.size(), 1u);
  EXPECT_EQ(m.nodes[0].name, "flag");
  ASSERT_EQ(m.nodes[0].mesh, 0);
  ASSERT_EQ(m.meshes.size(), 1u);
  ASSERT_EQ(m.meshes[0].primitives.size(), 1u);
  const tinygltf::Primitive& p = m.meshes[0].primitives[0];
  EXPECT_EQ(p.mode, TINYGLTF_MODE_TRIANGLES);

  // The triangles, as the topology has them.
  const std::vector<double> indices = accessorValues(m, p.indices);
  ASSERT_EQ(indices.size(), 3 * topology.triangles.size());
  for (std::size_t t = 0; t < topology.triangles.size(); ++t)
    for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(indices[3 * t + k], topology.triangles[t][k]);

  // Frame 0 is the base; every other frame a target of deltas; all with exact bounds.
  const int basePositions = p.attributes.at("POSITION");
  ASSERT_EQ(m.accessors[static_cast<std::size_t>(basePositions)].count, n);
  expectBoundsAreExact(m, basePositions);
  ASSERT_EQ(p.targets.size(), F - 1);
  std::vector<std::vector<double>> deltas;
  for (const auto& target : p.targets) {
    ASSERT_EQ(m.accessors[static_cast<std::size_t>(target.at("POSITION"))].count, n);
    expectBoundsAreExact(m, target.at("POSITION"));
    deltas.push_back(accessorValues(m, target.at("POSITION")));
  }
  EXPECT_EQ(m.meshes[0].weights, std::vector<double>(F - 1, 0.0));

  // The animation: LINEAR on the node's weights, keyed at the frames' times.
  ASSERT_EQ(m.animations.size(), 1u);
  const tinygltf::Animation& a = m.animations[0];
  ASSERT_EQ(a.channels.size(), 1u);
  ASSERT_EQ(a.samplers.size(), 1u);
  EXPECT_EQ(a.channels[0].target_node, 0);
  EXPECT_EQ(a.channels[0].target_path, "weights");
  EXPECT_EQ(a.samplers[0].interpolation, "LINEAR");
  const std::vector<double> times = accessorValues(m, a.samplers[0].input);
  const tinygltf::Accessor& input = m.accessors[static_cast<std::size_t>(a.samplers[0].input)];
  ASSERT_EQ(times.size(), F);
  EXPECT_EQ(input.minValues, std::vector<double>{times.front()});
  EXPECT_EQ(input.maxValues, std::vector<double>{times.back()});
  const std::vector<double> weights = accessorValues(m, a.samplers[0].output);
  ASSERT_EQ(weights.size(), F * (F - 1));

  const std::vector<double> base = accessorValues(m, basePositions);
  for (std::size_t k = 0; k < F; ++k) {
    EXPECT_EQ(times[k], static_cast<float>(written[k].time)) << "key " << k;
    if (k > 0) {
      EXPECT_GT(times[k], times[k - 1]);
    }
    double worst = 0;
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t c = 0; c < 3; ++c) {
        // As an importer computes it, in float: base + sum of weight x delta.
        float x = static_cast<float>(base[3 * i + c]);
        for (std::size_t j = 0; j + 1 < F; ++j)
          x += static_cast<float>(weights[k * (F - 1) + j]) * static_cast<float>(deltas[j][3 * i + c]);
        const double expected = static_cast<double>(written[k].x(static_cast<Index>(i), static_cast<int>(c)));
        worst = std::max(worst, std::abs(x - expected) / std::max(1.0, std::abs(expected)));
      }
    // One rounding of the base and one of the sum: 2^-23 relative at most.
    EXPECT_LE(worst, 1.2e-7) << "frame " << k;
  }
  fs::remove(path);
}

TEST(Frames, GltfOfARopeHasItsStructuralSpringsAsLines) {
  const ModelAndState<double> rope = makeRope<double>(5);
  const std::string path = gltfPath("rope.glb");
  GltfAnimationWriter<double> writer(path, 5, frameTopology(rope.model));
  writer.append(rope.state);
  writer.close();
  const tinygltf::Model m = loadGlb(path);
  if (::testing::Test::HasFailure()) return;
  const tinygltf::Primitive& p = m.meshes.at(0).primitives.at(0);
  EXPECT_EQ(p.mode, TINYGLTF_MODE_LINE);
  EXPECT_EQ(accessorValues(m, p.indices), (std::vector<double>{0, 1, 1, 2, 2, 3, 3, 4}));
  // One frame: a still mesh, no targets and no animation.
  EXPECT_TRUE(p.targets.empty());
  EXPECT_TRUE(m.animations.empty());
  const std::vector<double> x = accessorValues(m, p.attributes.at("POSITION"));
  ASSERT_EQ(x.size(), 15u);
  for (Index i = 0; i < 5; ++i)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(x[3 * i + c], static_cast<float>(rope.state.x(i, c)));
  fs::remove(path);

  // Particles joined by nothing: points.
  const std::string points = gltfPath("points.glb");
  GltfAnimationWriter<double> pointWriter(points, 5, FrameTopology{});
  pointWriter.append(rope.state);
  pointWriter.close();
  const tinygltf::Model pm = loadGlb(points);
  EXPECT_EQ(pm.meshes.at(0).primitives.at(0).mode, TINYGLTF_MODE_POINTS);
  EXPECT_EQ(pm.meshes.at(0).primitives.at(0).indices, -1);
  fs::remove(points);
}

TEST(Frames, GltfBadInputsAreRejectedNamingTheFieldAndTheValue) {
  const ModelAndState<double> flag = makeFlag<double>(3);
  const FrameTopology topology = frameTopology(flag.model);
  const std::string path = gltfPath("bad.glb");

  // An unwritable place fails in the constructor, naming the path and the reason.
  const std::string dir = ::testing::TempDir() + "weft_io_no_such_directory_gltf";
  fs::remove_all(dir);
  std::string message =
      thrownMessage<std::runtime_error>([&] { GltfAnimationWriter<double> w(dir + "/run.glb", 9, topology); });
  EXPECT_NE(message.find(dir + "/run.glb.frames.tmp"), std::string::npos) << message;
  EXPECT_NE(message.find(std::strerror(ENOENT)), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(dir));

  message = thrownMessage<std::invalid_argument>([&] { GltfAnimationWriter<double> w(path, 0, FrameTopology{}); });
  EXPECT_NE(message.find("particleCount = 0"), std::string::npos) << message;
  FrameTopology badTopology = topology;
  badTopology.triangles[2][1] = 9;
  message = thrownMessage<std::invalid_argument>([&] { GltfAnimationWriter<double> w(path, 9, badTopology); });
  EXPECT_NE(message.find("triangles[2][1] = 9 is not a particle index in [0, 9)"), std::string::npos) << message;
  EXPECT_NE(message.find(path), std::string::npos) << message;

  {
    GltfAnimationWriter<double> w(path, 9, topology);
    message = thrownMessage<std::logic_error>([&] { w.close(); });
    EXPECT_NE(message.find("before any frame"), std::string::npos) << message;
  }
  {
    GltfAnimationWriter<double> w(path, 9, topology);
    State<double> small = flag.state;
    small.x.conservativeResize(4, 3);
    message = thrownMessage<std::invalid_argument>([&] { w.append(small); });
    EXPECT_NE(message.find("state.x has 4 rows, the file holds 9 particles"), std::string::npos) << message;
    w.append(flag.state);
    // The same time again: keys must increase.
    message = thrownMessage<std::invalid_argument>([&] { w.append(flag.state); });
    EXPECT_NE(message.find("frame 1: state.time = 0 s"), std::string::npos) << message;
    EXPECT_NE(message.find("not a finite time later than the previous frame's 0 s"), std::string::npos) << message;
    State<double> broken = flag.state;
    broken.time = 1;
    broken.x(5, 1) = std::numeric_limits<double>::quiet_NaN();
    message = thrownMessage<std::invalid_argument>([&] { w.append(broken); });
    EXPECT_NE(message.find("state.x(5, 1) = nan is not finite"), std::string::npos) << message;
    broken.x(5, 1) = 1e300;
    message = thrownMessage<std::invalid_argument>([&] { w.append(broken); });
    EXPECT_NE(message.find("state.x(5, 1) = 1.0000000000000001e+300 does not fit a float"), std::string::npos)
        << message;
    EXPECT_EQ(w.frameCount(), 1);
    // Destroyed unclosed: no file, no temporaries.
  }
  EXPECT_FALSE(fs::exists(path));
  expectNoTemporaries(path);

  // The limits: 4096 frames of a small model; fewer when 4 GiB is the bound.
  EXPECT_EQ(gltfMaxFrames(9, topology), kGltfMaxFrames);
  EXPECT_EQ(gltfMaxFrames(100'000'000, FrameTopology{}), 3);  // 1.2 GB a frame
  EXPECT_EQ(gltfMaxFrames(400'000'000, FrameTopology{}), 0);
  message =
      thrownMessage<std::invalid_argument>([&] { GltfAnimationWriter<float> w(path, 400'000'000, FrameTopology{}); });
  EXPECT_NE(message.find("more than a .glb holds (4 GiB)"), std::string::npos) << message;
  expectNoTemporaries(path);
}

TEST(Frames, GltfRefusesTheFrameAfterItsLimit) {
  const ModelAndState<float> rope = makeRope<float>(2);
  const std::string path = gltfPath("limit.glb");
  GltfAnimationWriter<float> w(path, 2, FrameTopology{});
  State<float> s = rope.state;
  for (std::int64_t k = 0; k < kGltfMaxFrames; ++k) {
    s.time = static_cast<double>(k) * 0.01;
    w.append(s);
  }
  s.time += 1;
  const std::string message = thrownMessage<std::invalid_argument>([&] { w.append(s); });
  EXPECT_NE(message.find("frame 4096 is one more than the 4096 frames this file holds"), std::string::npos) << message;
  w.close();
  const tinygltf::Model m = loadGlb(path);
  ASSERT_EQ(m.animations.size(), 1u);
  EXPECT_EQ(m.accessors.at(static_cast<std::size_t>(m.animations[0].samplers.at(0).output)).count,
            static_cast<std::size_t>(kGltfMaxFrames * (kGltfMaxFrames - 1)));
  EXPECT_LT(fs::file_size(path), 80u << 20);
  fs::remove(path);
}
#endif  // WEFT_TEST_GLTF

}  // namespace
}  // namespace weft::test
