#pragma once
// A loaded scene ready to step: Scene -> Mesh -> Model -> State, with the
// Workspace that steps it and the frame's Pipeline.
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "engine/dynamics/state.h"
#include "engine/mesh/mesh.h"
#include "engine/model/model.h"
#include "engine/runtime/helper_thread.h"
#include "engine/runtime/pipeline.h"
#include "engine/runtime/tool_pose.h"
#include "engine/scene/scene.h"
#include "engine/solve/workspace.h"

namespace incise {

struct Simulation {
  Scene scene;
  Mesh mesh;              // as read (a cut rebuilds the model from it)
  Model model;            // frozen between frames; a cut puts the next version in place
  State state;            // the physical state: copyable, hashable
  Workspace ws;           // factors, threads, caches, work arrays, timings
  Pipeline pipeline;      // the frame's stages (engine/runtime/pipeline.h)
  // (scene.instruments) each instrument's pose at the start and end of the
  // coming frame, set by the tool-poses stage; empty without instruments.
  std::vector<ToolFrame> tools;
  // Module state that lives as long as the simulation (the collision model,
  // the instruments' trajectories, grasps): each module keeps its own, keyed
  // by its stage; engine/ only holds it.
  std::array<std::shared_ptr<void>, kNumStages> module_data{};
  double setup_ms = 0.0;  // reading the mesh, precomputation, symbolic analysis
  int model_version = 0;  // counts the models a cut put in place
  // cutting/cut_apply.cpp: the next frame's cut update being prepared on
  // cut_helper, which reads model, mesh and scene. Last members, so the
  // thread (destroyed first) has finished before any of them goes.
  std::shared_ptr<void> cut_ahead;
  // The model the last cut replaced, freed by the next cut-ahead task or
  // by prepare_cut_now.
  std::shared_ptr<Model> retired_model;
  std::unique_ptr<HelperThread> cut_helper;
  // Runs the collision stage while a stage's start runs on the stepping
  // thread (Pipeline::set_start); joined within the frame.
  std::unique_ptr<HelperThread> stage_helper;
};

// Reads the scene (with `patches` applied to its JSON first: load_scene) and
// its mesh, builds the model, initialises the state and workspace; the
// pipeline holds the dynamics stages only (modules plug in theirs). Throws
// incise::Error with the file (or patch) and field at fault.
std::unique_ptr<Simulation> load_simulation(const std::string& scene_path, const std::vector<ScenePatch>& patches = {});
// The same from a scene already parsed (a replay's embedded scene: parse_scene).
std::unique_ptr<Simulation> load_simulation(Scene scene);

// One frame through sim.pipeline.
inline FrameTiming advance_frame(Simulation& sim) { return sim.pipeline.run_frame(sim); }

// Puts `state` (a copy of another run's, or one read from a file) and the
// model it was stepped on in place: the next frame continues from it. The
// model must come from the same scene and mesh (a copy of the other run's
// sim.model; a model with no cuts when state.cut_progress applies none).
// Throws incise::Error when the sizes do not match the model.
void restore_state(Simulation& sim, const Model& model, const State& state);

}  // namespace incise
