// tests/support/test_support.hpp — helpers shared by the weft test executables.
//
// Scalar-type and integrator parameterisation, scalar-dependent tolerances, seeded random
// perturbations, the message of an expected exception, and the small scenes the property
// tests use (a single damped oscillator, a flag without pins). Everything is header-only so
// that each test file stays its own executable with no extra library. (What replaces global
// functions or runs programs, alloc_counter and cli_runner, is compiled in the libraries of
// this folder's CMakeLists.txt and linked by the programs that need it.)
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <type_traits>
#include <utility>

#include "weft/weft.hpp"

namespace weft::test {

// ---------------------------------------------------------------------------------------
// Scalar types
// ---------------------------------------------------------------------------------------

using ScalarTypes = ::testing::Types<float, double>;

template <class S>
constexpr const char* scalarName() {
  return std::is_same_v<S, float> ? "float" : "double";
}

// (Suites over ScalarTypes keep gtest's default names, Suite/0 and Suite/1: CMake's
// gtest_discover_tests then names the ctest entries Suite.Test<float> / <double>.)

/// Machine epsilon of S, as a double (the unit of every scalar-dependent tolerance).
template <class S>
constexpr double eps() {
  return static_cast<double>(std::numeric_limits<S>::epsilon());
}

// ---------------------------------------------------------------------------------------
// (scalar, integrator) configurations, generated from weft::kAllIntegrators so that a new
// integrator is covered by every parameterised test without touching the tests.
// ---------------------------------------------------------------------------------------

template <class S, IntegratorKind K>
struct Config {
  using Scalar = S;
  static constexpr IntegratorKind kIntegrator = K;
};

template <class Seq>
struct AllConfigsFor;
template <std::size_t... I>
struct AllConfigsFor<std::index_sequence<I...>> {
  using type = ::testing::Types<Config<float, kAllIntegrators[I]>..., Config<double, kAllIntegrators[I]>...>;
};

/// Every integrator in float and in double.
using AllConfigs = AllConfigsFor<std::make_index_sequence<std::size(kAllIntegrators)>>::type;

/// Name generator for TYPED_TEST_SUITE over AllConfigs: "float_rk4", "double_euler", ...
/// (gtest prints Suite/float_rk4.Test; the ctest entry is named
/// Suite.Test<Suite/float_rk4.  # TypeParam = ...>, so `ctest -R float_rk4` selects it.)
struct ConfigNames {
  template <class C>
  static std::string GetName(int) {
    return std::string(scalarName<typename C::Scalar>()) + "_" + integratorName(C::kIntegrator);
  }
};

/// The force strategies that apply to a cloth grid (Auto resolves to one of them).
inline constexpr ForceStrategy kGridStrategies[] = {ForceStrategy::Gather, ForceStrategy::Coloured,
                                                    ForceStrategy::GridStencil};
/// The force strategies that apply to any model.
inline constexpr ForceStrategy kGeneralStrategies[] = {ForceStrategy::Gather, ForceStrategy::Coloured};

// ---------------------------------------------------------------------------------------
// State helpers
// ---------------------------------------------------------------------------------------

template <class S>
bool allFinite(const State<S>& s) {
  return s.x.allFinite() && s.v.allFinite();
}

/// Adds uniform noise in [-amplitude, amplitude] to every coordinate of the rows of `a`
/// that `keep(i)` does not exclude. Seeded: the same call gives the same numbers.
template <class S, class Keep>
void addNoise(Vec3Array<S>& a, double amplitude, std::uint32_t seed, Keep keep) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  for (Index i = 0; i < a.rows(); ++i)
    for (int c = 0; c < 3; ++c) {
      const double d = u(rng);  // drawn for every entry, so the stream does not depend on keep
      if (keep(i)) a(i, c) = static_cast<S>(static_cast<double>(a(i, c)) + d);
    }
}

template <class S>
void addNoise(Vec3Array<S>& a, double amplitude, std::uint32_t seed) {
  addNoise<S>(a, amplitude, seed, [](Index) { return true; });
}

/// Perturbs the free particles of a model's state: positions by +-dx, velocities by +-dv.
template <class S>
void perturbFree(const Model<S>& model, State<S>& state, double dx, double dv, std::uint32_t seed) {
  const auto isFree = [&](Index i) { return !model.isPinned(i); };
  addNoise<S>(state.x, dx, seed, isFree);
  addNoise<S>(state.v, dv, seed + 1, isFree);
}

