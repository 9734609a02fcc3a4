// BM_Scene_EffectCost: what each effect costs in an RK4 step of the 128^2 cloth (double).
//
//   effect:0  bare kernel: weft::makeFlag + Simulation, springs and gravity (the same as
//             BM_Integrator_Rk4_double/size:128)
//   effect:1  springs + gravity assembled from a SceneSpec (weft::assembleScene): must run
//             within 3% of effect:0, since a scene without effects builds the same step
//   effect:2  + viscous drag
//   effect:3  + steady wind (per-triangle drag and lift)
//   effect:4  + gusty wind (8 seeded plane waves)
//   effect:5  + universal repulsion (radius half the rest spacing)
//   effect:6  + kinematic pins (the pinned edge on a turning bar)
//   effect:7  all of them
// Each effect is added alone to the springs + gravity scene, so the differences to
// effect:1 are the effects' own costs. The cloth hangs from its top edge (the
// hanging-cloth scene's geometry); the state is reset every 400 steps so that every
// configuration times the same motion.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <map>
#include <string>

#include "collide/contact_solver.hpp"
#include "weft/io/scene.hpp"
#include "weft/weft.hpp"

namespace {

constexpr weft::Index kSize = 128;

weft::SceneSpec sceneWith(int effect) {
  weft::SceneSpec spec = weft::builtinSceneSpec("hanging-cloth", kSize);
  weft::PinSpec& bar = spec.bodies[0].pins[0];
  const weft::KinematicPath turning = *bar.path;
  bar.path.reset();
  spec.simulation.effects = {};
  spec.simulation.integrator = weft::IntegratorKind::Rk4;
  weft::ParticleEffects& e = spec.simulation.effects;
  const bool all = effect == 7;
  if (effect == 2 || all) e.drag = 1e-3;
  if (effect == 3 || effect == 4 || all) {
    e.wind.enabled = true;
    e.wind.velocity = {2, 0, 4};
    if (effect == 4 || all) e.wind.gustStrength = 1.5;
  }
  if (effect == 5 || all) {
    e.repulsion.radius = 0.5 * spec.bodies[0].grid.spacing;
    e.repulsion.stiffness = 200;
  }
  if (effect == 6 || all) bar.path = turning;
  return spec;
}

void BM_Scene_EffectCost(benchmark::State& st) {
  const int effect = static_cast<int>(st.range(0));
  weft::SceneSpec spec = sceneWith(effect);
  spec.simulation.threads = static_cast<int>(st.range(1));
  std::unique_ptr<weft::Simulation<double>> sim;
  if (effect == 0) {
    weft::SimulationOptions options;
    options.integrator = weft::IntegratorKind::Rk4;
    options.threads = spec.simulation.threads;
    options.dt = weft::defaultTimeStep(weft::BuiltinScene::Flag, kSize);
    // The same cloth and pins as the scene, built directly.
    weft::ModelBuilder<double> b;
    weft::addClothGrid(b, spec.bodies[0].grid);
    for (const weft::Index i : spec.bodies[0].pins[0].particles) b.pin(i);
    sim = std::make_unique<weft::Simulation<double>>(b.build(), options);
  } else {
    weft::AssembledScene<double> scene = weft::assembleScene<double>(spec);
    sim = std::make_unique<weft::Simulation<double>>(std::move(scene.built), scene.options);
  }
  const weft::State<double> initial = sim->state();
  std::int64_t steps = 0;
  for (auto _ : st) {
    if (!sim->step().ok() || ++steps % 400 == 0) {
      st.PauseTiming();
      sim->setState(initial);
      st.ResumeTiming();
    }
  }
  st.counters["steps_per_second"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Scene_EffectCost)
    ->ArgsProduct({{0, 1, 2, 3, 4, 5, 6, 7}, {1, 2}})
    ->ArgNames({"effect", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

// BM_Scene_Drape: one step of the built-in collision scenes once the cloth has settled,
// with the collision share of the step's CPU time.
//
//   scene:0  drape       32^2 cloth on an analytic sphere and floor (RK4, dt 2e-4)
//   scene:1  drape-mesh  the same cloth on the imported torus (1536 triangles) and floor
//
// Each instance starts from the state after 1 s of the scene (the cloth lies on the
// obstacle: every step has resting contacts), computed once per scene and precision, and
// goes back to it every 400 steps. Counters: steps_per_second, collision_share (the
// contact passes' CPU time, summed over threads, over the step's: 1 - share is the
// integrator), contacts (free particles in contact at the settled state).
template <class S>
const weft::State<S>& settledDrape(const std::string& name) {
  static std::map<std::string, weft::State<S>> cache;
  auto it = cache.find(name);
  if (it == cache.end()) {
    weft::AssembledScene<S> scene = weft::assembleScene<S>(weft::builtinSceneSpec(name));
    weft::Simulation<S> sim(std::move(scene.built), scene.options);
    sim.run(static_cast<weft::Index>(std::lround(1.0 / sim.options().dt)));
    it = cache.emplace(name, sim.state()).first;
  }
  return it->second;
}

template <class S>
void BM_Scene_Drape(benchmark::State& st) {
  const std::string name = st.range(0) == 0 ? "drape" : "drape-mesh";
  weft::SceneSpec spec = weft::builtinSceneSpec(name);
  spec.simulation.threads = static_cast<int>(st.range(1));
  spec.simulation.profileEffects = true;
  weft::AssembledScene<S> scene = weft::assembleScene<S>(spec);
  weft::Simulation<S> sim(std::move(scene.built), scene.options);
  const weft::State<S>& settled = settledDrape<S>(name);
  sim.setState(settled);
  std::int64_t steps = 0;
  const double collisionBefore = sim.effectTimes().collision;
  const auto start = std::chrono::steady_clock::now();
  for (auto _ : st) {
    if (!sim.step().ok() || ++steps % 400 == 0) {
      st.PauseTiming();
      sim.setState(settled);
      st.ResumeTiming();
    }
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  st.counters["steps_per_second"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate);
  st.counters["collision_share"] = (sim.effectTimes().collision - collisionBefore) / (wall * sim.threadCount());
  st.counters["contacts"] =
      static_cast<double>(sim.contactSolver()->countContacts(settled.x, sim.model().inverseMass(), settled.time));
}
BENCHMARK(BM_Scene_Drape<float>)
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->ArgNames({"scene", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Scene_Drape<double>)
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->ArgNames({"scene", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

// BM_Contact_Corners: the contact pass (ContactSolver::resolve) of one step of
// tools/scenes/spikes.json, a 24^2 cloth resting on nine spikes whose tips sit in the
// middle of cloth faces, with the corner pass (corners:1) and without it (corners:0).
// Both resolve the same chunk every iteration: the state after 1 s of the scene (with
// corners: the cloth held up by the spikes) and its explicit Euler step x1 = x0 + dt v
// (fresh copies of x1 and v1 each time, outside the timing). The difference is the price of
// the corner pass on a cloth in contact with corners; counters: corner_contacts and
// edge_contacts per resolve.
template <class S>
void BM_Contact_Corners(benchmark::State& st) {
  const bool corners = st.range(0) != 0;
  weft::SceneSpec spec = weft::readSceneFile(std::string(WEFT_SOURCE_DIR) + "/tools/scenes/spikes.json");
  weft::AssembledScene<S> scene = weft::assembleScene<S>(spec);
  weft::Simulation<S> settle(scene.built, scene.options);
  settle.run(static_cast<weft::Index>(std::lround(1.0 / settle.options().dt)));
  const weft::State<S>& s = settle.state();
  weft::CollisionOptions options = scene.options.collision;
  options.corners = corners;
  const weft::Model<S>& model = settle.model();
  weft::ContactSolver<S> solver(options, model.particleCount(), model.collisionEdges(), nullptr,
                                corners ? model.triangles() : weft::Triangles{});
  weft::Executor exec(static_cast<int>(st.range(1)));
  const double dt = settle.options().dt, t0 = s.time, t1 = s.time + dt;
  const weft::Vec3Array<S> x1 = s.x + static_cast<S>(dt) * s.v;
  weft::Vec3Array<S> x = x1, v = s.v;
  weft::CollisionStats found;
  for (auto _ : st) {
    st.PauseTiming();
    x = x1;
    v = s.v;
    st.ResumeTiming();
    found = solver.resolve(s.x, x, v, model.inverseMass(), t0, t1, exec);
    benchmark::DoNotOptimize(x.data());
  }
  st.counters["corner_contacts"] = static_cast<double>(found.cornerContacts);
  st.counters["edge_contacts"] = static_cast<double>(found.edgeContacts);
}
BENCHMARK(BM_Contact_Corners<float>)
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->ArgNames({"corners", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Contact_Corners<double>)
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->ArgNames({"corners", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

}  // namespace
