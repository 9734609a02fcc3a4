// The meshes of the built-in scenes, embedded in weft::io at build time from the example
// scene files' meshes (kernel/src/io/builtin_meshes.cpp.in), so that `weft run drape-mesh`
// imports exactly the file tools/scenes/drape-mesh.json names, wherever weft runs.
#pragma once

#include <string_view>

namespace weft {

/// tools/scenes/meshes/torus.obj: a torus lying flat, in cm (major radius 30, tube 10).
std::string_view builtinTorusObj();

}  // namespace weft
