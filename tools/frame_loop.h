#pragma once
// One frame of the simulation loop as the command line runs it:
// 1. cutting (cuts due by now; a swept cut up to the end of this frame),
// 2.-6. the step (assembly, factorization, solve, Newmark).
// Stages a scene does not call for cost nothing: no cuts, no cutting work.
#include "engine/simulation.h"
#include "engine/timing.h"

namespace incise {

FrameTiming advance_frame(Simulation& sim);

}  // namespace incise
