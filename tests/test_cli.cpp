// tests/test_cli.cpp — the `weft` command line, run as a separate process (support/cli_runner.hpp).
// WEFT_CLI_PATH is the binary's path, given by CMake ($<TARGET_FILE:weft_cli>).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <weft/io/scene.hpp>

#include "../tools/weft/process_memory.hpp"
#include "support/cli_runner.hpp"
#include "support/sanitizers.hpp"
#include "support/test_support.hpp"

#ifndef WEFT_CLI_PATH
#error "WEFT_CLI_PATH must name the weft binary"
#endif

namespace weft::test {
namespace {

/// Runs `weft <args>`; `out` is stdout, or stdout and stderr when mergeStderr.
CliRun weft(const std::string& args, bool mergeStderr) {
  return runProgram(WEFT_CLI_PATH, args, mergeStderr ? Stderr::Merge : Stderr::Discard);
}

nlohmann::json runJson(const std::string& args) {
  const CliRun r = weft(args + " --json", false);
  EXPECT_EQ(r.exitCode, 0) << "weft " << args << " --json\n" << r.out;
  try {
    // The whole of stdout must be exactly one JSON value.
    return nlohmann::json::parse(r.out);
  } catch (const std::exception& e) {
    ADD_FAILURE() << "stdout is not one JSON document (" << e.what() << "):\n" << r.out;
    return {};
  }
}

TEST(Cli, JsonSummaryHasTheDocumentedKeys) {
  const nlohmann::json j = runJson("run flag --steps 20");
  ASSERT_TRUE(j.is_object()) << j.dump();
  for (const char* key :
       {"scene", "particles", "springs", "integrator", "precision", "threads", "steps", "dt", "wall_seconds",
        "steps_per_second", "spring_evals_per_second", "status", "state_hash", "max_stretch", "mean_stretch"})
    EXPECT_TRUE(j.contains(key)) << "missing key " << key << " in " << j.dump();
  if (testing::Test::HasFailure()) return;

  // The defaults: the 64 x 64 flag, RK4, double, all cores, the scene's time step.
  const ClothGridSpec spec = flagSpec(64);
  const auto counts = expectedGridSpringCounts(spec);
  EXPECT_EQ(j["scene"], "flag");
  EXPECT_EQ(j["particles"], 64 * 64);
  EXPECT_EQ(j["springs"], counts[0] + counts[1] + counts[2]);
  EXPECT_EQ(j["integrator"], "rk4");
  EXPECT_EQ(j["precision"], "double");
  EXPECT_GE(j["threads"].get<int>(), 1);
  EXPECT_EQ(j["steps"], 20);
  EXPECT_DOUBLE_EQ(j["dt"].get<double>(), defaultTimeStep(BuiltinScene::Flag, 64));
  EXPECT_GE(j["wall_seconds"].get<double>(), 0.0);
  EXPECT_GE(j["steps_per_second"].get<double>(), 0.0);
  EXPECT_GE(j["spring_evals_per_second"].get<double>(), 0.0);
  EXPECT_EQ(j["status"], "ok");
  const std::string hash = j["state_hash"].get<std::string>();
  EXPECT_TRUE(hash.size() == 18 && hash.rfind("0x", 0) == 0 &&
              hash.find_first_not_of("0123456789abcdef", 2) == std::string::npos)
      << "state_hash is not 0x and 16 hex digits: " << hash;
}

TEST(Cli, OptionsAreReflectedInTheSummary) {
  const nlohmann::json j = runJson(
      "run rope --size 20 --steps 7 --dt 1e-4 --integrator midpoint --precision float "
      "--threads 1 --strategy coloured");
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j["scene"], "rope");
  EXPECT_EQ(j["particles"], 20);
  EXPECT_EQ(j["springs"], 19 + 18);
  EXPECT_EQ(j["integrator"], "midpoint");
  EXPECT_EQ(j["precision"], "float");
  EXPECT_EQ(j["threads"], 1);
  EXPECT_EQ(j["steps"], 7);
  EXPECT_DOUBLE_EQ(j["dt"].get<double>(), 1e-4);
  EXPECT_EQ(j["status"], "ok");
}

TEST(Cli, WorkPerStepReportsTheAdaptiveAndImplicitCounters) {
  const nlohmann::json a = runJson("run flag --size 16 --steps 5 --dt 0.004 --integrator rk45 --rtol 1e-5 --atol 1e-7");
  ASSERT_TRUE(a.is_object());
  EXPECT_EQ(a["status"], "ok");
  const auto& w = a["work_per_step"];
  for (const char* key : {"force_evaluations", "substeps", "rejected_substeps", "linear_iterations",
                          "linear_unconverged", "max_linear_residual", "max_error_estimate"})
    EXPECT_TRUE(w.contains(key)) << key << " missing in " << w.dump();
  EXPECT_GT(w["substeps"].get<double>(), 1.0) << "dt 4 ms is far above the flag's explicit limit: substeps";
  EXPECT_LE(w["max_error_estimate"].get<double>(), 1.0);
  EXPECT_NEAR(a["work_total"]["force_evaluations"].get<double>(),
              6 * (a["work_total"]["substeps"].get<double>() + a["work_total"]["rejected_substeps"].get<double>()) + 1,
              0.5);

  const nlohmann::json i = runJson("run flag --size 16 --steps 5 --dt 0.01 --integrator implicit --cg-tolerance 1e-8");
  ASSERT_TRUE(i.is_object());
  EXPECT_EQ(i["status"], "ok");
  EXPECT_TRUE(i["stable_dt_estimate"].is_null()) << "implicit Euler has no stability limit: " << i.dump();
  EXPECT_EQ(i["work_per_step"]["force_evaluations"], 1.0);
  EXPECT_GT(i["work_per_step"]["linear_iterations"].get<double>(), 0.0);
  EXPECT_LE(i["work_per_step"]["max_linear_residual"].get<double>(), 1e-8);
  // The steps the multigrid preconditioned: all five when named; with the default, auto,
  // the one that followed block-Jacobi's 62-iteration second step (the multigrid's solve
  // then cost more than that, and the steps went back to block-Jacobi).
  EXPECT_EQ(i["work_total"]["multigrid_solves"], 1.0) << i.dump();
  EXPECT_EQ(i["work_per_step"]["multigrid_solves"], 0.2) << i.dump();
  const nlohmann::json m = runJson(
      "run flag --size 16 --steps 5 --dt 0.01 --integrator implicit --cg-tolerance 1e-8 --cg-preconditioner multigrid");
  EXPECT_EQ(m["work_total"]["multigrid_solves"], 5.0) << m.dump();

  const nlohmann::json p = runJson("run flag --size 16 --steps 5 --dt 0.01 --integrator projective --pd-iterations 7");
  ASSERT_TRUE(p.is_object());
  EXPECT_EQ(p["status"], "ok");
  EXPECT_TRUE(p["stable_dt_estimate"].is_null()) << "projective dynamics has no stability limit: " << p.dump();
  EXPECT_EQ(p["work_per_step"]["force_evaluations"], 1.0);
  EXPECT_EQ(p["work_per_step"]["linear_iterations"], 7.0);
  EXPECT_EQ(p["work_total"]["factorizations"], 1) << "one step size, one factorisation";
}

TEST(Cli, StudyWritesItsTablesWithEveryIntegratorAndAgreesAcrossThreads) {
  const std::string dir = ::testing::TempDir() + "weft_study_test";
  const CliRun r = weft("study --quick --scene oscillator --threads 1 2 --no-plot --out " + dir, false);
  ASSERT_EQ(r.exitCode, 0) << r.out;
  std::ifstream csv(dir + "/study.csv");
  ASSERT_TRUE(csv.good());
  std::string header, line;
  std::getline(csv, header);
  for (const char* column : {"scene", "integrator", "precision", "threads", "dt", "tolerance", "error", "energy_drift",
                             "wall_per_simulated_second", "stable_dt_measured", "stable_dt_estimate", "status",
                             "bitwise_same_as_first_thread_count"})
    EXPECT_NE(header.find(column), std::string::npos) << column;
  std::set<std::string> integrators;
  int rows = 0;
  while (std::getline(csv, line)) {
    ++rows;
    integrators.insert(line.substr(line.find(',') + 1, line.find(',', line.find(',') + 1) - line.find(',') - 1));
    EXPECT_EQ(line.back(), '1') << "1 and 2 threads differ: " << line;
  }
  EXPECT_EQ(integrators.size(), std::size(kAllIntegrators)) << rows << " rows";
  std::ifstream md(dir + "/study.md");
  std::stringstream text;
  text << md.rdbuf();
  EXPECT_NE(text.str().find("Cheapest run reaching each error"), std::string::npos);
  EXPECT_NE(text.str().find("bitwise identical across thread counts: yes"), std::string::npos);
}

TEST(Cli, StateHashMatchesTheLibrary) {
  // The same run in this process: the command line adds nothing to the physics.
  const nlohmann::json j = runJson("run flag --size 24 --steps 15 --threads 2");
  ASSERT_TRUE(j.is_object());
  SimulationOptions options;
  options.dt = defaultTimeStep(BuiltinScene::Flag, 24);
  options.threads = 1;
  Simulation<double> sim(makeFlag<double>(24), options);
  ASSERT_TRUE(sim.run(15).ok());
  char expected[19];
  std::snprintf(expected, sizeof expected, "0x%016llx", static_cast<unsigned long long>(stateHash(sim.state())));
  EXPECT_EQ(j["state_hash"], expected);
}

TEST(Cli, StretchIsTheLibrarysOverTheStructuralSprings) {
  // The flag sagging under gravity for 0.06 s: its structural springs stretch. The summary's
  // max_stretch and mean_stretch are weft::stretch of the same run's end state.
  const nlohmann::json j = runJson("run flag --size 24 --steps 300 --threads 2");
  ASSERT_TRUE(j.is_object());
  ASSERT_TRUE(j.contains("max_stretch") && j.contains("mean_stretch")) << j.dump();
  SimulationOptions options;
  options.dt = defaultTimeStep(BuiltinScene::Flag, 24);
  options.threads = 1;
  Simulation<double> sim(makeFlag<double>(24), options);
  ASSERT_TRUE(sim.run(300).ok());
  const Stretch expected = stretch(sim.model(), sim.state());
  EXPECT_EQ(expected.springs, sim.model().springCountByClass()[0]);
  EXPECT_GT(expected.max, 0.0);
  EXPECT_GT(expected.max, expected.mean);
  // JSON prints doubles in full (shortest round trip).
  EXPECT_EQ(j["max_stretch"].get<double>(), expected.max);
  EXPECT_EQ(j["mean_stretch"].get<double>(), expected.mean);

  // In the text summary too; a scene without structural springs (rigid bodies only) has null.
  const CliRun text = weft("run flag --size 8 --steps 5", false);
  EXPECT_NE(text.out.find("  stretch      max "), std::string::npos) << text.out;
  const nlohmann::json pile = runJson("run stack --steps 1");
  ASSERT_TRUE(pile.is_object());
  EXPECT_TRUE(pile["max_stretch"].is_null()) << pile.dump();
  EXPECT_TRUE(pile["mean_stretch"].is_null()) << pile.dump();
}

TEST(Cli, RigidBodiesLetIntoEachOtherGiveAWarningNotABareOk) {
  const nlohmann::json fine = runJson("run stack --steps 30");
  ASSERT_TRUE(fine.is_object());
  EXPECT_EQ(fine["status"], "ok");
  EXPECT_EQ(fine["warnings"], nlohmann::json::array()) << fine.dump();
  EXPECT_LT(fine["body_deepest_share_run"].get<double>(), 0.05);

  const nlohmann::json broken = runJson("run stack --steps 20 --dt 0.5");
  ASSERT_TRUE(broken.is_object());
  EXPECT_EQ(broken["status"], "ok") << "the run goes on: nothing is NaN";
  ASSERT_EQ(broken["warnings"].size(), 1u) << broken.dump();
  const std::string w = broken["warnings"][0];
  for (const char* part :
       {"rigid bodies ", " m into each other in the step, or the part of one, starting at t = ",
        "x the thinner piece's inner radius (0.25 m)", "Reduce dt (now 0.5 s)", "--time-of-impact rollback"})
    EXPECT_NE(w.find(part), std::string::npos) << part << "\n" << w;
  EXPECT_GT(broken["body_deepest_share_run"].get<double>(), 0.5);

  const CliRun text = weft("run stack --steps 20 --dt 0.5", true);
  EXPECT_EQ(text.exitCode, 0);
  EXPECT_NE(text.out.find("weft run: warning: rigid bodies "), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("  status       ok, with 1 warning (on standard error)"), std::string::npos) << text.out;
}

TEST(Cli, StateHashIsTheSameForOneAndTwoThreads) {
  for (const IntegratorKind kind : kAllIntegrators)
    for (const char* precision : {"float", "double"}) {
      const std::string args = std::string("run flag --size 40 --steps 10 --precision ") + precision +
                               " --integrator " + integratorName(kind);
      SCOPED_TRACE(args);
      const nlohmann::json one = runJson(args + " --threads 1");
      const nlohmann::json two = runJson(args + " --threads 2");
      ASSERT_TRUE(one.is_object() && two.is_object());
      EXPECT_EQ(one["threads"], 1);
      EXPECT_EQ(two["threads"], 2);
      EXPECT_EQ(one["status"], "ok");
      EXPECT_EQ(one["state_hash"], two["state_hash"]);
    }
  for (const char* strategy : {"gather", "coloured"}) {
    const std::string args = std::string("run flag --size 40 --steps 10 --strategy ") + strategy;
    SCOPED_TRACE(args);
    EXPECT_EQ(runJson(args + " --threads 1")["state_hash"], runJson(args + " --threads 2")["state_hash"]);
  }
}

TEST(Cli, StabilityFailureExitsWithThreeAndNamesTheParticle) {
  const CliRun r = weft("run flag --size 16 --integrator euler --dt 0.01 --steps 100 --json", false);
  EXPECT_EQ(r.exitCode, 3) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out, nullptr, false);
  ASSERT_TRUE(j.is_object()) << r.out;
  EXPECT_NE(j["status"], "ok");
  EXPECT_LT(j["steps"].get<int>(), 100);
  ASSERT_TRUE(j.contains("status_message"));
  EXPECT_NE(j["status_message"].get<std::string>().find("particle"), std::string::npos) << j["status_message"];
}

