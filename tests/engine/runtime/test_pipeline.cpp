// The frame as a pipeline of named stages: order, run counts, absent stages.
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "engine/dynamics/step.h"
#include "engine/runtime/pipeline.h"
#include "engine/runtime/simulation.h"
#include "engine/util/error.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

std::unique_ptr<Simulation> beam_sim(const SolverSettings& solver = {}) {
  auto sim = std::make_unique<Simulation>();
  Scene& s = sim->scene;
  s = test::basic_scene(2);
  s.material.young = 2e3;
  s.gravity = {0.0, 0.0, -9.81};
  s.fixed.push_back(test::box_region({-1, -1, -1}, {1e-9, 2, 2}));
  s.solver = solver;
  sim->mesh = make_beam(4, 1, 1, 4, 2, 2, 1);
  sim->model = build_model(sim->mesh, s);
  init_state(sim->model, sim->state, sim->ws);
  return sim;
}

TEST(Pipeline, AStageTheSceneDoesNotCallForRunsZeroTimes) {
  auto sim = beam_sim();
  FrameTiming total;
  for (int k = 0; k < 5; ++k) {
    const FrameTiming t = advance_frame(*sim);
    for (int s = 0; s < kNumStages; ++s) total.runs[s] += t.runs[s];
    EXPECT_EQ(t.runs[kStageAssembly], t.newton) << "one assembly per Newton iteration";
    EXPECT_EQ(t.runs[kStageSolve], t.newton) << "no rescue under exact";
    EXPECT_EQ(t.runs[kStageFactorization], t.runs[kStageSolve]);
  }
  for (Stage s : {kStageToolPoses, kStageCollision, kStageCutting, kStageContactPublish, kStageRender, kStageRecord}) {
    EXPECT_EQ(total.runs[s], 0) << kStageNames[s];
    EXPECT_FALSE(sim->pipeline.has(s)) << kStageNames[s];
  }
  EXPECT_EQ(total.runs[kStageIntegration], 5);
  EXPECT_GE(total.runs[kStageAssembly], 5);
  EXPECT_EQ(sim->state.frame, 5);
  EXPECT_NE(sim->pipeline.describe().find("cutting: absent\n"), std::string::npos) << sim->pipeline.describe();
  EXPECT_NE(sim->pipeline.describe().find("assembly: engine\n"), std::string::npos);
}

TEST(Pipeline, PluggedStagesRunInLoopOrderAroundTheStep) {
  auto sim = beam_sim();
  std::vector<std::string> seen;
  for (Stage s : {kStageRecord, kStageToolPoses, kStageRender, kStageCollision, kStageContactPublish, kStageCutting})
    sim->pipeline.set(s, [s, &seen](Simulation& x) { seen.push_back(std::string(kStageNames[s]) + "@" + std::to_string(x.state.frame)); });
  const FrameTiming t = advance_frame(*sim);
  const std::vector<std::string> expect = {"tool_poses@0", "collision@0", "cutting@0", "contact_publish@1", "render@1",
                                           "record@1"};
  EXPECT_EQ(seen, expect) << "before the step: frame 0; after it: frame 1";
  for (Stage s : {kStageToolPoses, kStageCollision, kStageCutting, kStageContactPublish, kStageRender, kStageRecord})
    EXPECT_EQ(t.runs[s], 1) << kStageNames[s];
}

// Expects fn() to throw incise::Error with "stage '<name of s>'" + what in
// its message.
template <class F>
void expect_stage_error(Stage s, F fn, const std::string& what) {
  try {
    fn();
    ADD_FAILURE() << kStageNames[s] << ": no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(std::string("stage '") + kStageNames[s] + "'" + what), std::string::npos)
        << e.what();
  }
}

TEST(Pipeline, TheStepsOwnStagesCannotBeReplaced) {
  auto sim = beam_sim();
  for (Stage s : {kStageAssembly, kStageFactorization, kStageSolve, kStageIntegration})
    expect_stage_error(s, [&] { sim->pipeline.set(s, [](Simulation&) {}); }, " is the engine's own step");
}

