#pragma once
// The cut a scalpel makes: in each frame its cutting edge moves from its pose
// at the frame's start to its pose at the end; the band it sweeps, where it
// passes through the tissue, is mapped into reference coordinates (X-FEM cuts
// live there) and appended to the State's swept triangles. The cutting stage
// (cut_stage.h) cuts along all of them, with the scene's declared cuts, as a
// progressive cut: the layout changes only when the set of split elements does.
#include <array>
#include <vector>

#include <Eigen/Core>

#include "engine/model/tissue_locator.h"
#include "engine/runtime/simulation.h"

namespace incise {

// Appends to sim.state.swept the triangles each scalpel's edge swept in the
// coming frame (sim.tools: before -> after), when the band meets the tissue.
// Returns how many were added.
int sweep_blades(Simulation& sim);

// Edge segments sampled per frame: the band is (kSweepSegments) quads.
inline constexpr int kSweepSegments = 2;
// A frame's motion is swept in steps of at most half the size of the
// smaller elements (sweep_spacing), and at most this many: a blade that
// passes through thin tissue within one frame, outside it at both ends,
// still cuts it.
inline constexpr int kMaxSweepSteps = 64;
// A band whose edge samples all lie within this many element sizes of the
// blade's incision so far (of its facets' planes, and not further ahead of
// its boundary) re-cuts it and is dropped.
inline constexpr double kReCutReach = 0.25;

}  // namespace incise