/// Total linear momentum sum m_i v_i, accumulated in long double.
template <class S>
std::array<long double, 3> momentum(const Model<S>& model, const State<S>& state) {
  std::array<long double, 3> p{0, 0, 0};
  for (Index i = 0; i < model.particleCount(); ++i)
    for (int c = 0; c < 3; ++c) p[c] += static_cast<long double>(model.mass()[i]) * state.v(i, c);
  return p;
}

// ---------------------------------------------------------------------------------------
// Exceptions
// ---------------------------------------------------------------------------------------

/// The message of the `Exception` that f() throws (fails the test if it throws none, or
/// another type).
template <class Exception>
std::string thrownMessage(const std::function<void()>& f) {
  try {
    f();
  } catch (const Exception& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "threw another exception type: " << e.what();
    return {};
  }
  ADD_FAILURE() << "no exception thrown";
  return {};
}

// ---------------------------------------------------------------------------------------
// Scenes
// ---------------------------------------------------------------------------------------

/// The damped oscillator with its exact solution (weft/scene/oscillator.hpp): the same one
/// the accuracy study runs.
using Oscillator = DampedOscillator;

/// The flag's grid (weft::flagSpec) built without pins.
template <class S>
ModelAndState<S> makeFreeFlag(Index size) {
  ModelBuilder<S> builder;
  addClothGrid(builder, flagSpec(size));
  return builder.build();
}

/// The flag scene (pinned at two corners) with every spring's damping set to zero.
template <class S>
ModelAndState<S> makeUndampedFlag(Index size) {
  ClothGridSpec spec = flagSpec(size);
  spec.structural.damping = 0;
  spec.shear.damping = 0;
  spec.bend.damping = 0;
  ModelBuilder<S> builder;
  addClothGrid(builder, spec);
  builder.pin(gridIndex(spec, 0, 0));
  builder.pin(gridIndex(spec, 0, spec.width - 1));
  return builder.build();
}

/// `sheets` triangulated (k x k)-vertex sheets 5 cm apart per vertex, side by side 2 m
/// apart and sharing no spring, each pinned at its first row's two corners: the grid's
/// connectivity without a GridLayout (the general paths, not the grid ones).
inline ModelAndState<double> makeMeshSheets(Index k, int sheets = 1) {
  ModelBuilder<double> b;
  for (int sheet = 0; sheet < sheets; ++sheet) {
    TriangleMesh mesh;
    for (Index r = 0; r < k; ++r)
      for (Index c = 0; c < k; ++c)
        mesh.vertices.push_back(Vec3d(0.05 * static_cast<double>(c) + 2.0 * sheet, 0, 0.05 * static_cast<double>(r)));
    for (Index r = 0; r + 1 < k; ++r)
      for (Index c = 0; c + 1 < k; ++c) {
        const Index a = r * k + c;
        mesh.triangles.push_back({a, a + 1, a + k + 1});
        mesh.triangles.push_back({a, a + k + 1, a + k});
      }
    ClothMeshSpec spec;
    spec.structural = {4000, 0.05};
    const Index first = b.particleCount();
    addClothMesh(b, mesh, spec);
    b.pin(first);
    b.pin(first + k - 1);
  }
  return b.build();
}

/// Options for a run of the flag scene.
inline SimulationOptions flagOptions(IntegratorKind kind, ForceStrategy strategy, int threads, double dt) {
  SimulationOptions o;
  o.integrator = kind;
  o.forceStrategy = strategy;
  o.threads = threads;
  o.dt = dt;
  return o;
}

/// The tablecloth trick (weft/scene/rigid_scenes.hpp) as a Simulation: a size x size
/// cloth on the table under two boxes and a ball, its +x edge pulled at `speed` (m/s),
/// symplectic Euler at the cloth's default step.
inline std::unique_ptr<Simulation<double>> makeTablecloth(double speed, int threads, Index size, bool supports = true) {
  ModelBuilder<double> builder;
  addClothGrid(builder, tableclothCloth(size));
  const std::vector<Index> grip = tableclothGrip(size);
  for (const Index i : grip) builder.pin(i);
  SimulationOptions options;
  options.integrator = IntegratorKind::SymplecticEuler;
  options.dt = defaultTimeStep(BuiltinScene::Flag, size);
  options.threads = threads;
  options.rigid = tableclothBodies();
  options.rigid.particleSupports = supports;
  options.kinematicPins.push_back({grip, tableclothPull(speed)});
  return std::make_unique<Simulation<double>>(builder.build(), options);
}

}  // namespace weft::test
