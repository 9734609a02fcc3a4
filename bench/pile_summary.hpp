// What a settled `pile` looks like, so that two engines' piles can be seen to be the same
// kind of state: BM_Rigid_Pile and BM_Peer_Bullet_Pile report it alike.
#pragma once

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>

namespace weftbench {

/// Over the dynamic bodies of a `pile`. The bin is pileScene's (kernel/src/scene/rigid_scenes.cpp):
/// floor top at y = 0, walls 1 m high with their inner faces at x = +-2 m and z = +-2 m.
struct PileSummary {
  int dynamicBodies = 0;
  int inBin = 0;       // centre above the floor's top, under the walls' top and within their inner faces
  int belowFloor = 0;  // centre under the floor's top (sunk into the floor or fallen through)
  double height = 0;   // sum of the centres' heights, m
  double speed = 0;    // sum of the centres' speeds, m/s
  void add(double x, double y, double z, double centreSpeed) {
    ++dynamicBodies;
    inBin += std::abs(x) < 2 && std::abs(z) < 2 && y > 0 && y < 1;
    belowFloor += y < 0;
    height += y;
    speed += centreSpeed;
  }
  double meanHeight() const { return height / std::max(dynamicBodies, 1); }
  /// Counters in_bin, below_floor, mean_height (m) and mean_speed (m/s).
  void report(benchmark::State& st) const {
    st.counters["in_bin"] = inBin;
    st.counters["below_floor"] = belowFloor;
    st.counters["mean_height"] = meanHeight();
    st.counters["mean_speed"] = speed / std::max(dynamicBodies, 1);
  }
};

}  // namespace weftbench
