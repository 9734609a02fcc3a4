// tests/test_scene_hashes.cpp — the results of every built-in scene and every scene file,
// held fixed: each is stepped on 1 and 2 threads, in float and double, and its state hash
// (particles, and rigid bodies where there are any: the hash `weft run --json` prints) must
// equal the one recorded in tests/data/state_hashes.txt.
//
// Why: a change that reorganises the kernel (moving derived data into the model, splitting
// files, one vector type) must change no result, and this table says so for every scene at
// once. A change that is meant to change results re-records the table and says why in its
// commit.
//
// Bits depend on the machine code: the table is tagged with the build it was recorded on
// (compiler, SIMD level, build type, sanitizers). On another build the comparison is
// skipped, saying which table it would need (1 vs 2 threads is compared by other tests on
// every build). Recording (prints the table for this build; paste it into the
// file under a new `fingerprint:` line):
//
//   WEFT_RECORD_STATE_HASHES=1 build/tests/test_scene_hashes --gtest_brief=1
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "weft/io/scene.hpp"
#include "weft/weft.hpp"

namespace {

using namespace weft;

const std::string kSource = WEFT_SOURCE_DIR;

/// What the floating-point results of this build depend on.
std::string buildFingerprint() {
  std::string f = "gcc-" + std::to_string(__GNUC__) + "." + std::to_string(__GNUC_MINOR__);
#if defined(__AVX512F__)
  f += " avx512f";
#elif defined(__AVX2__)
  f += " avx2";
#else
  f += " sse2";
#endif
#if defined(__FMA__)
  f += " fma";
#endif
  f += std::string(" ") + WEFT_BUILD_FLAVOUR;
  return f;
}

struct Entry {
  std::string scene;  // a built-in name, or "file:NAME" for tools/scenes/NAME.json
  std::string precision;
  std::int64_t steps = 0;
  std::string hash;  // as weft run prints it: 0x and 16 hex digits
  std::string status;
};

/// The entries recorded for `fingerprint` (the lines after its `fingerprint:` line up to
/// the next one), and every fingerprint the file holds.
std::vector<Entry> readTable(const std::string& fingerprint, std::vector<std::string>& fingerprints) {
  std::ifstream in(kSource + "/tests/data/state_hashes.txt");
  EXPECT_TRUE(in.good()) << "cannot read tests/data/state_hashes.txt";
  std::vector<Entry> entries;
  bool mine = false;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    if (line.rfind("fingerprint:", 0) == 0) {
      const std::string f = line.substr(line.find_first_not_of(' ', 12));
      fingerprints.push_back(f);
      mine = f == fingerprint;
      continue;
    }
    if (!mine) continue;
    std::istringstream fields(line);
    Entry e;
    fields >> e.scene >> e.precision >> e.steps >> e.hash >> e.status;
    EXPECT_FALSE(fields.fail()) << "malformed line in state_hashes.txt: " << line;
    entries.push_back(e);
  }
  return entries;
}

/// The scenes and step counts of the table: every built-in scene and every example file,
/// each stepped far enough to reach its contacts (the drape's cloth lands on the sphere, the
/// pile's bodies on the floor) but no farther, so the whole table runs in seconds.
std::int64_t stepBudget(const std::string& name) {
  if (name == "pile") return 40;
  if (name == "hanging-cloth") return 500;
  if (name == "flag-wind-pd") return 60;  // 20 global solves a step: half a second is enough
  // Implicit Euler at 1/60 s: block-Jacobi's first solve, then the multigrid (auto) on the
  // grid stencil's products, two chunks of them in double; a second is enough.
  if (name == "flag-wind-implicit") return 60;
  if (name == "flag" || name == "cloth-mesh") return 1000;
  // Self-collision: the flag's first folds touch after about 1,500 steps, the tablecloth's
  // after about 2,500 (when the cloth has left the table).
  if (name == "flag-wind") return 2000;
  if (name == "tablecloth-trick") return 3500;
  if (name == "hammock") return 5000;
  if (name == "rope-on-pegs") return 10000;
  // Self-collision: the fold has landed on itself, the upper cloth on the lower one.
  if (name == "fold" || name == "two-cloths") return 1500;
  return 2500;
}

std::vector<std::string> tableScenes() {
  std::vector<std::string> scenes = builtinSceneNames();
  std::vector<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(kSource + "/tools/scenes"))
    if (entry.path().extension() == ".json") files.push_back("file:" + entry.path().stem().string());
  std::sort(files.begin(), files.end());
  scenes.insert(scenes.end(), files.begin(), files.end());
  return scenes;
}

SceneSpec sceneSpec(const std::string& scene) {
  if (scene.rfind("file:", 0) == 0) return readSceneFile(kSource + "/tools/scenes/" + scene.substr(5) + ".json");
  return builtinSceneSpec(scene);
}

