#pragma once
// The frame as a pipeline of named stages, in the order of the loop
// (../shared/DESIGN.md, "The frame as stages"; engine/runtime/timing.h):
//
//   tool poses -> collision -> cutting -> [assembly -> factorization -> solve]
//   per Newton iteration -> integration -> contact publish -> render -> record
//
// (A stage may also have a start, run after tool poses, whose work may run
// while collision runs on a helper: set_start.)
//
// The dynamics stages (assembly .. integration) are the engine's own
// (engine/dynamics/step.h) and always run. The others are slots that a
// module fills when the scene calls for it, once, when the simulation is set
// up: cutting/ the cutting stage (a scene with cuts), render/ the render
// stage (when asked), and later collision, instruments, haptics and replay.
// engine/ knows none of them. An empty slot is absent: it costs nothing and
// its run count stays 0, which `incise bench` prints.
//
// The pipeline times every stage through run_stage; a stage never times
// itself (it may record details, such as the parts of a cut, in
// sim.ws.timing).
#include <array>
#include <functional>
#include <string>

#include "engine/runtime/timing.h"

namespace incise {

struct Simulation;

using StageFn = std::function<void(Simulation&)>;
// A stage's start (Pipeline::set_start): returns the work, if any, to run
// beside the collision stage.
using StartFn = std::function<StageFn(Simulation&)>;

class Pipeline {
 public:
  // Fills a stage's slot (replacing what it held, and dropping its start).
  // Throws incise::Error for a dynamics stage: those are the step's
  // (engine/dynamics/step.h).
  void set(Stage stage, StageFn fn);
  bool has(Stage stage) const;
  // What the slot holds (empty when absent): a module wraps another's stage
  // (haptics/ replaces the haptic instrument's pose after the tool-poses stage).
  const StageFn& get(Stage stage) const { return slots_[stage]; }
  // A stage's start: run on the stepping thread once the tool poses are
  // known, before collision. It may return work that needs only the poses;
  // that runs on the stepping thread while the collision stage runs beside
  // it on a helper thread (Simulation::stage_helper; both only read the
  // model and the state's kinematics). Without such work collision runs on
  // the stepping thread as always. cutting/ sweeps the scalpels in the
  // start and returns their cut's preparation when they cut. Its time
  // counts in the stage's ms, not its runs. Only for a stage after
  // collision that is not a dynamics stage (else incise::Error); set it
  // after the stage itself.
  void set_start(Stage stage, StartFn fn);
  // One frame: the stages in loop order. Returns the frame's timing (also
  // left in sim.ws.timing): each stage's time and runs, the frame's wall and
  // CPU time, and the details the stages recorded.
  FrameTiming run_frame(Simulation& sim) const;
  // The stages in order, each with "engine", "plugged in" or "absent" (and
  // ", with a start beside collision").
  std::string describe() const;

 private:
  // The starts, then their work on this thread with collision on
  // sim.stage_helper beside it.
  void run_starts_and_collision(Simulation& sim) const;
  std::array<StageFn, kNumStages> slots_{};
  std::array<StartFn, kNumStages> starts_{};
};

// Whether a stage is the engine's own (the step's).
bool is_dynamics_stage(Stage stage);

}  // namespace incise
