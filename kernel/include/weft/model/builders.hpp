// weft/model/builders.hpp — the earlier name of weft/model/ropes_and_grids.hpp (addRope,
// addClothGrid), kept so that existing includes still compile. New code includes
// ropes_and_grids.hpp, or weft/weft.hpp.
#pragma once

#include "weft/model/ropes_and_grids.hpp"
