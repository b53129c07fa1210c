#pragma once
// A loaded scene ready to step: Scene -> Mesh -> Model -> State.
#include <memory>
#include <string>
#include <vector>

#include "engine/runtime/helper_thread.h"
#include "engine/mesh/mesh.h"
#include "engine/model/model.h"
#include "engine/scene/scene.h"
#include "engine/dynamics/state.h"

namespace incise {

struct Simulation {
  Scene scene;
  Mesh mesh;                          // as read (a cut rebuilds the model from it)
  std::vector<double> cut_progress;   // (scene.cuts) share of each cut applied: -1 none, 1 whole
  Model model;
  State state;
  double setup_ms = 0.0;  // reading the mesh, precomputation, symbolic analysis
  int model_version = 0;  // counts the models a cut put in place
  // cutting/cut_apply.cpp: the next frame's cut update being prepared on
  // cut_helper, which reads model, mesh and scene. Last members, so the
  // thread (destroyed first) has finished before any of them goes.
  std::shared_ptr<void> cut_ahead;
  std::shared_ptr<Model> retired_model;  // the model the last cut replaced, freed by the next cut-ahead task
  std::unique_ptr<HelperThread> cut_helper;
};

// Reads the scene (with `patches` applied to its JSON first: load_scene) and
// its mesh, builds the model, initialises the state. Throws incise::Error with
// the file (or patch) and field at fault.
std::unique_ptr<Simulation> load_simulation(const std::string& scene_path, const std::vector<ScenePatch>& patches = {});

}  // namespace incise
