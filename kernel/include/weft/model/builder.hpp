// weft/model/builder.hpp — the earlier name of weft/model/model_builder.hpp (ModelBuilder),
// kept so that existing includes still compile. New code includes model_builder.hpp, or
// weft/weft.hpp.
#pragma once

#include "weft/model/model_builder.hpp"
