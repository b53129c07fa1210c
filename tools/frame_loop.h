#pragma once
// The frame as the command line (and an embedding application) sets it up:
// the scene loaded, checked, and its pipeline assembled once from it
// (engine/runtime/pipeline.h): the engine's dynamics stages, plus the
// cutting stage when the scene declares cuts. Render is plugged in by the
// commands that ask for it (render/render_stage.h). advance_frame
// (engine/runtime/simulation.h) runs one frame.
#include <memory>
#include <string>
#include <vector>

#include "engine/runtime/simulation.h"

namespace incise {

// load_simulation, then every scene cut built once at its full extent so a bad
// cut (a missing or malformed surface file, a non-convex polygon) fails at
// load, not in the middle of a run; then the pipeline's stages.
// `patches`: command-line overrides of scene keys (load_scene).
std::unique_ptr<Simulation> load_checked_simulation(const std::string& scene_path,
                                                    const std::vector<ScenePatch>& patches = {});
// The same from a scene already parsed (parse_scene). With `recorded_tools`
// (a replay's poses at its first frame) the instruments' trajectories are
// not read (install_instrument_stage).
std::unique_ptr<Simulation> load_checked_simulation(Scene scene,
                                                    const std::vector<ToolFrame>* recorded_tools = nullptr);

}  // namespace incise
