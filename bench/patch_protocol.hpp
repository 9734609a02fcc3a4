// The protocol of the cloth-peer comparison (BM_Patch_* in bench_patch.cpp, weft's
// integrators, and BM_Peer_Bullet_Cloth in bench_peer_bullet_cloth.cpp, Bullet's soft body):
// the 1 m, 128² patch of weft's flag (weft::makeFlag: two corners of its first row pinned,
// gravity -9.81 m/s² along y) advanced in frames of dt = 1/600 s from rest, for one span of
// kSpanFrames frames (0.5 s simulated: the free edge falls and swings through the bottom of
// its first swing, where the springs carry the most). A benchmark iteration is one frame; the
// iteration count is fixed to the span, so each repetition times the same frames from rest.
// After every frame, outside the timing, the stretch of the structural springs
// (weft::stretch: |x_a - x_b| / rest - 1) is sampled; the counters are
//   max_stretch   the largest stretch of any structural spring in any frame of the span
//   mean_stretch  the mean over the span's frames of the mean structural stretch
//   end_max_stretch, end_mean_stretch  the same at the span's last frame
//   wall_s_per_sim_s  wall seconds per simulated second (time per frame / the frame's length)
#pragma once

#include <benchmark/benchmark.h>

#include <algorithm>

#include "weft/weft.hpp"

namespace weftbench {

inline constexpr weft::Index kPatchSize = 128;
inline constexpr double kPatchFrame = 1.0 / 600;  // s
inline constexpr int kSpanFrames = 300;           // 0.5 s

/// The stretch samples of one span.
class StretchSeries {
 public:
  void add(const weft::Stretch& s) {
    peak_ = frames_ == 0 ? s.max : std::max(peak_, s.max);
    meanSum_ += s.mean;
    ++frames_;
    last_ = s;
  }
  /// Counters max_stretch, mean_stretch, end_max_stretch, end_mean_stretch, wall_s_per_sim_s
  /// (a benchmark iteration being one frame of `frame` s) and frames.
  void report(benchmark::State& st, double frame = kPatchFrame) const {
    st.counters["max_stretch"] = peak_;
    st.counters["mean_stretch"] = frames_ ? meanSum_ / frames_ : 0.0;
    st.counters["end_max_stretch"] = last_.max;
    st.counters["end_mean_stretch"] = last_.mean;
    st.counters["frames"] = frames_;
    st.counters["wall_s_per_sim_s"] =
        benchmark::Counter(frame, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  }

 private:
  double peak_ = 0, meanSum_ = 0;
  int frames_ = 0;
  weft::Stretch last_;
};

}  // namespace weftbench