TEST(Cli, SceneEffectsAndTheirTimesAreReported) {
  // A scene without effects lists none; flag-wind and hanging-cloth list theirs, each
  // with the CPU time spent in it (flag-wind keeps its folds apart with self-collision).
  const nlohmann::json plain = runJson("run flag --size 8 --steps 5");
  ASSERT_TRUE(plain.is_object());
  EXPECT_EQ(plain["effects"], nlohmann::json::array());
  EXPECT_EQ(plain["effect_cpu_seconds"], nlohmann::json::object());
  EXPECT_EQ(plain["triangles"], 2 * 7 * 7);
  const nlohmann::json wind = runJson("run flag-wind --size 10 --steps 50 --threads 2");
  ASSERT_TRUE(wind.is_object());
  EXPECT_EQ(wind["status"], "ok");
  EXPECT_EQ(wind["effects"], (nlohmann::json{"drag", "wind", "self_collision"}));
  EXPECT_GT(wind["effect_cpu_seconds"]["wind"].get<double>(), 0);
  const nlohmann::json hanging = runJson("run hanging-cloth --size 10 --steps 50");
  ASSERT_TRUE(hanging.is_object());
  EXPECT_EQ(hanging["status"], "ok");
  EXPECT_EQ(hanging["effects"], (nlohmann::json{"drag", "repulsion", "kinematic_pins"}));
  for (const char* e : {"drag", "repulsion", "kinematic_pins"})
    EXPECT_TRUE(hanging["effect_cpu_seconds"].contains(e)) << e;
}

TEST(Cli, CollisionScenesReportContactsPenetrationRollbacksAndTunnelling) {
  // fast-ball: a small cloth at 100 m/s against a one-triangle wall with dt = 1/60 s:
  // nothing tunnels. drape, drape-mesh and rope-on-pegs: shortened runs, bitwise the same on 1 and 2
  // threads, with the collision keys and its CPU time. Scenes without obstacles have no keys.
  const nlohmann::json ball = runJson("run fast-ball");
  ASSERT_TRUE(ball.is_object());
  EXPECT_EQ(ball["status"], "ok");
  EXPECT_EQ(ball["tunnelled"], 0);
  EXPECT_GT(ball["contacts"].get<int>(), 0);
  EXPECT_EQ(ball["effects"], (nlohmann::json{"collision"}));
  for (const char* scene :
       {"drape --size 16 --steps 2000", "drape-mesh --size 16 --steps 2000", "rope-on-pegs --size 32 --steps 3000"}) {
    const std::string args = std::string("run ") + scene;
    SCOPED_TRACE(args);
    const nlohmann::json one = runJson(args + " --threads 1");
    const nlohmann::json two = runJson(args + " --threads 2");
    ASSERT_TRUE(one.is_object() && two.is_object());
    EXPECT_EQ(one["status"], "ok");
    EXPECT_EQ(one["state_hash"], two["state_hash"]);
    EXPECT_GT(one["contacts"].get<int>(), 0);
    EXPECT_LE(one["max_penetration"].get<double>(), 0.0025 + 1e-9);
    EXPECT_EQ(one["tunnelled"], 0);
    EXPECT_TRUE(one.contains("rollbacks"));
    EXPECT_GT(one["effect_cpu_seconds"]["collision"].get<double>(), 0);
  }
  const nlohmann::json plain = runJson("run flag --size 8 --steps 5");
  EXPECT_FALSE(plain.contains("contacts"));
  EXPECT_FALSE(plain.contains("tunnelled"));
}

TEST(Cli, OptionsOverrideTheScene) {
  // The built-in flag-wind scene runs its own integrator and step unless told otherwise.
  const nlohmann::json j = runJson("run flag-wind --size 10 --steps 4 --dt 1e-4 --integrator midpoint --drag 0");
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j["integrator"], "midpoint");
  EXPECT_EQ(j["dt"], 1e-4);
  EXPECT_EQ(j["steps"], 4);
  EXPECT_EQ(j["effects"], (nlohmann::json{"wind", "self_collision"}));
}

// Integers are read in base 10 (CLI11 alone would read "010" as octal 8), also after white space.
TEST(Cli, IntegersWithLeadingZerosAreDecimal) {
  const nlohmann::json j = runJson("run rope --size 010 --steps ' 012' --threads 01");
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j["particles"], 10);
  EXPECT_EQ(j["steps"], 12);
  EXPECT_EQ(j["threads"], 1);
}

// A run refused while it is set up (here: frames of a scene without particles) writes no
// checkpoint, so the corrected command is not refused for a file the refused one left.
TEST(Cli, ARunRefusedAtSetUpLeavesNoCheckpoint) {
  const std::string checkpoint = ::testing::TempDir() + "weft_cli_refused.wckpt";
  std::filesystem::remove(checkpoint);
  const CliRun refused = weft(
      "run stack --steps 2 --checkpoint " + checkpoint + " --out " + ::testing::TempDir() + "weft_cli_refused_frames",
      true);
  EXPECT_EQ(refused.exitCode, 2) << refused.out;
  EXPECT_FALSE(std::filesystem::exists(checkpoint));
  const CliRun corrected = weft("run stack --steps 2 --checkpoint " + checkpoint, true);
  EXPECT_EQ(corrected.exitCode, 0) << corrected.out;
  std::filesystem::remove(checkpoint);
}

