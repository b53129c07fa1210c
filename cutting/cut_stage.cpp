#include "cutting/cut_stage.h"

#include "cutting/blade_sweep.h"
#include "cutting/cut_apply.h"
#include "engine/dynamics/static_solve.h"
#include "engine/runtime/failure_context.h"
#include "engine/util/error.h"

namespace incise {

namespace {

// The scalpels' sweep of a frame, done by the stage's start (cutting_start).
struct EarlySweep {
  int frame = -1;  // the frame it belongs to (-1: none)
  int swept = 0;   // sweep_blades' triangles added
  bool blade_done_changed = false;
};

// The cutting stage's start (Pipeline::set_start): the scalpels sweep
// (their bands need only this frame's poses and the state at its start);
// when they cut, it hands back the layout and model build, which then run
// while the collision stage runs on a helper. On probe-incision-20k the
// collision stage is 4-5 ms of each cut frame (the collision tree rebuilt
// after the last cut), the cut's layout and model 15-20 ms. The other way
// round (the cut on the helper) took the helper CPU from the background
// factorization for those 15-20 ms, not 4-5 (docs/benchmarks.md, "A
// scalpel's cut prepared while collision runs"). A frame that does not cut
// leaves collision on the stepping thread.
StageFn cutting_start(Simulation& sim, EarlySweep& early) {
  early.frame = sim.state.frame;
  early.swept = sweep_blades(sim, &early.blade_done_changed);
  if (early.swept == 0 && !early.blade_done_changed) return {};
  return [](Simulation& s) { prepare_cut_now(s, s.state.time, s.state.time + s.model.dt); };
}

// The stage; early: its start's sweep, when it has a start (a scalpel).
void run_cutting(Simulation& sim, EarlySweep* early) {
  const double t = sim.state.time, dt = sim.model.dt;
  bool blade_done_changed = false;
  int swept = 0;
  if (early && early->frame == sim.state.frame) {  // swept by the start
    swept = early->swept;
    blade_done_changed = early->blade_done_changed;
    early->frame = -1;
  } else {
    swept = sweep_blades(sim, &blade_done_changed);  // the scalpels' bands of this frame
  }
  const CutUpdate cut = update_cuts(sim, t, t + dt, swept > 0 || blade_done_changed);
  // The next frame's layout and model build run beside this step (the times
  // as the next frame will compute them: t1 = t + dt, then t1 + dt).
  // (t1 + dt, not t + 2 dt: the next frame sums its times the same way, and
  // a prepared update is taken only for exactly its times.)
  const double t1 = t + dt;
  start_cut_ahead(sim, t1, t1 + dt);
  // A cut-ahead on a helper: the assembly workers leave it the helpers' CPUs
  // this frame. Beside it they were descheduled mid-assembly and the
  // stepping thread waited for them (incision-10k, 2 workers: cut frames'
  // assembly 2.7 -> 11-18 ms). lagged_refresh keeps them down for the CG.
  SolverWork& w = sim.ws.work;
  w.helper_busy = sim.cut_ahead != nullptr;
  w.apply_stand_down();
  FrameTiming& ft = sim.ws.timing;
  ft.cut_ms = cut.part_ms;
  ft.cut_frame = cut.changed;
  ft.cut_ahead = cut.ahead;
  ft.cut_early = cut.early;
}

}  // namespace

void cutting_stage(Simulation& sim) { run_cutting(sim, nullptr); }

void install_cutting_stage(Simulation& sim) {
  bool scalpel = false;
  for (const InstrumentSpec& i : sim.scene.instruments) scalpel = scalpel || i.kind == InstrumentSpec::Kind::Scalpel;
  if (scalpel) {
    auto early = std::make_shared<EarlySweep>();
    sim.pipeline.set(kStageCutting, [early](Simulation& s) { run_cutting(s, early.get()); });
    sim.pipeline.set_start(kStageCutting, [early](Simulation& s) { return cutting_start(s, *early); });
  } else if (!sim.scene.cuts.empty()) {
    sim.pipeline.set(kStageCutting, cutting_stage);
  }
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
