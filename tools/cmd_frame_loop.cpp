#include "collision/collision_stage.h"
#include "cutting/cut_stage.h"
#include "cutting/cut_surface.h"
#include "engine/util/error.h"
#include "tools/frame_loop.h"
#include "tools/instrument_stage.h"

namespace incise {

std::unique_ptr<Simulation> load_checked_simulation(const std::string& scene_path,
                                                    const std::vector<ScenePatch>& patches) {
  return load_checked_simulation(load_scene(scene_path, patches));
}

std::unique_ptr<Simulation> load_checked_simulation(Scene scene, const std::vector<ToolFrame>* recorded_tools) {
  auto sim = load_simulation(std::move(scene));
  for (const CutSpec& c : sim->scene.cuts) {
    try {
      make_cut_surface(c, c.at_time + c.duration);
    } catch (const Error& e) {
      throw Error(sim->scene.path + ": " + e.what());
    }
  }
  install_instrument_stage(*sim, recorded_tools);  // before collision and cutting: they read sim.tools
  install_collision_stage(*sim);
  install_cutting_stage(*sim);
  return sim;
}

}  // namespace incise
