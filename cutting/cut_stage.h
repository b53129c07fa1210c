#pragma once
// The cutting stage plugged into the frame's pipeline (engine/runtime/pipeline.h):
// the scene's cuts that are due (a swept cut up to the end of the coming
// frame) through update_cuts, and the next frame's layout and model started
// on the cut-ahead helper. Installed only when the scene declares cuts.
#include "engine/runtime/simulation.h"

namespace incise {

// One run of the stage; records the cut's parts in sim.ws.timing.
void cutting_stage(Simulation& sim);

// Fills the pipeline's cutting slot when sim.scene has cuts; otherwise the
// stage stays absent.
void install_cutting_stage(Simulation& sim);

}  // namespace incise