// With the stability check off nothing stops a run that blows up: it does not end "ok".
TEST(Cli, AStateThatIsNotFiniteWithTheCheckOffIsNotOk) {
  const std::string path = ::testing::TempDir() + "weft_cli_unchecked.json";
  {
    std::ofstream f(path);
    f << R"({"bodies": [{"type": "cloth_grid", "width": 8, "height": 8}],
             "integrator": "euler", "dt": 0.05, "steps": 400, "stability": {"enabled": false}})";
  }
  const CliRun r = weft("run " + path + " --json", false);
  EXPECT_EQ(r.exitCode, 3) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out, nullptr, false);
  ASSERT_TRUE(j.is_object()) << r.out;
  EXPECT_EQ(j["status"], "not_finite");
  EXPECT_EQ(j["state_finite"], false);
  EXPECT_NE(j["status_message"].get<std::string>().find("stability.enabled = false"), std::string::npos);
  EXPECT_EQ(j["steps"], 400) << "with the check off every step is taken";
  // A run that stays finite says so.
  const nlohmann::json fine = runJson("run rope --size 8 --steps 3");
  EXPECT_EQ(fine["state_finite"], true);
  // With frames or checkpoints, the run stops at the first one that would hold the state
  // that is not finite, or that its format cannot hold: every frame written is finite (a
  // glTF file refuses NaN, an OBJ file with "nan" in it breaks its readers), the frames
  // before are kept, in every format, and the run still ends with its summary, not "ok".
  for (const char* format : {"obj", "ply", "gltf", "cache"}) {
    SCOPED_TRACE(format);
    const std::string dir = ::testing::TempDir() + "weft_cli_unchecked_frames";
    std::filesystem::remove_all(dir);
    const CliRun framed = weft("run " + path + " --out " + dir + " --format " + format + " --every 10 --json", false);
    EXPECT_EQ(framed.exitCode, 3) << framed.out;
    const nlohmann::json fj = nlohmann::json::parse(framed.out, nullptr, false);
    ASSERT_TRUE(fj.is_object()) << framed.out;
    // (glTF frames are float: a coordinate past its range stops the run a frame earlier.)
    EXPECT_EQ(fj["status"], std::string(format) == "gltf" ? "frame_unwritable" : "not_finite") << fj["status_message"];
    EXPECT_LT(fj["steps"].get<int>(), 400);
    EXPECT_EQ(fj["steps"].get<int>() % 10, 0);
    EXPECT_GE(fj["frames_written"].get<int>(), 1);
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      std::ifstream in(entry.path(), std::ios::binary);
      const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      EXPECT_EQ(bytes.find("nan"), std::string::npos) << entry.path();
      EXPECT_EQ(bytes.find("inf"), std::string::npos) << entry.path();
    }
    std::filesystem::remove_all(dir);
  }
  std::filesystem::remove(path);
}

TEST(Cli, FramesOutWritesOneObjPerFrame) {
  const std::string dir = ::testing::TempDir() + "weft_cli_frames_obj";
  std::filesystem::remove_all(dir);
  const nlohmann::json j = runJson("run flag --size 8 --steps 10 --every 5 --out " + dir + " --format obj");
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j["frames_written"], 3);
  EXPECT_EQ(j["output"], dir);
  std::set<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) files.insert(entry.path().filename().string());
  EXPECT_EQ(files, (std::set<std::string>{"frame_000000.obj", "frame_000001.obj", "frame_000002.obj", "frames.json"}));
  // The record of the numbering, which --resume checks.
  std::ifstream recordFile(dir + "/frames.json");
  const nlohmann::json record = nlohmann::json::parse(recordFile);
  EXPECT_EQ(record["every"], 5);
  EXPECT_EQ(record["format"], "obj");
  EXPECT_EQ(record["scene"], "flag");
  std::ifstream last(dir + "/frame_000002.obj");
  std::string line;
  int vertices = 0, faces = 0;
  while (std::getline(last, line)) {
    vertices += line.rfind("v ", 0) == 0;
    faces += line.rfind("f ", 0) == 0;
  }
  EXPECT_EQ(vertices, 64);
  EXPECT_EQ(faces, 2 * 7 * 7);
}

// A second Ctrl-C while the step is still running stops the process at once: a step that
// does not end must not hold the run hostage. The scene: two cloths swallowed by a sphere
// of radius 1e12 m (accepted, with a warning). The first step pushes every particle out by
// 1e12 m and self-collision then meets every pair: it runs for minutes.
TEST(Cli, ASecondInterruptStopsAStepThatDoesNotEnd) {
  const std::filesystem::path dir = ::testing::TempDir() + "weft_cli_second_interrupt";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string scene = (dir / "swallowed.json").string(), err = (dir / "stderr.txt").string();
  {
    std::ofstream out(scene);
    out << R"({"name": "swallowed", "dt": 2e-4, "steps": 3, "integrator": "rk4",
      "bodies": [{"type": "cloth_grid", "width": 24, "height": 24, "origin": [-0.5, 0.5, -0.5],
                  "row_axis": [1, 0, 0], "column_axis": [0, 0, 1], "total_mass": 0.5},
                 {"type": "cloth_grid", "width": 24, "height": 24, "origin": [-0.5, 0.51, -0.5],
                  "row_axis": [1, 0, 0], "column_axis": [0, 0, 1], "total_mass": 0.5}],
      "collision": {"obstacles": [{"type": "sphere", "center": [0, 0, 0], "radius": 1e12}]},
      "self_collision": {"thickness": 0.004, "max_candidates_per_triangle": 1048576}})";
  }
  // (The limit is raised so that the step runs on: by default self-collision stops it at
  // once with too-many-candidates, SelfCollision.ACloudOfCandidatesFailsTheStepAtOnce.)
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    if (std::freopen("/dev/null", "w", stdout) == nullptr || std::freopen(err.c_str(), "w", stderr) == nullptr)
      _exit(126);
    execl(WEFT_CLI_PATH, "weft", "run", scene.c_str(), "--threads", "1", static_cast<char*>(nullptr));
    _exit(127);
  }
  const auto stderrText = [&] {
    std::ifstream in(err);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  // The start's warning is written just before the steps; then give the handler time to be
  // in place and the first step time to be well under way.
  for (int k = 0; k < 6000 && stderrText().find("inside an obstacle") == std::string::npos; ++k) usleep(10000);
  ASSERT_NE(stderrText().find("inside an obstacle"), std::string::npos) << stderrText();
  usleep(1500000);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, WNOHANG), 0) << "the run ended before any signal: " << stderrText();
  kill(pid, SIGINT);
  usleep(300000);
  if (waitpid(pid, &status, WNOHANG) == pid)  // (not this test's case: the step ended in time)
    GTEST_SKIP() << "the step ended within 0.3 s of the first signal, exit status " << status;
  kill(pid, SIGINT);
  pid_t done = 0;
  for (int k = 0; k < 3000 && (done = waitpid(pid, &status, WNOHANG)) == 0; ++k) usleep(10000);
  if (done != pid) {
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
    FAIL() << "a second SIGINT did not stop the run within 30 s";
  }
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT)
      << "exited " << (WIFEXITED(status) ? WEXITSTATUS(status) : -1) << "; " << stderrText();
}

