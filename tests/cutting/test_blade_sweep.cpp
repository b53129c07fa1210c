// Cuts made by a scalpel (cutting/blade_sweep.cpp): world points mapped back
// to the reference configuration, and a blade driven through a block that
// separates it: the free piece falls freely, no force crosses the cut.
#include <cmath>

#include <gtest/gtest.h>

#include "cutting/blade_sweep.h"
#include "cutting/cut_surface.h"
#include "cutting/xfem_layout.h"
#include "engine/dynamics/step.h"
#include "tests/cutting/test_util.h"

namespace incise {
namespace {

// Under an affine deformation x = F X + c the corner map is exact, inside and
// (extrapolated) outside the body.
TEST(BladeSweep, ReferencePointInvertsAnAffineDeformation) {
  const Mesh mesh = make_beam(2, 1, 1, 4, 2, 2, 2);
  const Model m = build_model(mesh, test::block_scene(2));
  State s;
  size_state(m, s);
  const double F[3][3] = {{1.1, 0.2, 0.0}, {-0.1, 0.9, 0.05}, {0.0, 0.1, 1.2}}, c[3] = {0.3, -0.2, 0.1};
  for (int i = 0; i < m.nnode; ++i)
    for (int d = 0; d < 3; ++d) {
      double x = c[d];
      for (int k = 0; k < 3; ++k) x += F[d][k] * m.X[3 * i + k];
      s.u[3 * i + d] = x - m.X[3 * i + d];
    }
  for (const Vec3 X0 : {Vec3{0.7, 0.3, 0.6}, Vec3{1.9, 0.95, 0.05}, Vec3{2.5, 0.5, 0.5}, Vec3{-0.4, 1.3, 0.2}}) {
    double x[3];
    for (int d = 0; d < 3; ++d) x[d] = c[d] + F[d][0] * X0[0] + F[d][1] * X0[1] + F[d][2] * X0[2];
    bool inside = false;
    const auto X = reference_point(m, s, x, &inside);
    const bool in_body = X0[0] >= 0 && X0[0] <= 2 && X0[1] >= 0 && X0[1] <= 1 && X0[2] >= 0 && X0[2] <= 1;
    EXPECT_EQ(inside, in_body) << X0[0] << " " << X0[1] << " " << X0[2];
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(X[d], X0[d], 1e-12);
  }
}

constexpr int kFrames = 8;  // of the sweep

// A block fixed at x = 0; a scalpel whose edge spans the block's height
// moves across it at x = 1.25 in 8 frames: the block is then two bodies
// and the one beyond the cut falls.
TEST(BladeSweep, AScalpelDrivenThroughABlockSeparatesIt) {
  const Mesh mesh = make_beam(2, 1, 1, 4, 2, 2, 2);
  Scene scene = test::block_scene(2);
  scene.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  InstrumentSpec scalpel;
  scalpel.kind = InstrumentSpec::Kind::Scalpel;
  scalpel.blade = {0.2, 0.01, 0.1};
  scalpel.edge = {Vec3{0, 0, -0.3}, Vec3{0, 0, 1.3}};  // vertical, through the whole height
  scalpel.contact = false;
  scalpel.json_path = "instruments[0]";
  scene.instruments.push_back(scalpel);
  auto sim = test::make_sim(mesh, scene);
  ASSERT_TRUE(sim->pipeline.has(kStageCutting)) << "a scalpel calls for the cutting stage";
  // The tool-poses stage (tools/ fills it from a trajectory): y from -0.3 to 1.3.
  sim->pipeline.set(kStageToolPoses, [](Simulation& s) {
    const auto y = [](int f) { return -0.3 + 1.6 * std::min(f, kFrames) / kFrames; };
    s.tools.resize(1);
    s.tools[0].before.p = std::array<double, 3>{1.25, y(s.state.frame), 0.0};
    s.tools[0].after.p = std::array<double, 3>{1.25, y(s.state.frame + 1), 0.0};
  });
  int cut_frames = 0;
  for (int k = 0; k < kFrames + 4; ++k) cut_frames += advance_frame(*sim).cut_frame;
  EXPECT_GT(cut_frames, 0);
  // Bands of the frames whose edge meets the body (the first and last pass outside it).
  EXPECT_EQ(sim->state.swept_tool.size(), static_cast<size_t>(2 * kSweepSegments * (kFrames - 2)));
  EXPECT_GT(sim->model.cuts.n_enriched, 0);
  // Two bodies now: the layout of the swept surface on the uncut mesh.
  auto surface = make_swept_surface(sim->state.swept, sim->state.swept_tool, 0, "instruments[0]");
  ASSERT_TRUE(surface);
  CutReport report;
  compute_cut_layout(build_model(mesh, scene), {surface.get()}, &report);
  EXPECT_EQ(report.bodies, 2);
  // The free piece falls: over the frames after the separation its far end
  // drops by about g t^2 / 2 (its elastic vibration aside), far more than the
  // fixed cantilever's sag.
  // Mean vertical value of a field (u or v) over the far end's mesh nodes.
  const auto end_mean = [&](const std::vector<double>& f) {
    double z = 0;
    int n = 0;
    for (int i = 0; i < sim->model.nnode; ++i)
      if (sim->model.X[3 * i] > 2.0 - 1e-9) z += f[3 * i + 2], ++n;
    return z / n;
  };
  const double z0 = end_mean(sim->state.u), v0 = end_mean(sim->state.v);
  const int fall_frames = 15;
  for (int k = 0; k < fall_frames; ++k) advance_frame(*sim);
  const double t = fall_frames * sim->model.dt, expect = v0 * t - 0.5 * 9.81 * t * t;
  EXPECT_NEAR(end_mean(sim->state.u) - z0, expect, 0.1 * std::abs(expect));
}

}  // namespace
}  // namespace incise
