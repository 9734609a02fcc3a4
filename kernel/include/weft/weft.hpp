// weft/weft.hpp — the embedding API in one include.
#pragma once

#include "weft/collide/bvh.hpp"
#include "weft/collide/obstacles.hpp"
#include "weft/collide/shapes.hpp"
#include "weft/core/kinematic_path.hpp"
#include "weft/core/parallel.hpp"
#include "weft/core/state.hpp"
#include "weft/effects/effects.hpp"
#include "weft/effects/spring_jacobian.hpp"
#include "weft/io/frames.hpp"
#include "weft/model/builder.hpp"
#include "weft/model/builders.hpp"
#include "weft/model/cloth_mesh.hpp"
#include "weft/model/triangle_mesh.hpp"
#include "weft/scene/builtin_scenes.hpp"
#include "weft/scene/fixed_step_clock.hpp"
#include "weft/scene/simulation.hpp"