// Ctrl-C during a run: the step in progress finishes, the frames so far and a checkpoint
// are written whole (no .tmp left), the summary says "interrupted" and the exit code is 130;
// `--resume` then reaches the bits of the run that never stopped, and numbers its frames on.
TEST(Cli, InterruptWritesACheckpointThatResumesBitForBit) {
  const std::filesystem::path dir = ::testing::TempDir() + "weft_cli_interrupt";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string checkpoint = (dir / "run.wckpt").string(), frames = (dir / "frames").string(),
                    summary = (dir / "summary.json").string();
  const std::string scene = "run drape --size 24";
  std::fflush(stdout);  // (the child must not write this process's buffered output again)
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    if (std::freopen(summary.c_str(), "w", stdout) == nullptr) _exit(126);
    execl(WEFT_CLI_PATH, "weft", "run", "drape", "--size", "24", "--steps", "100000000", "--checkpoint",
          checkpoint.c_str(), "--every", "40", "--out", frames.c_str(), "--json", static_cast<char*>(nullptr));
    _exit(127);
  }
  // The second frame says the run is stepping (with the handler in place).
  const std::string second = frames + "/frame_000001.obj";
  for (int k = 0; k < 12000 && !std::filesystem::exists(second); ++k) usleep(10000);
  ASSERT_TRUE(std::filesystem::exists(second)) << "no second frame after 120 s";
  kill(pid, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "ended by a signal: " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  EXPECT_EQ(WEXITSTATUS(status), 130);
  std::ifstream in(summary);
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["status"], "interrupted");
  EXPECT_NE(j["status_message"].get<std::string>().find("stopped by SIGINT"), std::string::npos);
  const std::int64_t stopped = j["steps"].get<std::int64_t>();
  EXPECT_GT(stopped, 0);
  EXPECT_LT(stopped, 100000000);
  EXPECT_EQ(j["frames_written"].get<std::int64_t>(), stopped / 40 + 1);
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir))
    EXPECT_NE(entry.path().extension(), ".tmp") << entry.path() << " was left half-written";

  // Resumed from the step it stopped at, to 100 steps further: as the run that never stopped.
  const std::string more = " --steps " + std::to_string(stopped + 100);
  const nlohmann::json resumed = runJson(scene + more + " --resume " + checkpoint + " --out " + frames + " --every 40");
  const nlohmann::json straight = runJson(scene + more);
  EXPECT_EQ(resumed["steps"], stopped + 100);
  EXPECT_EQ(resumed["state_hash"], straight["state_hash"]);
  EXPECT_EQ(resumed["force_evaluations"], straight["force_evaluations"]);
  EXPECT_EQ(resumed["frames_written"].get<std::int64_t>(), (stopped + 100) / 40 + 1);
  std::int64_t files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(frames)) ++files;
  EXPECT_EQ(files, (stopped + 100) / 40 + 1 + 1);  // and frames.json
  // A path that cannot be written is refused before the first step.
  const CliRun unwritable = weft("run flag --size 8 --steps 10 --checkpoint /nonexistent-dir/run.wckpt", true);
  EXPECT_EQ(unwritable.exitCode, 2);
  EXPECT_NE(unwritable.out.find("checkpoint '/nonexistent-dir/run.wckpt': cannot write"), std::string::npos)
      << unwritable.out;
  // An existing checkpoint is written over only by the run that continues it: a run started
  // afresh with the same --checkpoint is refused and leaves the file as it was.
  const auto bytes = [](const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  };
  const std::string saved = bytes(checkpoint);
  const CliRun afresh = weft(scene + " --steps 10 --checkpoint " + checkpoint, true);
  EXPECT_EQ(afresh.exitCode, 2) << afresh.out;
  EXPECT_NE(afresh.out.find("--checkpoint " + checkpoint + ": the file exists"), std::string::npos) << afresh.out;
  EXPECT_NE(afresh.out.find("--resume " + checkpoint), std::string::npos) << afresh.out;
  EXPECT_EQ(bytes(checkpoint), saved);
  // A checkpoint taken at another time step is refused, naming both (the run would count
  // its steps for one and take them at the other).
  const CliRun otherStep = weft(scene + " --dt 0.0123 --resume " + checkpoint, true);
  EXPECT_EQ(otherStep.exitCode, 2) << otherStep.out;
  EXPECT_NE(otherStep.out.find("--resume: the checkpoint '" + checkpoint + "' was written at dt = "), std::string::npos)
      << otherStep.out;
  EXPECT_NE(otherStep.out.find("this run asks for dt = 0.0123 s"), std::string::npos) << otherStep.out;
  // A checkpoint of another scene is refused, naming the file.
  const CliRun other = weft("run flag --size 24 --steps 10 --resume " + checkpoint, true);
  EXPECT_EQ(other.exitCode, 2);
  EXPECT_NE(other.out.find("checkpoint '" + checkpoint + "': written for another model"), std::string::npos)
      << other.out;
  std::filesystem::remove_all(dir);
}

// Frame k is step k x --every, also across --resume: a resumed run with another --every
// or format than the directory's record (frames.json) is refused before its first step,
// and so is one that would write over or leave a gap in frames without a record; the
// files stay as they were.
TEST(Cli, ResumedFramesContinueTheNumberingOrAreRefused) {
  const std::filesystem::path dir = ::testing::TempDir() + "weft_cli_resume_frames";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string checkpoint = (dir / "run.wckpt").string(), frames = (dir / "frames").string();
  const auto count = [&] {
    std::int64_t n = 0;
    for (const auto& entry : std::filesystem::directory_iterator(frames)) n += entry.path().extension() == ".obj";
    return n;
  };
  const nlohmann::json first =
      runJson("run flag --size 8 --steps 30 --every 10 --out " + frames + " --checkpoint " + checkpoint);
  EXPECT_EQ(first["frames_written"], 4);
  ASSERT_EQ(count(), 4);
  const std::string resume = "run flag --size 8 --steps 60 --resume " + checkpoint + " --out " + frames;
  for (const char* every : {"20", "8", "5"}) {
    const CliRun other = weft(resume + " --every " + every, true);
    EXPECT_EQ(other.exitCode, 2) << other.out;
    EXPECT_NE(other.out.find("were written as obj every 10 steps (frames.json), and this run asks for obj every " +
                             std::string(every)),
              std::string::npos)
        << other.out;
  }
  const CliRun format = weft(resume + " --every 10 --format ply", true);
  EXPECT_EQ(format.exitCode, 2) << format.out;
  EXPECT_NE(format.out.find("this run asks for ply every 10"), std::string::npos) << format.out;
  EXPECT_EQ(count(), 4) << "a refused run wrote frames";
  // Without the record (frames of an older weft), by the frames' numbers.
  std::filesystem::remove(frames + "/frames.json");
  const CliRun over = weft(resume + " --every 20", true);
  EXPECT_EQ(over.exitCode, 2) << over.out;
  EXPECT_NE(over.out.find("end at frame_000003.obj, and this run continues from step 30 and writes frame_000002.obj "
                          "next (frame k is step k x --every 20): it would write over frames"),
            std::string::npos)
      << over.out;
  const CliRun gap = weft(resume + " --every 5", true);
  EXPECT_EQ(gap.exitCode, 2) << gap.out;
  EXPECT_NE(gap.out.find("writes frame_000007.obj next (frame k is step k x --every 5): it would leave frames missing"),
            std::string::npos)
      << gap.out;
  std::ofstream(frames + "/frame_-1.ply") << "";  // (not a frame number: ignored)
  const CliRun mixed = weft(resume + " --every 10 --format ply", true);
  EXPECT_EQ(mixed.exitCode, 2) << mixed.out;
  EXPECT_NE(mixed.out.find("holds frame_000000.obj, and this run writes ply frames"), std::string::npos) << mixed.out;
  std::filesystem::remove(frames + "/frame_-1.ply");
  EXPECT_EQ(count(), 4) << "a refused run wrote frames";
  // With the --every it began with, it continues the numbering (and writes the record again).
  const nlohmann::json same = runJson(resume + " --every 10");
  EXPECT_EQ(same["frames_written"], 7);
  EXPECT_EQ(count(), 7);
  EXPECT_TRUE(std::filesystem::exists(frames + "/frames.json"));
  // From an older checkpoint (a run killed after it wrote more frames), the same frames are
  // written again: the same bits.
  const auto bytes = [](const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  };
  const std::string frame5 = bytes(frames + "/frame_000005.obj");
  const nlohmann::json again = runJson(resume + " --every 10");
  EXPECT_EQ(again["state_hash"], same["state_hash"]);
  EXPECT_EQ(bytes(frames + "/frame_000005.obj"), frame5);
  // Into an empty directory, any --every.
  const std::string fresh = (dir / "fresh").string();
  runJson("run flag --size 8 --steps 60 --resume " + checkpoint + " --out " + fresh + " --every 20");
  EXPECT_TRUE(std::filesystem::exists(fresh + "/frame_000002.obj"));
  EXPECT_TRUE(std::filesystem::exists(fresh + "/frame_000003.obj"));
  std::filesystem::remove_all(dir);
}

