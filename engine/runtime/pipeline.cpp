#include "engine/runtime/pipeline.h"

#include <ctime>

#include "engine/dynamics/step.h"
#include "engine/runtime/failure_context.h"
#include "engine/runtime/simulation.h"
#include "engine/util/error.h"

namespace incise {

namespace {

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

}  // namespace

bool is_dynamics_stage(Stage stage) {
  return stage == kStageAssembly || stage == kStageFactorization || stage == kStageSolve || stage == kStageContact ||
         stage == kStageIntegration;
}

void Pipeline::set(Stage stage, StageFn fn) {
  if (is_dynamics_stage(stage))
    throw Error(std::string("pipeline: stage '") + kStageNames[stage] + "' is the engine's own step and cannot be replaced");
  slots_[stage] = std::move(fn);
}

bool Pipeline::has(Stage stage) const { return is_dynamics_stage(stage) || static_cast<bool>(slots_[stage]); }

FrameTiming Pipeline::run_frame(Simulation& sim) const {
  Stopwatch frame_clock;
  const double cpu0 = thread_cpu_ms();
  FrameTiming& t = sim.ws.timing;
  t = FrameTiming{};
  const auto run = [&](Stage s) {
    if (slots_[s]) run_stage(t, s, [&] { slots_[s](sim); });
  };
  run(kStageToolPoses);
  run(kStageCollision);
  run(kStageCutting);
  try {
    step_stages(sim.model, sim.state, sim.ws);  // assembly, factorization, solve (per Newton iteration), integration
  } catch (const NumericalError& e) {  // the node and the scene values to look at, once for every caller
    const std::string what = e.what();
    throw Error((what.find("at frame ") == std::string::npos ? "frame " + std::to_string(sim.state.frame) + ": " : "") +
                with_failure_context(e, sim.model));
  }
  run(kStageContactPublish);
  run(kStageRender);
  run(kStageRecord);
  t.frame_ms = frame_clock.ms();
  t.cpu_ms = thread_cpu_ms() - cpu0;
  return t;
}

std::string Pipeline::describe() const {
  std::string out;
  for (int s = 0; s < kNumStages; ++s) {
    const Stage st = static_cast<Stage>(s);
    out += std::string(kStageNames[s]) + ": " +
           (is_dynamics_stage(st) ? "engine" : (slots_[s] ? "plugged in" : "absent")) + "\n";
  }
  return out;
}

}  // namespace incise
