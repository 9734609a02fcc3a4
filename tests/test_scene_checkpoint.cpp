// Checkpoints (Simulation::save / load / checkpoint / restore): a run resumed from step K
// reaches bitwise the state at step N of the run that never stopped, for every built-in
// scene and every integrator, in float and double, saved on 2 threads and resumed on 1;
// a checkpoint of another model, precision, integrator, version or a damaged one is
// refused with a message saying which, and leaves the Simulation as it was.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "support/sanitizers.hpp"
#include "weft/io/scene.hpp"
#include "weft/weft.hpp"

namespace {

using namespace weft;

constexpr std::int64_t kStepDivisor = weft::test::kSanitized ? 40 : 4;  // the sanitizers are 10-20x slower

/// Steps of the resume test per scene: a quarter of test_scene_hashes' budget (enough for
/// the cloths to reach their obstacles and the bodies to touch), at least 8.
std::int64_t resumeSteps(const std::string& name) {
  std::int64_t budget = 2500;
  if (name == "pile") budget = 40;
  if (name == "hanging-cloth") budget = 500;
  if (name == "flag" || name == "flag-wind") budget = 1000;
  if (name == "fold" || name == "two-cloths") budget = 1500;
  return std::max<std::int64_t>(8, budget / kStepDivisor);
}

template <class S>
Simulation<S> build(const SceneSpec& spec, int threads) {
  AssembledScene<S> a = assembleScene<S>(spec);
  a.options.threads = threads;
  return Simulation<S>(std::move(a.built), a.options);
}

template <class S>
std::uint64_t fullHash(const Simulation<S>& sim) {
  const RigidWorld* rigid = sim.rigidWorld();
  return rigid ? stateHash(sim.state()) ^ rigidStateHash(rigid->state()) : stateHash(sim.state());
}

/// Runs `spec` K steps on 2 threads, checkpoints, runs on to N; a second Simulation built
/// on 1 thread restores the checkpoint and runs N - K: the same bits and the same counts.
template <class S>
void expectResumesBitwise(const SceneSpec& spec, std::int64_t n, const std::string& what) {
  const std::int64_t k = n / 2 + 1;
  Simulation<S> original = build<S>(spec, 2);
  ASSERT_TRUE(original.run(static_cast<Index>(k)).ok()) << what;
  const std::string bytes = original.checkpoint();
  const StepStatus end = original.run(static_cast<Index>(n - k));

  Simulation<S> resumed = build<S>(spec, 1);
  resumed.restore(bytes, what);
  EXPECT_EQ(resumed.stepCount(), k) << what;
  const StepStatus resumedEnd = resumed.run(static_cast<Index>(n - k));
  EXPECT_EQ(resumedEnd.code, end.code) << what;
  EXPECT_EQ(fullHash(resumed), fullHash(original)) << what;
  EXPECT_EQ(resumed.state().time, original.state().time) << what;
  EXPECT_EQ(resumed.stepCount(), original.stepCount()) << what;
  EXPECT_EQ(resumed.totalWork().forceEvaluations, original.totalWork().forceEvaluations) << what;
  EXPECT_EQ(resumed.totalWork().linearIterations, original.totalWork().linearIterations) << what;
  EXPECT_EQ(resumed.totalWork().rejectedSubsteps, original.totalWork().rejectedSubsteps) << what;
  EXPECT_EQ(resumed.totalCollision().contacts, original.totalCollision().contacts) << what;
  EXPECT_EQ(resumed.totalSelfCollision().contacts, original.totalSelfCollision().contacts) << what;
  if (original.rigidWorld()) {
    EXPECT_EQ(resumed.rigidWorld()->totalStats().contacts, original.rigidWorld()->totalStats().contacts) << what;
    EXPECT_EQ(resumed.rigidWorld()->totalStats().witnessHits, original.rigidWorld()->totalStats().witnessHits) << what;
  }
}

class ResumeScene : public ::testing::TestWithParam<std::string> {};

TEST_P(ResumeScene, ReachesTheSameBitsAsTheRunThatNeverStopped) {
  const std::string name = GetParam();
  const SceneSpec spec = builtinSceneSpec(name);
  const std::int64_t n = std::min<std::int64_t>(sceneStepCount(spec), resumeSteps(name));
  expectResumesBitwise<float>(spec, n, name + " float");
  expectResumesBitwise<double>(spec, n, name + " double");
}

INSTANTIATE_TEST_SUITE_P(EveryBuiltInScene, ResumeScene, ::testing::ValuesIn(builtinSceneNames()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string s = info.param;
                           for (char& c : s)
                             if (c == '-') c = '_';
                           return s;
                         });

// Every integrator, with what it carries: Verlet's acceleration, rk45's slope, proposal and
// error history (adaptive), implicit Euler's warm start.
TEST(Resume, EveryIntegratorCarriesWhatItNeeds) {
  for (const IntegratorKind kind : kAllIntegrators) {
    SceneSpec spec = builtinSceneSpec("drape", 12);
    spec.simulation.integrator = kind;
    spec.simulation.dt = kind == IntegratorKind::ImplicitEuler ? 2e-3 : 5e-4;
    const std::string what = std::string("drape ") + integratorName(kind);
    expectResumesBitwise<float>(spec, 40, what + " float");
    expectResumesBitwise<double>(spec, 40, what + " double");
  }
}

TEST(Resume, ThroughAFileLeavesNoTemporary) {
  const std::string path = ::testing::TempDir() + "weft_checkpoint_flag.wckpt";
  const SceneSpec spec = builtinSceneSpec("flag", 8);
  Simulation<double> a = build<double>(spec, 2);
  ASSERT_TRUE(a.run(7).ok());
  a.save(path);
  EXPECT_TRUE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  ASSERT_TRUE(a.run(5).ok());
  Simulation<double> b = build<double>(spec, 2);
  b.load(path);
  ASSERT_TRUE(b.run(5).ok());
  EXPECT_EQ(stateHash(b.state()), stateHash(a.state()));
  std::filesystem::remove(path);
}

/// The message of the std::runtime_error `f` throws ("" if none).
template <class F>
std::string refusal(F&& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

std::uint64_t fnv(const std::string& bytes) { return fnv1a64(bytes.data(), bytes.size()); }

/// `bytes` with its checksum recomputed (a file edited on purpose, not damaged).
std::string resealed(std::string bytes) {
  const std::uint64_t sum = fnv(bytes.substr(0, bytes.size() - 8));
  std::memcpy(bytes.data() + bytes.size() - 8, &sum, 8);
  return bytes;
}

TEST(Resume, ForeignOrDamagedCheckpointsAreRefusedAndChangeNothing) {
  const SceneSpec spec = builtinSceneSpec("flag", 8);
  Simulation<double> saved = build<double>(spec, 1);
  ASSERT_TRUE(saved.run(3).ok());
  const std::string bytes = saved.checkpoint();

  Simulation<double> target = build<double>(spec, 1);
  ASSERT_TRUE(target.run(1).ok());
  const std::uint64_t before = stateHash(target.state());
  const auto refused = [&](const std::string& b) {
    const std::string m = refusal([&] { target.restore(b, "c.wckpt"); });
    EXPECT_EQ(stateHash(target.state()), before) << "a refused checkpoint changed the simulation: " << m;
    EXPECT_EQ(target.stepCount(), 1);
    EXPECT_EQ(m.rfind("checkpoint 'c.wckpt': ", 0), 0u) << m;
    return m;
  };

  // Another precision, model or integrator.
  Simulation<float> single = build<float>(spec, 1);
  EXPECT_NE(refused(single.checkpoint()).find("written in float precision, this simulation is double"),
            std::string::npos);
  EXPECT_NE(refused(build<double>(builtinSceneSpec("flag", 9), 1).checkpoint()).find("another model"),
            std::string::npos);
  SceneSpec verlet = spec;
  verlet.simulation.integrator = IntegratorKind::VelocityVerlet;
  EXPECT_NE(refused(build<double>(verlet, 1).checkpoint())
                .find("written by the integrator verlet, this simulation "
                      "uses rk4"),
            std::string::npos)
      << refused(build<double>(verlet, 1).checkpoint());
  // Damaged: one byte changed, cut short, empty, not a checkpoint.
  std::string flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x10;
  EXPECT_NE(refused(flipped).find("damaged: the checksum"), std::string::npos);
  EXPECT_NE(refused(bytes.substr(0, bytes.size() - 100)).find("damaged"), std::string::npos);
  EXPECT_NE(refused("").find("not a weft checkpoint"), std::string::npos);
  EXPECT_NE(refused("{\"bodies\": []}").find("not a weft checkpoint"), std::string::npos);
  // Another version or format, even with a valid checksum.
  std::string version = bytes;
  const size_t at = version.find("0.1.0");
  ASSERT_NE(at, std::string::npos);
  version.replace(at, 5, "9.9.9");
  EXPECT_NE(refused(resealed(version)).find("written by weft 9.9.9"), std::string::npos) << refused(resealed(version));
  std::string format = bytes;
  format[8] = 7;
  EXPECT_NE(
      refused(resealed(format))
          .find("checkpoint format 7, this weft reads format " + std::to_string(Simulation<double>::kCheckpointFormat)),
      std::string::npos);
  // A count made up, checksum valid: refused before anything is allocated or changed.
  std::string huge = bytes;
  const std::int64_t rows = 1ll << 40;
  const size_t simu = huge.find("SIMU");
  ASSERT_NE(simu, std::string::npos);
  std::memcpy(huge.data() + simu + 4, &rows, 8);
  EXPECT_NE(refused(resealed(huge)).find("positions"), std::string::npos) << refused(resealed(huge));
  // The file API names the path.
  const std::string missing = ::testing::TempDir() + "weft_no_such_checkpoint.wckpt";
  const std::string m = refusal([&] { target.load(missing); });
  EXPECT_NE(m.find("checkpoint '" + missing + "': cannot open"), std::string::npos) << m;
  // And the original still loads.
  target.restore(bytes, "c.wckpt");
  EXPECT_EQ(stateHash(target.state()), stateHash(saved.state()));
  EXPECT_EQ(target.stepCount(), 3);
}

/// Where the section `tag` starts in a checkpoint (its first byte after the tag).
size_t sectionBody(const std::string& bytes, const char* tag) {
  const size_t at = bytes.find(tag);
  EXPECT_NE(at, std::string::npos) << tag;
  EXPECT_EQ(bytes.find(tag, at + 1), std::string::npos) << tag << " twice: the test would edit the wrong place";
  return at == std::string::npos ? 0 : at + 4;
}

template <class T>
T readAt(const std::string& bytes, size_t at) {
  T v{};
  std::memcpy(&v, bytes.data() + at, sizeof v);
  return v;
}

/// What restoring `bytes` into `target` says; the target must come out unchanged.
template <class S>
std::string refusedInto(Simulation<S>& target, const std::string& bytes) {
  const std::uint64_t before = fullHash(target);
  const std::int64_t steps = target.stepCount();
  const std::string m = refusal([&] { target.restore(bytes, "c.wckpt"); });
  EXPECT_EQ(fullHash(target), before) << "a refused checkpoint changed the simulation: " << m;
  EXPECT_EQ(target.stepCount(), steps);
  return m;
}

// A file edited so that its checksum holds but a value in it is not a number, or a list
// does not match the one it goes with: refused when loaded, not steps later.
TEST(Resume, ACheckpointWithANonFiniteCarryOrMismatchedListsIsRefused) {
  const double nan = std::nan("");
  {  // implicit Euler's warm start (the INTG section: its flag, then the n x 3 array)
    SceneSpec spec = builtinSceneSpec("flag", 8);
    spec.simulation.integrator = IntegratorKind::ImplicitEuler;
    Simulation<double> saved = build<double>(spec, 1);
    ASSERT_TRUE(saved.run(3).ok());
    std::string bytes = saved.checkpoint();
    const size_t at = sectionBody(bytes, "INTG") + 1 + 16 + 8 * 5;  // entry (5, 0)
    std::memcpy(bytes.data() + at, &nan, 8);
    Simulation<double> target = build<double>(spec, 1);
    EXPECT_EQ(refusedInto(target, resealed(bytes)),
              "checkpoint 'c.wckpt': implicit Euler's warm start: entry (5, 0) is nan, not a finite number");
  }
  {  // a kinematic pin's origin (the last vector of the SIMU section, just before INTG)
    const SceneSpec spec = builtinSceneSpec("twist", 12);
    Simulation<double> saved = build<double>(spec, 1);
    ASSERT_FALSE(saved.options().kinematicPins.empty());
    ASSERT_TRUE(saved.run(2).ok());
    std::string bytes = saved.checkpoint();
    const size_t end = sectionBody(bytes, "INTG") - 4;
    std::memcpy(bytes.data() + end - 8, &nan, 8);  // the last origin's z
    Simulation<double> target = build<double>(spec, 1);
    const std::string m = refusedInto(target, resealed(bytes));
    EXPECT_NE(m.find("kinematic pin origin"), std::string::npos) << m;
    EXPECT_NE(m.find("is not finite"), std::string::npos) << m;
  }
  {  // rigid pairs without their witness caches (the next step would read past the list)
    const SceneSpec spec = builtinSceneSpec("stack", 4);
    Simulation<double> saved = build<double>(spec, 1);
    ASSERT_TRUE(saved.run(30).ok());
    const std::string bytes = saved.checkpoint();
    const size_t n = static_cast<size_t>(saved.rigidWorld()->model().bodyCount());
    // x, q, v, w, time, the kinematic origins and orientations, then the pairs (8 bytes each).
    size_t at = sectionBody(bytes, "RIGD");
    for (const size_t entry : {24, 32, 24, 24}) at += 8 + entry * n;
    at += 8;
    for (const size_t entry : {24, 32}) at += 8 + entry * n;
    const auto pairs = readAt<std::uint64_t>(bytes, at);
    ASSERT_GT(pairs, 0u) << "the boxes should touch by now";
    at += 8 + 8 * pairs;
    ASSERT_EQ(readAt<std::uint64_t>(bytes, at), pairs) << "the layout this test assumes";
    const size_t cacheBytes = sizeof(PairCache) * pairs;
    std::string edited = bytes.substr(0, at);
    const std::uint64_t none = 0;
    edited.append(reinterpret_cast<const char*>(&none), 8);
    edited += bytes.substr(at + 8 + cacheBytes);
    Simulation<double> target = build<double>(spec, 1);
    EXPECT_EQ(refusedInto(target, resealed(edited)),
              "checkpoint 'c.wckpt': 0 witness caches for " + std::to_string(pairs) + " pairs");
    target.restore(bytes, "c.wckpt");  // the file as written still loads, and steps
    EXPECT_TRUE(target.step().ok());
  }
}

// After a failed step an integrator's carry may hold what the failure made (NaN), unused
// (its flag is off): the checkpoint of that simulation loads, and a refused file loaded
// into it puts it back as it was (the state before loading is not refused in turn).
TEST(Resume, ACheckpointAfterAFailedStepLoadsAndARefusedOneLeavesItAlone) {
  for (const IntegratorKind kind :
       {IntegratorKind::VelocityVerlet, IntegratorKind::Rk45, IntegratorKind::ImplicitEuler}) {
    SCOPED_TRACE(integratorName(kind));
    SceneSpec spec = builtinSceneSpec("flag", 8);
    spec.simulation.integrator = kind;
    Simulation<double> sim = build<double>(spec, 1);
    ASSERT_TRUE(sim.run(3).ok());
    State<double> wild = sim.state();
    wild.v(20, 1) = 2e8;  // the next step stretches a spring past the stability check
    sim.setState(wild);
    EXPECT_FALSE(sim.step().ok());
    const std::string bytes = sim.checkpoint();
    Simulation<double> other = build<double>(spec, 1);
    EXPECT_EQ(refusal([&] { other.restore(bytes, "c.wckpt"); }), "");
    EXPECT_EQ(stateHash(other.state()), stateHash(sim.state()));
    std::string damaged = bytes;
    const double nan = std::nan("");
    std::memcpy(damaged.data() + sectionBody(damaged, "SIMU") + 16, &nan, 8);  // the first position
    const std::string m = refusedInto(sim, resealed(damaged));
    EXPECT_NE(m.find("the state is not finite"), std::string::npos) << m;
  }
}

TEST(Resume, ACheckpointOfOtherSelfCollisionSettingsIsRefused) {
  // The self-collision candidates a checkpoint carries hold for the thickness, the skin and
  // the culling they were gathered with: a Simulation with other settings refuses them.
  const SceneSpec spec = builtinSceneSpec("fold", 16);
  ASSERT_TRUE(spec.simulation.selfCollision.enabled);
  Simulation<double> saved = build<double>(spec, 1);
  ASSERT_TRUE(saved.run(5).ok());
  const std::string bytes = saved.checkpoint();
  for (const bool thicker : {true, false}) {
    SceneSpec other = spec;
    if (thicker)
      other.simulation.selfCollision.thickness *= 1.5;
    else
      other.simulation.selfCollision.cullFlatRegions = !other.simulation.selfCollision.cullFlatRegions;
    Simulation<double> target = build<double>(other, 1);
    const std::uint64_t before = stateHash(target.state());
    const std::string m = refusal([&] { target.restore(bytes, "c.wckpt"); });
    EXPECT_NE(m.find("written with other self-collision settings"), std::string::npos) << m;
    EXPECT_EQ(stateHash(target.state()), before) << m;
    EXPECT_EQ(target.stepCount(), 0);
  }
  Simulation<double> same = build<double>(spec, 1);
  same.restore(bytes, "c.wckpt");
  EXPECT_EQ(stateHash(same.state()), stateHash(saved.state()));
}

}  // namespace