// Settings of a scene file that the run does not read are named on stderr and listed in
// the summary; the same settings given on the command line are refused (their tests are
// CliBadOption's rows).
TEST(Cli, SceneSettingsTheRunDoesNotReadAreNamed) {
  const std::filesystem::path dir = ::testing::TempDir() + "weft_cli_unused";
  std::filesystem::create_directories(dir);
  const std::string file = (dir / "unused.json").string();
  std::ofstream(file) << R"({"name": "unused", "dt": 0.001, "steps": 2,
    "bodies": [{"type": "rope", "particles": 5}],
    "integrator": "rk4",
    "integration": {"rtol": 1e-4, "cg_tolerance": 1e-3, "projective_iterations": 4},
    "self_collision": {}, "stability": {"enabled": false, "max_stretch": 3},
    "output": {"every": 5}})";
  const nlohmann::json j = runJson("run " + file);
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j["unused_settings"],
            (nlohmann::json{"integration.rtol applies to rk45, and this run integrates with rk4",
                            "integration.cg_tolerance applies to implicit, and this run integrates with rk4",
                            "integration.projective_iterations applies to projective, and this run integrates with rk4",
                            "self_collision applies to cloth (its triangles), and the scene 'unused' has none",
                            "stability.max_stretch applies to the stability check, and stability.enabled is false",
                            "output.every applies to frames (output.directory or --out), and this run writes none"}))
      << j["unused_settings"].dump();
  const CliRun noted = weft("run " + file, true);
  EXPECT_EQ(noted.exitCode, 0) << noted.out;
  EXPECT_NE(noted.out.find("weft run: note: integration.rtol applies to rk45, and this run integrates with rk4 (not "
                           "used)"),
            std::string::npos)
      << noted.out;
  // With the integrator that reads it, rtol is not listed; the others still are.
  const nlohmann::json rk45 = runJson("run " + file + " --integrator rk45");
  EXPECT_EQ(rk45["unused_settings"].size(), 5u) << rk45["unused_settings"].dump();
  // A scene that uses everything it sets lists nothing.
  EXPECT_EQ(runJson("run flag --size 8 --steps 2")["unused_settings"], nlohmann::json::array());
  // rk45 with fixed steps, and a frame format without frames.
  const std::string fixed = (dir / "fixed.json").string();
  std::ofstream(fixed) << R"({"name": "fixed", "dt": 0.001, "steps": 2, "bodies": [{"type": "rope", "particles": 5}],
    "integrator": "rk45", "integration": {"adaptive": false, "min_substep": 1e-9}, "output": {"format": "ply"}})";
  EXPECT_EQ(runJson("run " + fixed)["unused_settings"],
            (nlohmann::json{"integration.min_substep applies to rk45's error control, and this run takes fixed rk45 "
                            "steps (--fixed-step or integration.adaptive false)",
                            "output.format applies to frames (output.directory or --out), and this run writes none"}));
  // Rigid bodies only: the particles' settings, rollback's with speculative contacts, and
  // ofg_faces with another narrow phase.
  const std::string bodies = (dir / "bodies.json").string();
  std::ofstream(bodies) << R"({"name": "bodies", "dt": 0.01, "steps": 2, "integrator": "rk45", "precision": "float",
    "integration": {"rtol": 1e-3},
    "rigid_bodies": {"ofg_faces": 4, "max_halvings": 3, "particle_thickness": 0.01, "redo_deep_steps": false,
      "bodies": [{"motion": "static", "shapes": [{"type": "box", "half_extents": [1, 0.5, 1]}]},
                 {"shapes": [{"type": "box", "half_extents": [0.1, 0.1, 0.1]}], "position": [0, 1, 0]}]}})";
  EXPECT_EQ(runJson("run " + bodies)["unused_settings"],
            (nlohmann::json{
                "integrator applies to particles (cloth and ropes), and the scene 'bodies' has none",
                "precision applies to particles (cloth and ropes), and the scene 'bodies' has none (rigid bodies run "
                "in double)",
                "integration applies to particles (cloth and ropes), and the scene 'bodies' has none",
                "rigid_bodies.particle_contacts, particle_supports and particle_thickness applies to particles (cloth "
                "and ropes), and the scene 'bodies' has none",
                "rigid_bodies.max_halvings applies to time_of_impact \"rollback\" or redo_deep_steps, and this run "
                "has neither",
                "rigid_bodies.ofg_faces applies to narrow_phase \"ofg\", and this run uses witness"}));
  // Taking speculative steps again in halves is speculative contacts' own safeguard.
  const std::string rollback = (dir / "rollback.json").string();
  std::ofstream(rollback) << R"({"name": "rollback", "dt": 0.01, "steps": 2,
    "rigid_bodies": {"time_of_impact": "rollback", "redo_deep_steps": false,
      "bodies": [{"motion": "static", "shapes": [{"type": "box", "half_extents": [1, 0.5, 1]}]},
                 {"shapes": [{"type": "box", "half_extents": [0.1, 0.1, 0.1]}], "position": [0, 1, 0]}]}})";
  EXPECT_EQ(runJson("run " + rollback)["unused_settings"],
            (nlohmann::json{"rigid_bodies.redo_deep_steps applies to time_of_impact \"speculative\", and this run's "
                            "is rollback"}));
  // A key the file writes is named even at its default value: the user wrote it, so the
  // user expects it to act.
  const std::string defaults = (dir / "defaults.json").string();
  std::ofstream(defaults) << R"({"name": "defaults", "dt": 0.001, "steps": 2, "integrator": "rk4",
    "bodies": [{"type": "rope", "particles": 5}], "integration": {"rtol": 1e-6, "projective_iterations": 10}})";
  EXPECT_EQ(runJson("run " + defaults)["unused_settings"],
            (nlohmann::json{"integration.rtol applies to rk45, and this run integrates with rk4",
                            "integration.projective_iterations applies to projective, and this run integrates with "
                            "rk4"}));
  // Settings whose subject the scene lacks: a narrow phase with spheres only, the shape of
  // gusts in a steady wind, feature edges without continuous detection against meshes, and
  // bend springs on a rope of two particles.
  const std::string spheres = (dir / "spheres.json").string();
  std::ofstream(spheres) << R"({"name": "spheres", "dt": 0.01, "steps": 2,
    "rigid_bodies": {"narrow_phase": "exact",
      "bodies": [{"motion": "static", "shapes": [{"type": "sphere", "radius": 1}]},
                 {"shapes": [{"type": "sphere", "radius": 0.1}], "position": [0, 2, 0]}]}})";
  EXPECT_EQ(runJson("run " + spheres)["unused_settings"],
            (nlohmann::json{"rigid_bodies.narrow_phase applies to pairs of boxes and hulls, and the scene 'spheres' "
                            "has spheres only (a sphere's test is its own)"}));
  const std::string lacking = (dir / "lacking.json").string();
  std::ofstream(lacking) << R"({"name": "lacking", "dt": 0.001, "steps": 2,
    "bodies": [{"type": "rope", "particles": 2, "materials": {"bend": {"stiffness": 5}}}],
    "effects": {"wind": {"velocity": [1, 0, 0], "gust_period": 2, "seed": 1}},
    "collision": {"continuous": false, "edges": false,
      "obstacles": [{"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0]}]}})";
  EXPECT_EQ(runJson("run " + lacking)["unused_settings"],
            (nlohmann::json{
                "effects.wind.gust_period applies to gusts (effects.wind.gust_strength > 0), and this run's wind is "
                "steady",
                "effects.wind.seed applies to gusts (effects.wind.gust_strength > 0), and this run's wind is steady",
                "collision.edges applies to continuous detection against mesh obstacles, and the scene 'lacking' has "
                "no mesh obstacle",
                "bodies[0].materials.bend applies to springs between every second particle, and this rope has 2 "
                "particles"}));
  std::filesystem::remove_all(dir);
}

// Self-collision cannot undo an intersection a cloth starts with: the run warns before it
// starts, and the summary counts the pairs at the start beside those at the end.
TEST(Cli, ClothThatStartsIntersectingIsNamed) {
  const std::string path = ::testing::TempDir() + "weft_cli_crossing.json";
  std::ofstream(path) << R"({"name": "crossing", "dt": 2e-4, "steps": 2, "self_collision": {}, "bodies": [
    {"type": "cloth_grid", "width": 8, "height": 8, "origin": [-0.5, 0.5, -0.5]},
    {"type": "cloth_grid", "width": 8, "height": 8, "origin": [0, 0.5, -0.7071],
     "row_axis": [0.7071, 0, 0.7071], "column_axis": [-0.7071, 0, 0.7071]}]})";
  const CliRun r = weft("run " + path, true);
  EXPECT_EQ(r.exitCode, 0) << r.out;
  EXPECT_NE(r.out.find("weft run: warning: the cloth started with "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ok, with 1 warning"), std::string::npos) << r.out;
  const nlohmann::json j = runJson("run " + path);
  EXPECT_GT(j["intersecting_pairs_at_start"].get<int>(), 0);
  ASSERT_EQ(j["warnings"].size(), 1u) << j.dump();
  EXPECT_EQ(j["warnings"][0], "the cloth started with " + std::to_string(j["intersecting_pairs_at_start"].get<int>()) +
                                  " pairs of triangles intersecting: self-collision keeps cloth from passing through "
                                  "itself and cannot undo an intersection it starts with; move the cloths apart");
  EXPECT_EQ(runJson("run two-cloths --steps 1")["intersecting_pairs_at_start"], 0);
  std::filesystem::remove(path);
}

// A particle that starts inside an obstacle is pushed out within a step, which can tear the
// cloth around it: the run warns before it starts, and the summary has the depth.
TEST(Cli, AParticleThatStartsInsideAnObstacleIsNamed) {
  const std::string path = ::testing::TempDir() + "weft_cli_inside.json";
  std::ofstream(path) << R"({"name": "inside", "dt": 2e-4, "steps": 2,
    "bodies": [{"type": "cloth_grid", "width": 8, "height": 8, "origin": [-0.5, 0.5, -0.5]}],
    "collision": {"obstacles": [{"type": "sphere", "center": [0, 0.5, 0], "radius": 0.3}]}})";
  const CliRun r = weft("run " + path, true);
  EXPECT_EQ(r.exitCode, 0) << r.out;
  // Said before the first step, once (not again at the end), and counted in the status.
  const std::string said = "weft run: warning: a particle started ";
  const size_t at = r.out.find(said);
  EXPECT_NE(at, std::string::npos) << r.out;
  EXPECT_EQ(r.out.find(said, at + 1), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ok, with 1 warning (on standard error)"), std::string::npos) << r.out;
  const nlohmann::json inside = runJson("run " + path);
  EXPECT_GT(inside["max_penetration_at_start"].get<double>(), 0.005);
  ASSERT_EQ(inside["warnings"].size(), 1u) << inside.dump();
  EXPECT_NE(inside["warnings"][0].get<std::string>().find(
                " m inside an obstacle (beyond the collision thickness): the response pushes it out within a step and "
                "can tear the cloth around it; move the body or the obstacle"),
            std::string::npos)
      << inside["warnings"][0];
  const CliRun drape = weft("run drape --size 8 --steps 1", true);
  EXPECT_EQ(drape.out.find("note"), std::string::npos) << drape.out;
  EXPECT_EQ(drape.out.find("warning"), std::string::npos) << drape.out;
  // Deep enough that pushing the particles out overstretches the springs around them: the
  // failure names the start as the likelier cause than the time step.
  std::ofstream(path) << R"({"name": "deep", "dt": 2e-4, "steps": 2,
    "bodies": [{"type": "cloth_grid", "width": 32, "height": 32, "origin": [-0.5, 0.5, -0.5]}],
    "collision": {"obstacles": [{"type": "sphere", "center": [0, 0.5, 0], "radius": 0.4}]}})";
  const CliRun deep = weft("run " + path + " --json", false);
  EXPECT_EQ(deep.exitCode, 3) << deep.out;
  const nlohmann::json j = nlohmann::json::parse(deep.out, nullptr, false);
  ASSERT_TRUE(j.is_object()) << deep.out;
  EXPECT_EQ(j["status"], "overstretched");
  EXPECT_NE(j["status_message"].get<std::string>().find("; but the run started with a particle 0.37"),
            std::string::npos)
      << j["status_message"];
  EXPECT_NE(j["status_message"].get<std::string>().find(
                " m inside an obstacle (the warning above), the likelier cause: move the body or the obstacle first"),
            std::string::npos)
      << j["status_message"];
  std::filesystem::remove(path);
}

