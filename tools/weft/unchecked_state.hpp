// tools/weft/unchecked_state.hpp — what the commands say of a state that is not finite.
#pragma once

#include <cstdint>
#include <string>

namespace weftcli {

/// With the stability check off (stability.enabled = false) nothing stops a state that
/// overflowed (weft::Simulation::stateFinite is false): run, render, soak and view say so in
/// these words instead of "ok".
inline std::string notFiniteMessage(std::int64_t step) {
  return "the state is not finite after step " + std::to_string(step) +
         " (with the stability check off, stability.enabled = false, nothing stopped the run)";
}

}  // namespace weftcli
