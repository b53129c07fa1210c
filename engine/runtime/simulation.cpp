#include "engine/runtime/simulation.h"

#include <cstdio>

#include "engine/dynamics/static_solve.h"
#include "engine/dynamics/step.h"
#include "engine/mesh/mesh_io.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/runtime/failure_context.h"
#include "engine/runtime/timing.h"
#include "engine/util/error.h"

namespace incise {

std::unique_ptr<Simulation> load_simulation(const std::string& scene_path, const std::vector<ScenePatch>& patches) {
  return load_simulation(load_scene(scene_path, patches));
}

std::unique_ptr<Simulation> load_simulation(Scene scene) {
  Stopwatch clock;
  auto sim = std::make_unique<Simulation>();
  sim->scene = std::move(scene);
  sim->mesh = read_mesh(sim->scene.mesh_file);
  sim->model = build_model(sim->mesh, sim->scene);  // (checks the mesh: no NaN reaches the sort below)
  if (const CoincidentNodes c = coincident_nodes(sim->mesh); c.count > 0)
    std::fprintf(stderr,
                 "warning: %s: %d node(s) lie exactly where another node lies (first: nodes %d and %d, counted "
                 "from 0, at (%g, %g, %g)): the elements using one and those using the other are not connected "
                 "there, as if the mesh were cut; merge duplicate vertices when exporting (unless the mesh models "
                 "a slit on purpose)\n",
                 sim->mesh.source.empty() ? sim->scene.mesh_file.c_str() : sim->mesh.source.c_str(), c.count, c.a, c.b,
                 sim->mesh.X[3 * c.a], sim->mesh.X[3 * c.a + 1], sim->mesh.X[3 * c.a + 2]);
  sim->ws.runtime = sim->scene.runtime;
  init_state(sim->model, sim->state, sim->ws);
  if (sim->scene.initial_static) {
    try {
      start_at_static_equilibrium(sim->model, sim->state, sim->ws, sim->scene.static_tolerance,
                                  sim->scene.static_max_iterations, sim->scene.path);
    } catch (const NumericalError& e) {
      throw Error(sim->scene.path + ": initial \"static\": " + with_failure_context(e, sim->model));
    }
  }
  sim->state.cut_progress.assign(sim->scene.cuts.size(), -1.0);
  sim->setup_ms = clock.ms();
  return sim;
}

void restore_state(Simulation& sim, const Model& model, const State& state) {
  if (state.cut_progress.size() != sim.scene.cuts.size())
    throw Error("state: cut_progress has " + std::to_string(state.cut_progress.size()) + " entries, the scene has " +
                std::to_string(sim.scene.cuts.size()) + " cuts");
  sim.cut_ahead.reset();
  if (sim.cut_helper) sim.cut_helper->wait();  // (its task reads the model about to be replaced)
  if (&model != &sim.model) sim.model = model;
  ++sim.model_version;  // a cut prepared for the old model is not taken
  attach_state(sim.model, state, sim.ws);
  sim.state = state;
}

}  // namespace incise
