#include "cutting/cut_apply.h"
#include "engine/step.h"
#include "tools/frame_loop.h"

namespace incise {

FrameTiming advance_frame(Simulation& sim) {
  Stopwatch clock;
  CutUpdate cut;
  if (!sim.scene.cuts.empty()) cut = update_cuts(sim, sim.state.time, sim.state.time + sim.model.dt);
  step(sim.model, sim.state);
  FrameTiming t = sim.state.timing;
  t.ms[kStageCutting] = cut.ms;
  t.cut_frame = cut.changed;
  t.frame_ms = clock.ms();
  return t;
}

}  // namespace incise
