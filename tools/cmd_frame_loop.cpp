#include <ctime>

#include "cutting/cut_apply.h"
#include "cutting/cut_surface.h"
#include "engine/util/error.h"
#include "engine/dynamics/step.h"
#include "tools/frame_loop.h"

namespace incise {

namespace {
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}
}  // namespace

FrameTiming advance_frame(Simulation& sim) {
  Stopwatch clock;
  const double cpu0 = thread_cpu_ms();
  CutUpdate cut;
  if (!sim.scene.cuts.empty()) {
    cut = update_cuts(sim, sim.state.time, sim.state.time + sim.model.dt);
    // The next frame's layout and model build run beside this step (the
    // times as the next frame will compute them: t1 = t + dt, then t1 + dt).
    const double t1 = sim.state.time + sim.model.dt;
    start_cut_ahead(sim, t1, t1 + sim.model.dt);
  }
  step(sim.model, sim.state);
  FrameTiming t = sim.state.timing;
  t.ms[kStageCutting] = cut.ms;
  t.cut_ms = cut.part_ms;
  t.cut_frame = cut.changed;
  t.cut_ahead = cut.ahead;
  t.frame_ms = clock.ms();
  t.cpu_ms = thread_cpu_ms() - cpu0;
  return t;
}

std::unique_ptr<Simulation> load_checked_simulation(const std::string& scene_path,
                                                    const std::vector<ScenePatch>& patches) {
  auto sim = load_simulation(scene_path, patches);
  for (const CutSpec& c : sim->scene.cuts) {
    try {
      make_cut_surface(c, c.at_time + c.duration);
    } catch (const Error& e) {
      throw Error(scene_path + ": " + e.what());
    }
  }
  return sim;
}

}  // namespace incise
