// weft/effects/force_field.hpp — accelerations from springs and gravity, in parallel,
// bitwise identical for any thread count.
//
// Design note
// -----------
// a_i = w_i (sum of spring forces on i) + [w_i > 0] g, with w_i the inverse mass (0 for
// a pinned particle, whose acceleration is therefore exactly zero for any finite force).
//
// Parallel accumulation without races and without floating-point atomics. Three
// strategies, each deterministic because every particle's sum is formed in an order that
// depends only on the model (see docs/architecture.md for the measurements):
//   Gather      pass 1, per spring: f_s into an (m x 3) buffer; pass 2, per particle:
//               sum of +f_s / -f_s over the particle's springs, in the order of a CSR
//               incidence list built once. Works for any model. 2 passes.
//   Coloured    springs are greedily edge-coloured so no two springs of a colour share a
//               particle; colour by colour, each spring adds f to a and -f to b directly.
//               Any model. One pass per colour (about 12-14 on a cloth grid).
//   GridStencil regular grids only: springs fall into families with a fixed neighbour
//               offset (right, down, two diagonals, skip-right, skip-down) and uniform
//               parameters. Per chunk of rows, and per family, f is computed into a
//               window indexed by the first endpoint, with contiguous loads only; then
//               each particle of the chunk sums f_k[i] - f_k[i - offset_k] over families:
//               contiguous again, no index lists at all. Slots without a spring hold
//               zero, so no masks are needed. A chunk recomputes the springs of the two
//               rows above it (the halo, ~5% extra work at 128^2) so that its window
//               stays in L2 and chunks are independent: one pass, no barrier.
// Auto picks GridStencil for grids and Gather otherwise (the faster general strategy
// on this machine; see docs/benchmarks.md).
//
// Accelerations are handed to an AccelerationSink block by block, while they are still in
// L1: an integrator combines them into its next stage state in the same pass (no
// acceleration buffer written and read back, one parallel pass per stage instead of two).
//
// All scratch buffers are sized in the constructor, except the grid stencil's windows (one
// per thread of the executor): reserve(exec) makes those, as a Simulation does when it is
// built; otherwise the first pass does. After that, accelerations() never allocates.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "weft/core/parallel.hpp"
#include "weft/effects/effects.hpp"
#include "weft/model/model.hpp"

namespace weft {

enum class ForceStrategy { Auto, Gather, Coloured, GridStencil };
const char* forceStrategyName(ForceStrategy s);
/// Parses "auto", "gather", "coloured" (or "colored"), "grid" / "grid-stencil"; throws
/// std::invalid_argument naming the value otherwise.
ForceStrategy parseForceStrategy(const std::string& name);

/// Receives accelerations for particles [begin, begin + count) (ax[t] is particle
/// begin + t, m/s^2). Called concurrently for disjoint ranges, each particle exactly once
/// per evaluation. It must not write the positions or velocities being evaluated (other
/// blocks may still read them); it may write anything else belonging to its own range.
template <class S>
struct AccelerationSink {
  void* context = nullptr;
  void (*consume)(void* context, Index begin, Index count, const S* ax, const S* ay, const S* az) = nullptr;
  void operator()(Index begin, Index count, const S* ax, const S* ay, const S* az) const {
    consume(context, begin, count, ax, ay, az);
  }
};

/// A sink calling f(begin, count, ax, ay, az); f must outlive the sink.
template <class S, class F>
AccelerationSink<S> makeSink(F& f) {
  return {&f, [](void* c, Index begin, Index count, const S* ax, const S* ay, const S* az) {
            (*static_cast<F*>(c))(begin, count, ax, ay, az);
          }};
}

namespace detail {
template <class S>
class WindForce;
template <class S>
class Repulsion;
}  // namespace detail

/// CPU time spent in each effect's code, summed over threads (s), while profiling is on.
struct EffectTimes {
  double drag = 0;
  double wind = 0;
  double repulsion = 0;
};

template <class S>
class ForceField {
 public:
  /// `model` must outlive the ForceField. gravity in m/s^2. Throws std::invalid_argument
  /// if GridStencil is requested for a model without a grid layout, or for bad effects
  /// (naming the field and the value).
  ForceField(const Model<S>& model, ForceStrategy strategy, const Vec3d& gravity, const ParticleEffects& effects = {});
  ~ForceField();
  /// Makes the scratch that passes on `exec` will need (the grid stencil's windows, one per
  /// thread), so that no pass with at most as many threads allocates.
  void reserve(const Executor& exec);
  ForceField(const ForceField&) = delete;
  ForceField& operator=(const ForceField&) = delete;
  const ParticleEffects& effects() const { return effects_; }

