#include "engine/runtime/simulation.h"

#include "engine/mesh/mesh_io.h"
#include "engine/runtime/timing.h"

namespace incise {

std::unique_ptr<Simulation> load_simulation(const std::string& scene_path, const std::vector<ScenePatch>& patches) {
  Stopwatch clock;
  auto sim = std::make_unique<Simulation>();
  sim->scene = load_scene(scene_path, patches);
  sim->mesh = read_mesh(sim->scene.mesh_file);
  sim->model = build_model(sim->mesh, sim->scene);
  sim->cut_progress.assign(sim->scene.cuts.size(), -1.0);
  init_state(sim->model, sim->state);
  sim->setup_ms = clock.ms();
  return sim;
}

}  // namespace incise
