#include "cutting/cut_stage.h"

#include "cutting/blade_sweep.h"
#include "cutting/cut_apply.h"
#include "engine/dynamics/static_solve.h"
#include "engine/runtime/failure_context.h"
#include "engine/util/error.h"

namespace incise {

void cutting_stage(Simulation& sim) {
  const double t = sim.state.time, dt = sim.model.dt;
  bool blade_done_changed = false;
  const int swept = sweep_blades(sim, &blade_done_changed);  // the scalpels' bands of this frame
  const CutUpdate cut = update_cuts(sim, t, t + dt, swept > 0 || blade_done_changed);
  // The next frame's layout and model build run beside this step (the times
  // as the next frame will compute them: t1 = t + dt, then t1 + dt).
  // (t1 + dt, not t + 2 dt: the next frame sums its times the same way, and
  // a prepared update is taken only for exactly its times.)
  const double t1 = t + dt;
  start_cut_ahead(sim, t1, t1 + dt);
  FrameTiming& ft = sim.ws.timing;
  ft.cut_ms = cut.part_ms;
  ft.cut_frame = cut.changed;
  ft.cut_ahead = cut.ahead;
}

void install_cutting_stage(Simulation& sim) {
  bool scalpel = false;
  for (const InstrumentSpec& i : sim.scene.instruments) scalpel = scalpel || i.kind == InstrumentSpec::Kind::Scalpel;
  if (!sim.scene.cuts.empty() || scalpel) sim.pipeline.set(kStageCutting, cutting_stage);
  warn_cuts_that_cut_nothing(sim);
  // initial "static" with cuts due at t = 0: load_simulation solved the
  // uncut equilibrium (engine/ does not cut), so the scene started there
  // and moved at once when the first frame cut (a partial slit: 0.57 m/s at
  // frame 1). The cuts are applied now and the equilibrium solved again
  // from there.
  bool due = false;
  for (const CutSpec& c : sim.scene.cuts) due = due || c.at_time <= 0.0;
  if (sim.scene.initial_static && due && sim.state.frame == 0 && update_cuts(sim, 0.0, 0.0).changed) {
    try {
      start_at_static_equilibrium(sim.model, sim.state, sim.ws, sim.scene.static_tolerance,
                                  sim.scene.static_max_iterations, sim.scene.path);
    } catch (const NumericalError& e) {
      throw Error(sim.scene.path + ": initial \"static\" with the cuts at t = 0: " + with_failure_context(e, sim.model));
    }
  }
}

}  // namespace incise