// Particles that went through an obstacle do not end a bare "ok": a warning says how many
// and what to change; a run that kept them out says nothing.
TEST(Cli, ParticlesThatWentThroughAnObstacleGiveAWarning) {
  const std::string path = ::testing::TempDir() + "weft_cli_tunnel.json";
  const auto write = [&](const char* continuous) {
    std::ofstream(path) << R"({"name": "tunnel", "dt": 0.01, "steps": 3,
      "bodies": [{"type": "cloth_grid", "width": 4, "height": 4, "origin": [-0.1, 0.5, -0.1],
                  "velocity": [0, -30, 0]}],
      "collision": {"continuous": )"
                        << continuous << R"(, "obstacles": [{"type": "box", "center": [0, 0, 0],
                                                            "half_extents": [1, 0.005, 1]}]}})";
  };
  write("false");
  const nlohmann::json through = runJson("run " + path);
  ASSERT_TRUE(through.is_object());
  EXPECT_EQ(through["status"], "ok");
  EXPECT_EQ(through["tunnelled"], 16);
  ASSERT_EQ(through["warnings"].size(), 1u) << through.dump();
  EXPECT_EQ(through["warnings"][0],
            "16 particles went through an obstacle over the run (they ended inside it or beyond a thin one): the "
            "detection is not continuous (collision.continuous false); turn it on");
  write("true");
  const nlohmann::json held = runJson("run " + path);
  ASSERT_TRUE(held.is_object());
  EXPECT_EQ(held["tunnelled"], 0);
  EXPECT_EQ(held["warnings"], nlohmann::json::array()) << held.dump();
  std::filesystem::remove(path);
}

// weft's own example files use every setting they write: a run of each names none (a key
// an example writes for nothing would teach users to write it too).
TEST(Cli, EveryExampleFileUsesEverySettingItWrites) {
  // (From a directory of its own: the examples that write frames write them below it.)
  const std::filesystem::path dir = ::testing::TempDir() + "weft_cli_examples";
  std::filesystem::create_directories(dir);
  const std::filesystem::path before = std::filesystem::current_path();
  std::filesystem::current_path(dir);
  int examples = 0;
  for (const auto& entry : std::filesystem::directory_iterator(std::string(WEFT_SOURCE_DIR) + "/tools/scenes")) {
    if (entry.path().extension() != ".json") continue;
    ++examples;
    const nlohmann::json j = runJson("run " + entry.path().string() + " --steps 1");
    EXPECT_TRUE(j.is_object()) << entry.path();
    if (!j.is_object()) continue;
    EXPECT_EQ(j["unused_settings"], nlohmann::json::array()) << entry.path() << ": " << j["unused_settings"].dump();
  }
  std::filesystem::current_path(before);
  std::filesystem::remove_all(dir);
  EXPECT_GE(examples, 20);
}

// What `weft soak` checks for growth: the bytes the allocator handed out, which count a
// buffer in full when it is allocated, not when its pages are first touched (resident
// memory grows then, with no allocation).
TEST(Cli, SoakCountsAllocatedBytesNotPagesFirstTouched) {
  const double heapBefore = weftcli::heapBytes();
  if (heapBefore < 0) GTEST_SKIP() << "this allocator does not say what it handed out";
  const double residentBefore = weftcli::residentBytes();
  constexpr std::size_t size = 64u << 20;
  std::unique_ptr<char[]> untouched(new char[size]);  // (new char[]: not written)
  const double heapAfter = weftcli::heapBytes();
  const double residentAfter = weftcli::residentBytes();
  EXPECT_GE(heapAfter - heapBefore, static_cast<double>(size));
  EXPECT_LT(residentAfter - residentBefore, 0.5 * static_cast<double>(size));
  std::memset(untouched.get(), 1, size);  // touched: resident now, and no more allocated
  EXPECT_GE(weftcli::residentBytes() - residentBefore, 0.9 * static_cast<double>(size));
  EXPECT_LT(weftcli::heapBytes() - heapAfter, 1 << 20);
  untouched.reset();
  EXPECT_LT(weftcli::heapBytes() - heapBefore, 1 << 20);
}

