// tests/test_io.cpp — frames out: topology, OBJ, PLY and the binary frame cache.
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

}  // namespace
}  // namespace weft::test
