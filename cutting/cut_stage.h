#pragma once
// The cutting stage plugged into the frame's pipeline (engine/runtime/pipeline.h):
// the scene's cuts that are due (a swept cut up to the end of the coming
// frame) through update_cuts, and the next frame's layout and model started
// on the cut-ahead helper. Installed only when the scene declares cuts or a
// scalpel; with a scalpel the stage also has a start (Pipeline::set_start):
// the blades sweep, and when they cut, their cut is prepared while the
// collision stage runs on a helper.
#include "engine/runtime/simulation.h"

namespace incise {

// One run of the stage (the blades' sweep included); records the cut's parts
// in sim.ws.timing.
void cutting_stage(Simulation& sim);

// Fills the pipeline's cutting slot when sim.scene has cuts; otherwise the
// stage stays absent.
void install_cutting_stage(Simulation& sim);

}  // namespace incise
