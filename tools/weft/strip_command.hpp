// `weft study --strip DIR`: the flag under every integrator at the same simulated time, side
// by side in one picture (DIR/strip.png) with a Markdown key (DIR/strip.md).
#pragma once

#include <string>

namespace weftcli {

/// Runs the 24 x 24 flag (32 x 32 unless `quick`) with each integrator at the flag's
/// default dt for 0.25 s (or until the stability check stops it) and draws the end of each
/// run with one camera, framed on RK4's. A run the check stopped shows its last good state
/// in a red frame. Returns 0, or 2 when weft was built without rendering.
int writeIntegratorStrip(const std::string& directory, bool quick);

}  // namespace weftcli