std::string hex(std::uint64_t h) {
  char text[19];
  std::snprintf(text, sizeof text, "0x%016llx", static_cast<unsigned long long>(h));
  return text;
}

struct Outcome {
  std::string hash;
  std::int64_t steps = 0;
  std::string status;
};

template <class S>
Outcome runScene(SceneSpec spec, std::int64_t steps, int threads) {
  AssembledScene<S> assembled = assembleScene<S>(spec);
  assembled.options.threads = threads;
  Simulation<S> sim(std::move(assembled.built), assembled.options);
  const StepStatus status = sim.run(static_cast<Index>(steps));
  const RigidWorld* rigid = sim.rigidWorld();
  const std::uint64_t h = rigid ? stateHash(sim.state()) ^ rigidStateHash(rigid->state()) : stateHash(sim.state());
  return {hex(h), sim.stepCount(), stepCodeName(status.code)};
}

Outcome runScene(const std::string& scene, const std::string& precision, std::int64_t steps, int threads) {
  SceneSpec spec = sceneSpec(scene);
  return precision == "float" ? runScene<float>(spec, steps, threads) : runScene<double>(spec, steps, threads);
}

std::int64_t tableSteps(const std::string& scene) {
  const std::string name = scene.rfind("file:", 0) == 0 ? scene.substr(5) : scene;
  return std::min(sceneStepCount(sceneSpec(scene)), stepBudget(name));
}

// ---------------------------------------------------------------------------------------

TEST(StateHashTable, ListsEveryBuiltInSceneAndEveryExampleFileInFloatAndDouble) {
  std::vector<std::string> fingerprints;
  const std::vector<Entry> entries = readTable(buildFingerprint(), fingerprints);
  ASSERT_FALSE(fingerprints.empty()) << "state_hashes.txt holds no table";
  if (entries.empty()) GTEST_SKIP() << "no table recorded for this build (" << buildFingerprint() << ")";
  std::vector<std::string> listed;
  for (const Entry& e : entries) listed.push_back(e.scene + " " + e.precision);
  std::vector<std::string> expected;
  for (const std::string& s : tableScenes())
    for (const char* p : {"float", "double"}) expected.push_back(s + " " + p);
  std::sort(listed.begin(), listed.end());
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(listed, expected) << "a new scene or example file needs its line: record the table again";
}

class StateHash : public ::testing::TestWithParam<std::string> {};

TEST_P(StateHash, IsTheRecordedOneOnOneAndTwoThreadsInFloatAndDouble) {
  const std::string scene = GetParam();
  const std::int64_t steps = tableSteps(scene);
  const std::string fingerprint = buildFingerprint();
  const bool record = std::getenv("WEFT_RECORD_STATE_HASHES") != nullptr;
  std::vector<std::string> fingerprints;
  const std::vector<Entry> entries = record ? std::vector<Entry>{} : readTable(fingerprint, fingerprints);
  // (Skipped before stepping: sanitizer builds have no table and would spend minutes here.)
  if (!record && entries.empty())
    GTEST_SKIP() << "no table recorded for this build (" << fingerprint
                 << "); recorded builds: " << ::testing::PrintToString(fingerprints)
                 << ". Record one with WEFT_RECORD_STATE_HASHES=1 (see the top of this file).";
  for (const char* precision : {"float", "double"}) {
    SCOPED_TRACE(scene + " in " + precision + ", " + std::to_string(steps) + " steps");
    const Outcome one = runScene(scene, precision, steps, 1);
    const Outcome two = runScene(scene, precision, steps, 2);
    EXPECT_EQ(one.hash, two.hash) << "1 and 2 threads differ";
    EXPECT_EQ(one.steps, two.steps);
    if (record) {
      std::cout << "RECORD " << scene << " " << precision << " " << one.steps << " " << one.hash << " " << one.status
                << "\n";
      continue;
    }
    const Entry* recorded = nullptr;
    for (const Entry& e : entries)
      if (e.scene == scene && e.precision == precision) recorded = &e;
    ASSERT_NE(recorded, nullptr) << "no line for it in state_hashes.txt";
    EXPECT_EQ(recorded->steps, steps) << "the table was recorded with another step count";
    EXPECT_EQ(one.hash, recorded->hash) << "the scene's result changed (status " << one.status << " after " << one.steps
                                        << " steps; recorded " << recorded->status << ")";
    EXPECT_EQ(one.status, recorded->status);
  }
}

INSTANTIATE_TEST_SUITE_P(Scenes, StateHash, ::testing::ValuesIn(tableScenes()), [](const auto& info) {
  std::string name = info.param;
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
});

}  // namespace
