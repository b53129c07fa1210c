#pragma once
// The cut a scalpel makes: in each frame its cutting edge moves from its pose
// at the frame's start to its pose at the end; the band it sweeps, where it
// passes through the tissue, is mapped into reference coordinates (X-FEM cuts
// live there) and appended to the State's swept triangles. The cutting stage
// (cut_stage.h) cuts along all of them, with the scene's declared cuts, as a
// progressive cut: the layout changes only when the set of split elements does.
#include <array>

#include "engine/runtime/simulation.h"

namespace incise {

// Reference position of the material point at world position x in the
// current configuration: the element whose deformed corner tetrahedron
// contains x (barycentric coordinates of the corners, the largest smallest
// one), mapped by the same coordinates to the reference corners; outside the
// tissue the nearest such element's map, extrapolated. *inside tells which.
std::array<double, 3> reference_point(const Model& model, const State& state, const double x[3], bool* inside);

// Appends to sim.state.swept the triangles each scalpel's edge swept in the
// coming frame (sim.tools: before -> after), when the band meets the tissue.
// Returns how many were added.
int sweep_blades(Simulation& sim);

// Edge segments sampled per frame: the band is (kSweepSegments) quads.
inline constexpr int kSweepSegments = 2;

}  // namespace incise