// The pile lands in the second half of a simulated second: the pages of its contact buffers,
// reserved at construction, become resident then. That is not an allocation, and the soak
// passes (it used to fail "memory grew in the second half"), with no warning (it warned of
// bodies let into each other until speculative steps that do so were taken again in halves).
TEST(Cli, SoakOfAPileLandingLateIsNotAMemoryFailure) {
  const CliRun r = weft("soak --seconds 1 --scene pile --threads 1", true);
  EXPECT_EQ(r.exitCode, 0) << r.out;
  EXPECT_NE(r.out.find("| pile | double | 60 |"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("allocated MB at 1 % -> 50 % -> end | resident MB at 1 % -> 50 % -> end | checks |"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("| pass |"), std::string::npos) << r.out;
}

// A thread count above what the machine runs is run on fewer; soak says so, in the table's
// header and on stderr, since the hashes it compares are then of fewer thread counts.
TEST(Cli, SoakSaysWhenAThreadCountRunsOnFewer) {
  const CliRun r = weft("soak --seconds 0.01 --max-steps 2 --scene rope --threads 1 1024", true);
  EXPECT_EQ(r.exitCode, 0) << r.out;
  EXPECT_NE(r.out.find("weft soak: note: --threads 1024 runs on "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(threads 1 1024 (runs "), std::string::npos) << r.out;
}

// `weft soak`, short: each scene on 1 and 2 threads, one row with the checks.
TEST(Cli, SoakRunsEachSceneOnBothThreadCountsAndChecksIt) {
  const CliRun r = weft("soak --seconds 0.05 --scene drape --scene stack --scene twist", true);
  EXPECT_EQ(r.exitCode, 0) << r.out;
  for (const char* row : {"| drape | double | 250 | 0.05 |", "| stack | double | 3 |", "| twist | double |"})
    EXPECT_NE(r.out.find(row), std::string::npos) << row << " in\n" << r.out;
  std::istringstream lines(r.out);
  int rows = 0;
  for (std::string line; std::getline(lines, line);)
    if (line.rfind("| drape", 0) == 0 || line.rfind("| stack", 0) == 0 || line.rfind("| twist", 0) == 0) {
      ++rows;
      EXPECT_NE(line.find("(all equal)"), std::string::npos) << line;
      EXPECT_NE(line.find("| pass |"), std::string::npos) << line;
    }
  EXPECT_EQ(rows, 3);
  // More simulated seconds than an int64 counts steps of: --max-steps still decides.
  const CliRun far = weft("soak --seconds 1e16 --max-steps 3 --threads 1 --scene stack", true);
  EXPECT_EQ(far.exitCode, 0) << far.out;
  EXPECT_NE(far.out.find("| stack | double | 3 |"), std::string::npos) << far.out;
  EXPECT_EQ(weft("soak --seconds 0", true).exitCode, 2);
  EXPECT_EQ(weft("soak --scene no-such-scene", true).exitCode, 2);
  // A thread count or a scene given twice would compare a run with itself: refused, naming it.
  for (const char* twice : {"soak --seconds 0.01 --threads 1 --threads 1", "soak --seconds 0.01 --threads 2 1 2",
                            "soak --seconds 0.01 --scene rope --scene rope", "study --quick --threads 1 1",
                            "study --quick --scene rope --scene rope"}) {
    const CliRun r = weft(twice, true);
    EXPECT_EQ(r.exitCode, 2) << twice << "\n" << r.out;
    const std::string what = std::string(twice).find("--scene") != std::string::npos ? "--scene rope" : "--threads ";
    EXPECT_NE(r.out.find(what), std::string::npos) << twice << "\n" << r.out;
    EXPECT_NE(r.out.find("is given twice; give each value once"), std::string::npos) << twice << "\n" << r.out;
  }
  // A table file that cannot be written is refused before the first run (no row printed);
  // the check leaves no file behind where it could write.
  const std::string missing = ::testing::TempDir() + "weft_no_such_dir/table.md";
  const CliRun unwritable = weft("soak --seconds 0.05 --threads 1 --scene stack --out " + missing, true);
  EXPECT_EQ(unwritable.exitCode, 2) << unwritable.out;
  EXPECT_NE(unwritable.out.find("--out " + missing + ": cannot write the file (No such file or directory)"),
            std::string::npos)
      << unwritable.out;
  EXPECT_EQ(unwritable.out.find("| stack"), std::string::npos) << unwritable.out;
}

TEST(Cli, FramesOutCacheHoldsEveryKthStateOfTheLibraryRun) {
  const std::string dir = ::testing::TempDir() + "weft_cli_frames_cache";
  std::filesystem::remove_all(dir);
  const nlohmann::json j = runJson("run flag --size 8 --steps 10 --every 5 --out " + dir + " --format cache");
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j["frames_written"], 3);
  FrameCacheReader<double> reader(dir + "/frames.wcache");
  ASSERT_EQ(reader.frameCount(), 3);
  ASSERT_EQ(reader.particleCount(), 64);
  State<double> frame;
  reader.read(2, frame);
  const double dt = defaultTimeStep(BuiltinScene::Flag, 8);
  EXPECT_NEAR(frame.time, 10 * dt, 1e-15);
  // The same run in this process: the last frame is its final state, bit for bit.
  SimulationOptions options;
  options.dt = dt;
  options.threads = 1;
  Simulation<double> sim(makeFlag<double>(8), options);
  ASSERT_TRUE(sim.run(10).ok());
  EXPECT_EQ(frame.time, sim.state().time);
  EXPECT_TRUE(frame.x == sim.state().x) << "the cached frame differs from the library's state";
}

/// A .glb's JSON chunk and binary chunk.
struct Glb {
  nlohmann::json json;
  std::string bin;
};

Glb readGlb(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  Glb glb;
  std::uint32_t header[5] = {};
  EXPECT_GE(bytes.size(), sizeof header);
  if (bytes.size() < sizeof header) return glb;
  std::memcpy(header, bytes.data(), sizeof header);
  EXPECT_EQ(bytes.substr(0, 4), "glTF");
  EXPECT_EQ(header[1], 2u);
  EXPECT_EQ(header[2], bytes.size());
  EXPECT_EQ(header[4], 0x4E4F534Au);  // "JSON"
  glb.json = nlohmann::json::parse(bytes.substr(20, header[3]));
  const std::size_t binAt = 20 + header[3];
  std::uint32_t bin[2] = {};
  EXPECT_GE(bytes.size(), binAt + sizeof bin);
  if (bytes.size() < binAt + sizeof bin) return glb;
  std::memcpy(bin, bytes.data() + binAt, sizeof bin);
  EXPECT_EQ(bin[1], 0x004E4942u);  // "BIN\0"
  EXPECT_EQ(binAt + 8 + bin[0], bytes.size());
  glb.bin = bytes.substr(binAt + 8, bin[0]);
  return glb;
}

/// The floats of accessor `index` (tightly packed, in the one buffer).
std::vector<float> glbFloats(const Glb& glb, int index) {
  const nlohmann::json& a = glb.json["accessors"][index];
  const nlohmann::json& v = glb.json["bufferViews"][a["bufferView"].get<int>()];
  const std::size_t count = a["count"].get<std::size_t>() * (a["type"] == "VEC3" ? 3 : 1);
  const std::size_t at = v.value("byteOffset", std::size_t{0}) + a.value("byteOffset", std::size_t{0});
  EXPECT_LE(at + 4 * count, glb.bin.size());
  std::vector<float> values(count);
  if (at + 4 * count <= glb.bin.size()) std::memcpy(values.data(), glb.bin.data() + at, 4 * count);
  return values;
}

/// The "v x y z" lines of an OBJ file.
std::vector<double> objVertices(const std::string& path) {
  std::ifstream in(path);
  std::vector<double> x;
  for (std::string line; std::getline(in, line);)
    if (line.rfind("v ", 0) == 0) {
      std::istringstream fields(line.substr(2));
      for (double value; fields >> value;) x.push_back(value);
    }
  return x;
}

// --format gltf: one run.glb; frame k (frame 0 plus target k - 1, at its animation key) is
// the k-th OBJ frame of the same run within one float rounding.
TEST(Cli, FramesOutGltfIsOneGlbThatPlaysTheRunsFrames) {
  const std::string dir = ::testing::TempDir() + "weft_cli_frames_gltf", objs = dir + "_obj";
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(objs);
  const std::string run = "run flag --size 8 --steps 10 --every 5 --threads 1 --out ";
  const nlohmann::json j = runJson(run + dir + " --format gltf");
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j["frames_written"], 3);
  std::set<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) files.insert(entry.path().filename().string());
  EXPECT_EQ(files, std::set<std::string>{"run.glb"});
  runJson(run + objs + " --format obj");
  const Glb glb = readGlb(dir + "/run.glb");
  if (testing::Test::HasFailure()) return;
  EXPECT_EQ(glb.json["asset"]["version"], "2.0");
  EXPECT_EQ(glb.json["nodes"][0]["name"], "flag");
  const nlohmann::json& primitive = glb.json["meshes"][0]["primitives"][0];
  EXPECT_EQ(primitive["mode"], 4);  // TRIANGLES
  EXPECT_EQ(glb.json["accessors"][primitive["indices"].get<int>()]["count"], 3 * 2 * 7 * 7);
  ASSERT_EQ(primitive["targets"].size(), 2u);
  const nlohmann::json& sampler = glb.json["animations"][0]["samplers"][0];
  const std::vector<float> times = glbFloats(glb, sampler["input"].get<int>());
  const double dt = defaultTimeStep(BuiltinScene::Flag, 8);
  ASSERT_EQ(times.size(), 3u);
  const std::vector<float> base = glbFloats(glb, primitive["attributes"]["POSITION"].get<int>());
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(times[k], static_cast<float>(5 * k * dt)) << "key " << k;
    char name[32];
    std::snprintf(name, sizeof name, "/frame_%06d.obj", k);
    const std::vector<double> expected = objVertices(objs + name);
    ASSERT_EQ(expected.size(), 3u * 64);
    const std::vector<float> delta =
        k == 0 ? std::vector<float>(base.size(), 0.0f) : glbFloats(glb, primitive["targets"][k - 1]["POSITION"]);
    ASSERT_EQ(delta.size(), base.size());
    for (std::size_t i = 0; i < expected.size(); ++i)
      EXPECT_NEAR(base[i] + delta[i], expected[i], 1.2e-7 * std::max(1.0, std::abs(expected[i])))
          << "frame " << k << " coordinate " << i;
  }
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(objs);
}

// More frames than one file holds is refused before the run, with the --every that fits.
TEST(Cli, GltfWithTooManyFramesIsRefusedBeforeTheRun) {
  const std::string dir = ::testing::TempDir() + "weft_cli_frames_gltf_many";
  std::filesystem::remove_all(dir);
  const CliRun r = weft("run flag --size 4 --steps 5000 --every 1 --out " + dir + " --format gltf", true);
  EXPECT_EQ(r.exitCode, 2) << r.out;
  EXPECT_NE(r.out.find("--format gltf --every 1: 5001 frames of 5000 steps, more than the 4096"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("use --every 2 or more"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir));
  // And with that --every it runs.
  const nlohmann::json j = runJson("run flag --size 4 --steps 5000 --every 2 --out " + dir + " --format gltf");
  EXPECT_EQ(j["frames_written"], 2501);
  EXPECT_TRUE(std::filesystem::exists(dir + "/run.glb"));
  std::filesystem::remove_all(dir);
}

struct BadOption {
  const char* args;
  const char* option;  // what the message must name
  const char* value;
};

class CliBadOption : public ::testing::TestWithParam<BadOption> {};

TEST_P(CliBadOption, ExitsNonZeroNamingTheOptionAndTheValue) {
  const BadOption& bad = GetParam();
  const CliRun r = weft(std::string("run ") + bad.args + " --steps 1", true);
  EXPECT_EQ(r.exitCode, 2) << "bad input exits 2 (README)\n" << r.out;
  EXPECT_NE(r.out.find(bad.option), std::string::npos) << "message does not name " << bad.option << ":\n" << r.out;
  EXPECT_NE(r.out.find(bad.value), std::string::npos) << "message does not name " << bad.value << ":\n" << r.out;
  EXPECT_EQ(r.out.find("state_hash"), std::string::npos) << "it ran anyway:\n" << r.out;
}

INSTANTIATE_TEST_SUITE_P(
    Run, CliBadOption,
    ::testing::Values(
        BadOption{"flag --integrator foo", "--integrator", "foo"}, BadOption{"moon", "scene", "moon"},
        BadOption{"flag --dt 0", "--dt", "0"}, BadOption{"flag --dt -1", "--dt", "-1"},
        BadOption{"flag --dt nan", "--dt", "nan"}, BadOption{"flag --dt 1e-3x", "--dt", "1e-3x"},
        BadOption{"flag --dt 1e-400", "--dt", "1e-400' is too small"},
        BadOption{"flag --dt 1e400", "--dt", "1e400' is too large"}, BadOption{"flag --dt 1e-320", "dt", "1e-320"},
        BadOption{"flag --resume /", "checkpoint '/'", "is a directory"},
        BadOption{"flag --integrator projective --dt 1e160", "dt", "1e+160"}, BadOption{"flag --size 1", "--size", "1"},
        BadOption{"flag --steps abc", "--steps", "abc"}, BadOption{"flag --precision half", "--precision", "half"},
        BadOption{"flag --threads -1", "--threads", "-1"},
        BadOption{"flag --strategy scatter", "--strategy", "scatter"},
        BadOption{"flag --integrator rk45 --rtol -1", "--rtol", "-1"},
        BadOption{"flag --integrator rk45 --rtol nan", "--rtol", "nan"},
        BadOption{"flag --integrator rk45 --atol 0", "--atol", "0"},
        BadOption{"flag --integrator implicit --cg-tolerance 1.5", "--cg-tolerance", "1.5"},
        BadOption{"flag --integrator implicit --cg-max-iterations 0", "--cg-max-iterations", "0"},
        BadOption{"flag --integrator implicit --cg-max-iterations 2147483648", "--cg-max-iterations", "2147483648"},
        BadOption{"flag --precision float --dt 1e39", "dt", "1e+39"},
        BadOption{"flag --integrator projective --pd-iterations 0", "--pd-iterations", "0"},
        BadOption{"flag --integrator implicit --cg-preconditioner ilu", "--cg-preconditioner", "ilu"},
        BadOption{"flag --out weft_bad_out --format vtk", "--format", "vtk"},
        BadOption{"flag --out /proc/self --format gltf", "--out /proc/self --format gltf",
                  "cannot open for writing '/proc/self/run.glb.frames.tmp'"},
        BadOption{"stack --out weft_bad_out --format gltf", "--format gltf", "the scene 'stack' has no particles"},
        BadOption{"stack --out weft_bad_out", "--out weft_bad_out", "the scene 'stack' has no particles to write"},
        BadOption{"flag --out weft_bad_out --format gltf --resume weft_no.wckpt", "--resume",
                  "cannot append to a glTF file (--format gltf)"},
        BadOption{"flag --out weft_bad_out --every 0", "--every", "0"}, BadOption{"flag --every 2", "--every", "--out"},
        BadOption{"flag --steps -5", "--steps", "must be >= 0, got -5"},
        BadOption{"flag --steps 0x10", "--steps", "must be a whole number in base 10, got 0x10"},
        BadOption{"flag --size 0b11", "--size", "must be a whole number in base 10, got 0b11"},
        BadOption{"flag --szie 32", "--szie", "did you mean --size?"},
        BadOption{"flag --time-of-impact later", "--time-of-impact", "later"},
        // Options the run would not read are refused, not ignored.
        BadOption{"flag --integrator euler --rtol 1e-3", "--rtol", "this run integrates with euler"},
        BadOption{"flag --atol 1e-3", "--atol", "this run integrates with rk4"},
        BadOption{"flag --fixed-step", "--fixed-step", "--integrator rk45"},
        BadOption{"flag --integrator rk45 --fixed-step --rtol 1e-3", "--rtol", "takes fixed rk45 steps"},
        BadOption{"flag --integrator projective --cg-tolerance 1e-3", "--cg-tolerance", "integrates with projective"},
        BadOption{"flag --cg-preconditioner multigrid", "--cg-preconditioner", "--integrator implicit"},
        BadOption{"flag --cg-max-iterations 5", "--cg-max-iterations", "--integrator implicit"},
        BadOption{"flag --integrator implicit --pd-iterations 3", "--pd-iterations", "integrates with implicit"},
        BadOption{"flag --narrow-phase ofg", "--narrow-phase", "the scene 'flag' has no rigid bodies"},
        BadOption{"drape --time-of-impact rollback", "--time-of-impact", "the scene 'drape' has no rigid bodies"},
        BadOption{"stack --ofg-faces 4", "--ofg-faces", "this run uses witness"},
        BadOption{"stack --narrow-phase ofg --ofg-faces 65", "--ofg-faces", "65"},
        BadOption{"bullet --integrator rk45", "--integrator", "the scene 'bullet' has none"},
        BadOption{"stack --cg-tolerance 1e-3", "--cg-tolerance", "particles (cloth and ropes), and the scene 'stack'"},
        BadOption{"stack --precision float", "--precision", "run in double"},
        BadOption{"pile --drag 1", "--drag", "has none"},
        BadOption{"slope --strategy gather", "--strategy", "has none"},
        BadOption{"ball-on-brick --size 4", "size", "fixed layout"}, BadOption{"bullet --size 9", "size", "got 9"},
        BadOption{"slope --size 3", "size", "fixed layout"},
        BadOption{"hammock --narrow-phase exact", "--narrow-phase", "the scene 'hammock' has spheres only"},
        BadOption{"flag rope", "unexpected argument", "rope"}),
    [](const auto& info) {
      std::string name = info.param.args;
      for (char& c : name)
        if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
      return name;
    });

TEST(Cli, MessagesAreShortAndSayWhatHappened) {
  // A range without a 300-digit bound, one "weft: " prefix, a reason for a bad --out.
  const CliRun steps = weft("run flag --steps -5", true);
  EXPECT_LT(steps.out.size(), 200u) << steps.out;
  const CliRun badOut = weft("run flag --steps 1 --out /proc/weft-no-such-dir/x", true);
  EXPECT_NE(badOut.exitCode, 0);
  EXPECT_EQ(badOut.out.find("weft: weft:"), std::string::npos) << badOut.out;
  EXPECT_NE(badOut.out.find("/proc/weft-no-such-dir/x"), std::string::npos) << badOut.out;
  const CliRun study = weft("study --quick --no-plot --out /proc/weft-no-such-dir", true);
  EXPECT_EQ(study.exitCode, 2) << study.out;
  EXPECT_NE(study.out.find("cannot create the output directory '/proc/weft-no-such-dir'"), std::string::npos)
      << study.out;
  EXPECT_EQ(study.out.find("filesystem error"), std::string::npos) << study.out;
}

TEST(Cli, MoreThreadsThanTheMachineRunsAreReportedAsRun) {
  const CliRun r = weft("run rope --steps 2 --threads 999", true);
  EXPECT_EQ(r.exitCode, 0) << r.out;
  EXPECT_EQ(r.out.find("999 thread(s)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(999 asked for: the most this machine runs)"), std::string::npos) << r.out;
}

TEST(Cli, HelpNamesEveryBuiltInSceneAndSceneFiles) {
  const CliRun r = weft("run --help", true);
  EXPECT_EQ(r.exitCode, 0);
  for (const std::string& name : builtinSceneNames()) EXPECT_NE(r.out.find(name), std::string::npos) << name;
  EXPECT_NE(r.out.find("JSON scene file"), std::string::npos);
  const CliRun top = weft("--help", true);
  EXPECT_NE(top.out.find("scene file"), std::string::npos) << top.out;
}

TEST(Cli, MemoryIsAskedForBeforeItIsTaken) {
  // A billion particles: refused with what it would need, before anything is allocated.
  const CliRun huge = weft("run flag --size 32768", true);
  EXPECT_EQ(huge.exitCode, 2) << huge.out;
  EXPECT_NE(huge.out.find("needs about"), std::string::npos) << huge.out;
  EXPECT_NE(huge.out.find("GiB (1073741824 particles"), std::string::npos) << huge.out;
  EXPECT_EQ(huge.out.find("bad_alloc"), std::string::npos) << huge.out;
  const CliRun capped = weft("run flag --size 512 --max-memory 100", true);
  EXPECT_EQ(capped.exitCode, 2) << capped.out;
  EXPECT_NE(capped.out.find("--max-memory allows 100 MiB"), std::string::npos) << capped.out;
}

TEST(Cli, MemoryEstimateIsWithinAQuarterOfThePeakForEveryBuiltInScene) {
  if (weft::test::kSanitized) GTEST_SKIP() << "a sanitizer's shadow memory and quarantine are not the program's";
  std::vector<std::string> runs;
  for (const std::string& name : builtinSceneNames()) runs.push_back(name);
  runs.push_back("flag --size 256 --integrator implicit");  // the arrays dominate, not the process
  // The preconditioners beyond block-Jacobi keep their own structures (a hierarchy, a factor).
  for (const char* p : {"multigrid", "projective"})
    for (const char* precision : {"double", "float"})
      runs.push_back(std::string("flag --size 128 --integrator implicit --cg-preconditioner ") + p + " --precision " +
                     precision);
  // The factor dominates (its bytes an entry follow the solver's storage: re-measure the
  // rates in scene_memory.cpp when that changes).
  runs.push_back("flag --size 128 --integrator projective");
  runs.push_back("flag --size 128 --integrator projective --precision float");
  for (const std::string& args : runs) {
    SCOPED_TRACE(args);
    // (The pile once its bodies have landed: the contacts' buffers fill as they touch, and
    // the estimate counts a landed pile.)
    const std::string steps = args == "pile" ? " --steps 100" : " --steps 1";
    const nlohmann::json j = runJson("run " + args + steps + " --threads 1");
    const double estimate = j.value("memory_estimate_mb", 0.0), peak = j.value("peak_rss_mb", 0.0);
    EXPECT_GT(peak, 0);
    EXPECT_NEAR(estimate / peak, 1.0, 0.25) << estimate << " MB estimated, " << peak << " MB peak";
    // The figure for a folded cloth is above it with self-collision (by 5.5 kB a triangle,
    // less where building the model is the peak) and the same without.
    bool self = false;
    for (const nlohmann::json& effect : j.value("effects", nlohmann::json::array()))
      self = self || effect == "self_collision";
    const double folded = j.value("memory_estimate_folded_mb", 0.0);
    if (self) {
      EXPECT_GT(folded, estimate);
      EXPECT_LE(folded - estimate, 5500.0 * j.value("triangles", 0) / (1024.0 * 1024.0) + 1e-6);
    } else
      EXPECT_EQ(folded, estimate);
  }
}

TEST(Cli, TheMemoryOfAClothFoldedOnItselfIsEstimatedAndWarnedOfBeforeTheRun) {
  if (weft::test::kSanitized) GTEST_SKIP() << "a sanitizer's shadow memory and quarantine are not the program's";
  // twist wrings its cloth: self-collision's candidate lists grow with the folds, past the
  // estimate for the cloth as it starts, and stay under the one for a folded cloth.
  const nlohmann::json j = runJson("run twist --steps 3000 --threads 2");
  const double estimate = j.value("memory_estimate_mb", 0.0), folded = j.value("memory_estimate_folded_mb", 0.0),
               peak = j.value("peak_rss_mb", 0.0);
  EXPECT_GT(folded, 1.5 * estimate);
  EXPECT_GT(peak, 0);
  EXPECT_LT(peak, folded) << estimate << " MB estimated, " << folded << " MB folded";
  // A limit between the two figures: the run starts and says it may not fit later.
  const int between = static_cast<int>((estimate + folded) / 2);
  const CliRun warned = weft("run twist --steps 1 --max-memory " + std::to_string(between), true);
  EXPECT_EQ(warned.exitCode, 0) << warned.out;
  EXPECT_NE(warned.out.find("once its cloth folds on itself"), std::string::npos) << warned.out;
  EXPECT_NE(warned.out.find("--max-memory allows " + std::to_string(between) + " MiB"), std::string::npos)
      << warned.out;
  // Under the first: refused, as any run that does not fit.
  const CliRun refused =
      weft("run twist --steps 1 --max-memory " + std::to_string(static_cast<int>(estimate) - 4), true);
  EXPECT_EQ(refused.exitCode, 2) << refused.out;
  // Without self-collision nothing is said.
  const CliRun flat = weft("run flag --steps 1 --max-memory " + std::to_string(between), true);
  EXPECT_EQ(flat.exitCode, 0) << flat.out;
  EXPECT_EQ(flat.out.find("folds on itself"), std::string::npos) << flat.out;
}

TEST(Cli, NoSubcommandIsAnError) {
  const CliRun r = weft("", true);
  EXPECT_NE(r.exitCode, 0) << r.out;
}

}  // namespace
}  // namespace weft::test