  /// Time of the evaluations (s), for time-dependent effects (the wind's gusts): the
  /// Simulation sets the start of each step, an integrator the offset of each stage.
  void beginStep(double time) { stepStart_ = time_ = time; }
  void setStageOffset(double offset) { time_ = stepStart_ + offset; }
  double time() const { return time_; }

  /// Measures the CPU time of each effect (two clock reads per effect and block) while on.
  void setProfiling(bool on) { profiling_ = on; }
  EffectTimes effectTimes() const;
  /// The air velocity of the wind effect at a point and time (m/s); the mean wind is
  /// returned also when the effect is off.
  Vec3d airVelocity(const Vec3d& x, double time) const;

  /// Accelerations at positions x and velocities v (n x 3), handed to `sink` in blocks.
  void accelerations(const Vec3Array<S>& x, const Vec3Array<S>& v, const AccelerationSink<S>& sink,
                     const Executor& exec);
  /// a = accelerations at positions x and velocities v (all n x 3; a distinct from x, v).
  void accelerations(const Vec3Array<S>& x, const Vec3Array<S>& v, Vec3Array<S>& a, const Executor& exec);

  /// Largest block a sink is called with.
  static constexpr Index kSinkBlock = 256;

  ForceStrategy strategy() const { return strategy_; }
  const Model<S>& model() const { return *model_; }
  /// Colours used by the Coloured strategy (0 for the others).
  Index colourCount() const { return colouring_ ? colouring_->colourCount() : 0; }

  /// Grain sizes (items per parallel block). Fixed numbers: the block boundaries, and so
  /// the results, do not depend on the thread count.
  static constexpr Index kSpringGrain = 4096;
  static constexpr Index kParticleGrain = 1024;
  /// Particles per chunk of the GridStencil strategy (rows per chunk = this / width).
  static constexpr Index kStencilChunkParticles = 2048;

 private:
  void gatherForces(const Vec3Array<S>& x, const Vec3Array<S>& v, const AccelerationSink<S>& sink,
                    const Executor& exec);
  void colouredForces(const Vec3Array<S>& x, const Vec3Array<S>& v, const AccelerationSink<S>& sink,
                      const Executor& exec);
  void stencilForces(const Vec3Array<S>& x, const Vec3Array<S>& v, const AccelerationSink<S>& sink,
                     const Executor& exec);

  /// Passes the active effects need before the per-particle pass (wind, repulsion).
  void prepareEffects(const Vec3Array<S>& x, const Vec3Array<S>& v, const Executor& exec);
  /// Adds the active per-particle effects to a finished block of accelerations.
  void applyEffects(Index begin, Index count, const Vec3Array<S>& x, const Vec3Array<S>& v, S* ax, S* ay, S* az) const;

  const Model<S>* model_;
  ForceStrategy strategy_;
  S gx_, gy_, gz_;
  ParticleEffects effects_;
  bool anyEffect_ = false;
  S drag_ = 0;  // c, N s/m
  std::unique_ptr<detail::WindForce<S>> wind_;
  std::unique_ptr<detail::Repulsion<S>> repulsion_;
  double stepStart_ = 0, time_ = 0;
  bool profiling_ = false;
  mutable std::atomic<std::int64_t> dragNs_{0}, windNs_{0}, repulsionNs_{0};

  // Gather: per-spring forces and the CSR incidence (entry = 2 * spring + side, side 1
  // meaning the particle is endpoint b and takes -f).
  Vec3Array<S> springForce_;              // (m x 3) force on endpoint a, N
  const Incidence* incidence_ = nullptr;  // the Model's particle -> spring lists

  // Coloured: the Model's springs in colour order.
  const SpringColouring<S>* colouring_ = nullptr;
  Vec3Array<S> force_;  // (n x 3) accumulated force, N

  // GridStencil: per thread, a window of family forces for the chunk of rows it runs,
  // laid out [thread][family][axis][window slot], window slot = (row - r0 + halo) * width +
  // column.
  std::vector<S> stencilWindows_;    // N (force on the first endpoint of each spring)
  std::vector<Index> familyOffset_;  // index offset b - a of each family
  Index maxRowOffset_ = 0;           // halo rows
  Index chunkRows_ = 0;
  Index windowSize_ = 0;  // slots per family and axis
  // Windows the stencil pass on `exec` uses: 1 when it runs serially, else one per thread.
  size_t stencilWindowCount(const Executor& exec) const;
};

extern template class ForceField<float>;
extern template class ForceField<double>;

}  // namespace weft
