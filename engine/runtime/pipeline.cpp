#include "engine/runtime/pipeline.h"

#include <ctime>
#include <exception>

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
  starts_[stage] = nullptr;  // a start belongs to the stage it was set with
}

void Pipeline::set_start(Stage stage, StartFn fn) {
  if (is_dynamics_stage(stage) || stage <= kStageCollision)
    throw Error(std::string("pipeline: stage '") + kStageNames[stage] +
                "' cannot have a start: only a module's stage after collision can");
  starts_[stage] = std::move(fn);
}

bool Pipeline::has(Stage stage) const { return is_dynamics_stage(stage) || static_cast<bool>(slots_[stage]); }

void Pipeline::run_starts_and_collision(Simulation& sim) const {
  FrameTiming& t = sim.ws.timing;
  std::array<StageFn, kNumStages> work{};  // what the starts hand back, timed into their stages (not runs)
  bool any = false;
  for (int k = kStageCollision + 1; k < kNumStages; ++k)
    if (starts_[k] && slots_[k]) {
      Stopwatch clock;
      work[k] = starts_[k](sim);
      t.ms[k] += clock.ms();
      any = any || static_cast<bool>(work[k]);
    }
  const auto run_work = [&] {
    for (int k = kStageCollision + 1; k < kNumStages; ++k)
      if (work[k]) {
        Stopwatch clock;
        work[k](sim);
        t.ms[k] += clock.ms();
      }
  };
  if (!any || !slots_[kStageCollision]) {
    run_work();
    if (slots_[kStageCollision]) run_stage(t, kStageCollision, [&] { slots_[kStageCollision](sim); });
    return;
  }
  // Collision on the helper, the work here. The helper's task refers to
  // sim: it is joined before anything leaves this function.
  const bool helper_cpus = sim.ws.runtime.split_affinity;
  if (!sim.stage_helper || sim.stage_helper->helper_cpus() != helper_cpus)
    sim.stage_helper = std::make_unique<HelperThread>(helper_cpus, HelperThread::Priority::Normal);
  std::exception_ptr collision_error;
  double collision_ms = 0.0;
  sim.stage_helper->run([&] {
    Stopwatch clock;
    try {
      slots_[kStageCollision](sim);
    } catch (...) {
      collision_error = std::current_exception();
    }
    collision_ms = clock.ms();
  });
  try {
    run_work();
  } catch (...) {
    sim.stage_helper->wait();
    throw;
  }
  sim.stage_helper->wait();
  if (collision_error) std::rethrow_exception(collision_error);
  t.ms[kStageCollision] += collision_ms;
  ++t.runs[kStageCollision];
}

FrameTiming Pipeline::run_frame(Simulation& sim) const {
  Stopwatch frame_clock;
  const double cpu0 = thread_cpu_ms();
  FrameTiming& t = sim.ws.timing;
  t = FrameTiming{};
  const auto run = [&](Stage s) {
    if (slots_[s]) run_stage(t, s, [&] { slots_[s](sim); });
  };
  run(kStageToolPoses);
  run_starts_and_collision(sim);
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
           (is_dynamics_stage(st) ? "engine" : (slots_[s] ? "plugged in" : "absent")) +
           (slots_[s] && starts_[s] ? ", with a start beside collision" : "") + "\n";
  }
  return out;
}

}  // namespace incise
