// The cutting stage in the frame's pipeline, and the State as a value across
// cuts: a copy taken before, during or after an incision continues exactly.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "cutting/cut_stage.h"
#include "engine/dynamics/step.h"
#include "tests/cutting/test_util.h"

namespace incise {
namespace {

// A block fixed at x = 0, incised by a blade sweeping down through it from
// 0.1 s to 0.6 s (frames 3 to 18), then left to swing.
Scene incised_block() {
  Scene s = test::block_scene(2);
  s.material.rayleigh_mass = 0.5;
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  s.cuts = {test::swept_blade({Vec3{2.3, -0.1, 1.2}, Vec3{2.45, 1.1, 1.2}}, {Vec3{2.3, -0.1, -0.1}, Vec3{2.45, 1.1, -0.1}}, 0.5)};
  s.cuts[0].at_time = 0.1;
  return s;
}

// Runs `a` to frame `copy_at`, puts a copy of its State (and the Model it
// stands on) into a second simulation, then steps both; every later frame
// must hash the same.
void copy_and_continue(int copy_at, int frames) {
  const Mesh mesh = make_beam(4, 1, 1, 8, 2, 2, 1);
  auto a = test::make_sim(mesh, incised_block());
  auto b = test::make_sim(mesh, incised_block());
  for (int k = 0; k < copy_at; ++k) advance_frame(*a);
  restore_state(*b, a->model, a->state);
  int cut_frames = 0;
  for (int k = 0; k < frames; ++k) {
    cut_frames += advance_frame(*a).cut_frame;
    advance_frame(*b);
    ASSERT_EQ(a->model.ndof(), b->model.ndof()) << "frame " << a->state.frame;
    ASSERT_EQ(state_hash(a->state), state_hash(b->state)) << "frame " << a->state.frame;
  }
  EXPECT_TRUE(a->state == b->state);
  if (copy_at < 18) {
    EXPECT_GT(cut_frames, 0) << "the copy went through cut frames";
  }
  EXPECT_GT(a->model.cuts.n_enriched, 0);
}

TEST(CutStage, AStateCopiedBeforeTheCutContinuesBitForBit) { copy_and_continue(2, 100); }
TEST(CutStage, AStateCopiedDuringTheIncisionContinuesBitForBit) { copy_and_continue(9, 100); }
TEST(CutStage, AStateCopiedAfterTheCutContinuesBitForBit) { copy_and_continue(25, 100); }

TEST(CutStage, OnlyAScenesWithCutsHaveTheStage) {
  const Mesh mesh = make_beam(4, 1, 1, 4, 1, 1, 1);
  Scene uncut = incised_block();
  uncut.cuts.clear();
  auto plain = test::make_sim(mesh, uncut);
  auto cut = test::make_sim(mesh, incised_block());
  EXPECT_FALSE(plain->pipeline.has(kStageCutting));
  EXPECT_TRUE(cut->pipeline.has(kStageCutting));
  int cut_runs = 0, plain_runs = 0, cut_frames = 0;
  for (int k = 0; k < 20; ++k) {
    const FrameTiming t = advance_frame(*cut);
    cut_runs += t.runs[kStageCutting];
    cut_frames += t.cut_frame;
    plain_runs += advance_frame(*plain).runs[kStageCutting];
  }
  EXPECT_EQ(plain_runs, 0);
  EXPECT_EQ(cut_runs, 20);
  EXPECT_GT(cut_frames, 2) << "the progressive cut changed the model in several frames";
  EXPECT_EQ(cut->state.cut_progress.size(), 1u);
  EXPECT_DOUBLE_EQ(cut->state.cut_progress[0], 1.0) << "the sweep ended at 0.6 s";
}

// initial "static" with a cut due at t = 0 (a partial slit declared in the
// scene): the scene starts at the equilibrium of the cut beam, at rest. The
// equilibrium used to be the uncut one (load_simulation cannot cut), the
// first frame cut, and the beam moved at once (0.57 m/s at frame 1 on
// assets/scenes/beam_partial_slit.json).
TEST(CutStage, AnInitialStaticSceneStartsAtRestWithItsCutsAtTimeZero) {
  Scene s = test::block_scene(2);
  s.material.young = 1e3;
  s.material.rayleigh_mass = 1.0;
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  CutSpec slit;  // x = 2.05 from the top down to z = 0.4
  slit.type = CutSpec::Type::Polygon;
  slit.points = {{2.05, -1, 0.4}, {2.05, 2, 0.4}, {2.05, 2, 3}, {2.05, -1, 3}};
  slit.json_path = "cuts[0]";
  s.cuts = {slit};
  s.initial_static = true;
  auto sim = test::make_sim(make_beam(4, 1, 1, 8, 2, 2, 1), s);
  EXPECT_TRUE(sim->model.has_cuts()) << "the cut applied before frame 0";
  double sag = 0;
  for (int i = 0; i < sim->model.nnode; ++i) sag = std::max(sag, std::abs(sim->state.u[3 * i + 2]));
  ASSERT_GT(sag, 1e-3);
  double vmax = 0;
  int cut_frames = 0;
  for (int k = 0; k < 5; ++k) {
    cut_frames += advance_frame(*sim).cut_frame;
    for (double v : sim->state.v) vmax = std::max(vmax, std::abs(v));
  }
  EXPECT_EQ(cut_frames, 0);
  EXPECT_LT(vmax * sim->model.dt, 1e-3 * sag) << "at rest: moved less than 0.1% of the sag a frame";
}

}  // namespace
}  // namespace incise