// A stage's start runs on the stepping thread after tool poses; the work it
// hands back runs there too while the collision stage runs beside it on a
// helper, and without such work collision stays on the stepping thread. A
// start is timed into its stage without counting as a run and goes when
// the stage is replaced. An error thrown on the helper reaches the caller.
// Only a module's stage after collision may have a start.
TEST(Pipeline, AStartsWorkRunsBesideCollisionAndBelongsToItsStage) {
  auto sim = beam_sim();
  const std::thread::id stepping = std::this_thread::get_id();
  std::vector<std::string> seen;  // (the stepping thread's stages only)
  std::thread::id collision_thread;
  int collisions = 0;
  bool collision_throws = false;
  for (Stage s : {kStageToolPoses, kStageCutting, kStageRender})
    sim->pipeline.set(s, [s, &seen](Simulation&) { seen.push_back(kStageNames[s]); });
  sim->pipeline.set(kStageCollision, [&](Simulation&) {
    collision_thread = std::this_thread::get_id();
    ++collisions;
    if (collision_throws) throw Error("collision failed");
  });
  sim->pipeline.set_start(kStageCutting, [&seen](Simulation&) -> StageFn {
    seen.push_back("cutting start");
    return [&seen](Simulation&) { seen.push_back("cutting work"); };
  });
  sim->pipeline.set_start(kStageRender, [&seen](Simulation&) -> StageFn {
    seen.push_back("render start");
    return {};  // nothing to run beside collision
  });
  EXPECT_NE(sim->pipeline.describe().find("cutting: plugged in, with a start beside collision\n"), std::string::npos)
      << sim->pipeline.describe();
  FrameTiming t = advance_frame(*sim);
  const std::vector<std::string> expect = {"tool_poses", "cutting start", "render start", "cutting work", "cutting",
                                           "render"};
  EXPECT_EQ(seen, expect);
  EXPECT_EQ(collisions, 1);
  EXPECT_EQ(t.runs[kStageCollision], 1);
  EXPECT_NE(collision_thread, stepping) << "collision ran beside the work";
  EXPECT_EQ(t.runs[kStageCutting], 1) << "a start is not a run";
  collision_throws = true;
  EXPECT_THROW(advance_frame(*sim), Error) << "the helper's error reaches the caller";
  collision_throws = false;
  seen.clear();
  sim->pipeline.set(kStageCutting, [&seen](Simulation&) { seen.push_back("cutting, replaced"); });
  t = advance_frame(*sim);
  const std::vector<std::string> replaced = {"tool_poses", "render start", "cutting, replaced", "render"};
  EXPECT_EQ(seen, replaced) << "the replaced stage's start went with it";
  EXPECT_EQ(collision_thread, stepping) << "no work beside collision: collision on the stepping thread";
  EXPECT_EQ(collisions, 3);
  EXPECT_EQ(t.runs[kStageCollision], 1);
  for (Stage s : {kStageToolPoses, kStageCollision, kStageAssembly, kStageIntegration})
    expect_stage_error(s, [&] { sim->pipeline.set_start(s, [](Simulation&) { return StageFn{}; }); },
                       " cannot have a start");
}

// A lagged rescue (CG gave up after rescue_after iterations) runs the
// factorization and solve stages once more in the same Newton iteration.
TEST(Pipeline, ALaggedRescueRunsFactorizationAndSolveAgain) {
  SolverSettings lagged;
  lagged.policy = SolverPolicy::Lagged;
  lagged.refresh_every = 1000;  // the factor of frame 1 preconditions every later frame
  lagged.rescue_after = 1;
  lagged.tolerance = 1e-13;     // one CG iteration with a stale factor cannot reach it
  lagged.max_iterations = 200;
  auto sim = beam_sim(lagged);
  advance_frame(*sim);
  const FrameTiming t = advance_frame(*sim);
  ASSERT_GT(t.rescues, 0);
  EXPECT_EQ(t.runs[kStageSolve], t.newton + t.rescues);
  EXPECT_EQ(t.runs[kStageFactorization], t.runs[kStageSolve]);
  EXPECT_EQ(t.runs[kStageAssembly], t.newton);
  EXPECT_TRUE(t.converged);
}

}  // namespace
}  // namespace incise
