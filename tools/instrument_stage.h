#pragma once
// The tool-poses stage plugged into the frame's pipeline
// (engine/runtime/pipeline.h, kStageToolPoses): each instrument of the scene
// (scene.instruments) posed at the start and end of the coming frame from its
// keyframe trajectory (engine/runtime/trajectory.h) or its fixed pose, into
// Simulation::tools for collision and cutting. Installed only when the scene
// has instruments.
#include "engine/runtime/simulation.h"

namespace incise {

// One run of the stage: sim.tools[i].before = pose at sim.state.time,
// .after = pose at sim.state.time + sim.model.dt.
void tool_poses_stage(Simulation& sim);

// Without instruments: nothing (the slot stays empty, sim.tools stays empty).
// Otherwise reads every trajectory, checks each instrument's sizes against
// the mesh (within [1e-4, 10] times its bounding-box diagonal), keeps the
// trajectories in sim.module_data[kStageToolPoses], sizes sim.tools with
// before = after = the pose at sim.state.time (0 at set-up) and fills the
// slot. Throws incise::Error naming the scene, the JSON path and the file
// line ("scene.json: instruments[0].trajectory: traj.csv:5: ...").
// With `recorded` (a replay, whose recorded poses stand in for trajectories
// and devices: one ToolFrame per instrument) no trajectory is read, so a
// replay does not need their files; sim.tools = *recorded and the slot's
// stage is the caller's to replace.
void install_instrument_stage(Simulation& sim, const std::vector<ToolFrame>* recorded = nullptr);

// Instrument i (scene.instruments index) at time t: its trajectory's sample
// (jaw from the trajectory's jaw column, else the scene's jaw) or its fixed
// pose. Allocates nothing. Throws incise::Error for an index out of range or
// an instrument with a trajectory before install_instrument_stage.
ToolPose instrument_pose(const Simulation& sim, int i, double t);

}  // namespace incise
