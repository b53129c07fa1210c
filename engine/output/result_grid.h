#pragma once
// The simulation result as a ParaView grid: deformed positions, displacement,
// velocity (point data) and von Mises stress (cell data).
#include "engine/mesh/mesh_io.h"
#include "engine/model/model.h"
#include "engine/dynamics/state.h"

namespace incise {

VtuGrid result_grid(const Model& model, const State& state);

}  // namespace incise
