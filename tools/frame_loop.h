#pragma once
// One frame of the simulation loop as the command line runs it:
// 1. cutting (cuts due by now; a swept cut up to the end of this frame),
// 2.-6. the step (assembly, factorization, solve, Newmark).
// Stages a scene does not call for cost nothing: no cuts, no cutting work.
#include <memory>
#include <string>
#include <vector>

#include "engine/runtime/simulation.h"
#include "engine/runtime/timing.h"

namespace incise {

FrameTiming advance_frame(Simulation& sim);

// load_simulation, then every scene cut built once at its full extent so a bad
// cut (a missing or malformed surface file, a non-convex polygon) fails at
// load, not in the middle of a run.
// `patches`: command-line overrides of scene keys (load_scene).
std::unique_ptr<Simulation> load_checked_simulation(const std::string& scene_path,
                                                    const std::vector<ScenePatch>& patches = {});

}  // namespace incise
