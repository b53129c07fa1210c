// The collision stage and the contact response in the step: a probe pressed
// into a block reaches a static equilibrium whose contact force balances the
// supports and the weight, with the penetration held below tolerance in every
// frame; a probe on one side of a cut leaves the other side alone; the
// collision tree is refitted, and rebuilt only after a topology change.
#include <algorithm>
#include <cmath>
#include <functional>

#include <gtest/gtest.h>

#include "collision/collision_stage.h"
#include "engine/util/error.h"
#include "cutting/cut_stage.h"
#include "engine/dynamics/step.h"
#include "engine/output/display_mesh.h"
#include "tests/collision/collision_test_util.h"

namespace incise {
namespace {

using PoseAt = std::function<ToolPose(double t)>;

// The tissue block of the instrument tests (E = 30 kPa), heavily damped.
Scene tissue_block() { return test::tissue_block_scene(3e4, 8.0); }

InstrumentSpec probe(double radius) {
  InstrumentSpec p;
  p.kind = InstrumentSpec::Kind::Probe;
  p.radius = radius;
  p.json_path = "instruments[0]";
  return p;
}

// The simulation with a scripted tool-poses stage (tools/ reads trajectories;
// here the pose is a function of time) and the collision stage.
std::unique_ptr<Simulation> make_probe_sim(const Mesh& mesh, const Scene& scene, PoseAt pose_at) {
  auto sim = test::make_sim(mesh, scene);
  sim->tools.assign(scene.instruments.size(), ToolFrame{});
  for (auto& f : sim->tools) f.before = f.after = pose_at(0.0);
  sim->pipeline.set(kStageToolPoses, [pose_at](Simulation& s) {
    for (auto& f : s.tools) {
      f.before = pose_at(s.state.time);
      f.after = pose_at(s.state.time + s.model.dt);
    }
  });
  install_collision_stage(*sim);
  return sim;
}

// Deepest penetration of instrument 0, at its pose at the frame's end, into
// the tissue as the step left it (a fresh collision model).
double penetration_after_step(const Simulation& sim) {
  CollisionModel check(sim.scene.render.subdivision);
  check.sync(sim.model, sim.state, sim.model_version);
  return max_penetration(check, instrument_shape(sim, 0, sim.tools[0].after));
}

ToolPose at(double x, double y, double z) {
  ToolPose p;
  p.p = {x, y, z};
  return p;
}

TEST(CollisionStage, AScalpelOrNoInstrumentBuildsNoCollisionModel) {
  const Mesh mesh = make_beam(0.1, 0.1, 0.05, 2, 2, 1, 1);
  Scene scene = tissue_block();
  for (int with_scalpel = 0; with_scalpel < 2; ++with_scalpel) {
    if (with_scalpel) {
      InstrumentSpec s;
      s.kind = InstrumentSpec::Kind::Scalpel;
      s.blade = {0.02, 0.001, 0.01};
      s.edge = {Vec3{-0.01, 0, 0}, Vec3{0.01, 0, 0}};
      s.contact = false;
      s.json_path = "instruments[0]";
      scene.instruments.push_back(s);
    }
    auto sim = make_probe_sim(mesh, scene, [](double) { return at(1, 1, 1); });
    EXPECT_FALSE(sim->pipeline.has(kStageCollision));
    EXPECT_EQ(sim->module_data[kStageCollision], nullptr);
    const FrameTiming t = advance_frame(*sim);
    EXPECT_EQ(t.runs[kStageCollision], 0);
    EXPECT_EQ(t.runs[kStageContact], 0);
  }
}

// A probe more than half its radius inside the tissue: at the first frame
// the scene is refused (a 5 cm probe started 10 cm inside organ_3k crushed
// it and the run exited 0); later in a run (the tissue not pushed out) a
// warning says so, once. Half a radius
// in is allowed (probe-incision-10k starts 1.4 mm into its 1 cm probe).
TEST(CollisionStage, AProbeDeepInsideTheTissueIsRefusedAtTheStartAndNamedLater) {
  const Mesh mesh = test::tissue_block_mesh();  // top face at z = 0.05
  Scene scene = tissue_block();
  const double r = 0.01, top = 0.05;
  scene.instruments.push_back(probe(r));
  scene.path = "block.json";
  for (const double start_depth : {0.4 * r, 0.8 * r}) {
    auto sim = make_probe_sim(mesh, scene, [&](double) { return at(0.05, 0.05, top + r - start_depth); });
    if (start_depth < 0.5 * r) {
      EXPECT_NO_THROW(advance_frame(*sim));
      continue;
    }
    try {
      advance_frame(*sim);
      ADD_FAILURE() << "a probe started " << start_depth << " m deep was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("block.json: instruments[0] starts 0.008"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("move the first pose of its trajectory out of the tissue"), std::string::npos)
          << e.what();
    }
  }
  // Above the surface, then 3 radii down at 0.4 radii a frame (under the
  // sweep's half radius) and held there: the face rows let the probe sink
  // into the faces between them (the face rows' limit). (A jab 1.5 radii
  // down in one frame warns too, unless contact.sweep is on:
  // AProbeJabbedPastTheSurfaceInOneFramePushesAsASlowPressDoes.)
  Scene small = scene;
  const double rs = 0.005;  // a fifth of the elements' size
  small.instruments[0].radius = rs;
  auto sim = make_probe_sim(mesh, small, [&](double t) {
    return at(0.045, 0.055, top + rs + 0.001 - std::clamp((t - 0.1) * 0.4 * rs / scene.dt, 0.0, 3 * rs));
  });
  testing::internal::CaptureStderr();
  for (int k = 0; k < 15; ++k) advance_frame(*sim);
  const std::string err = testing::internal::GetCapturedStderr();
  const size_t at_warning = err.find("block.json: instruments[0] went ");
  ASSERT_NE(at_warning, std::string::npos) << err;
  EXPECT_NE(err.find("more than half its radius (0.005 m)"), std::string::npos) << err;
  EXPECT_EQ(err.find("block.json: instruments[0] went ", at_warning + 1), std::string::npos) << "warned more than once: " << err;
}

// Rows per face (the default) and per triangle: one row per face holds one
// point of each face, so the rest of a face the probe covers (2.5 cm faces
// under a 3 cm ball) may stay up to 9% of the indent inside it (measured
// 9.3%; at each face's deepest point 0.6%, but the force chatters:
// AHeldProbesForceSettlesFrameToFrame); per triangle 2%.
class PressedProbe : public ::testing::TestWithParam<ContactSettings::Rows> {};

TEST_P(PressedProbe, BalancesSupportsAndWeight) {
  const Mesh mesh = test::tissue_block_mesh();
  Scene scene = tissue_block();
  scene.contact.rows = GetParam();
  const double r = 0.015, top = 0.05, indent = 0.006;
  scene.instruments.push_back(probe(r));
  // Down from 2 mm above the surface to `indent` deep in 0.5 s, then held.
  auto sim = make_probe_sim(mesh, scene, [&](double t) {
    const double s = std::min(t / 0.5, 1.0);
    return at(0.05, 0.05, top + r + 0.002 - s * (0.002 + indent));
  });
  const double tol = (GetParam() == ContactSettings::Rows::Triangle ? 0.02 : 0.12) * indent;
  double worst = 0.0;
  int rebuilds = 0, refits = 0;
  for (int k = 0; k < 120; ++k) {
    const FrameTiming t = advance_frame(*sim);
    EXPECT_EQ(t.runs[kStageCollision], 1);
    rebuilds += t.bvh_rebuilds;
    refits += t.bvh_refits;
    worst = std::max(worst, penetration_after_step(*sim));
  }
  EXPECT_LT(worst, tol) << "penetration after the step, in every frame";
  EXPECT_EQ(rebuilds, 1) << "built once; no topology change, no rebuild";
  EXPECT_EQ(refits, 119);
  RecordProperty("worst_penetration_over_indent", std::to_string(worst / indent));
  // Static equilibrium: f_int = f_gravity + f_contact on the free DOFs; the
  // supports carry S = f_int - f_gravity on the fixed ones.
  const Model& m = sim->model;
  internal_forces(m, sim->state, sim->ws, sim->state.u.data(), false);
  double support = 0.0, weight = 0.0;
  for (int d : m.fixed_dofs)
    if (d % 3 == 2) support += sim->ws.f_int[d] - m.f_gravity[d];
  for (int d = 2; d < m.ndof(); d += 3) weight -= m.f_gravity[d];
  const ContactRows& c = sim->ws.contacts;
  double Fz = 0.0;
  for (int i = 0; i < c.nrow(); ++i) Fz += c.lambda[i] * c.dir[3 * i + 2];
  ASSERT_LT(Fz, 0.0) << "the probe pushes down";
  EXPECT_NEAR(support - weight, -Fz, 0.01 * -Fz) << "support " << support << " weight " << weight;
  double vmax = 0.0;
  for (double v : sim->state.v) vmax = std::max(vmax, std::abs(v));
  EXPECT_LT(vmax, 1e-3 * indent / sim->model.dt) << "settled";
}

INSTANTIATE_TEST_SUITE_P(CollisionStage, PressedProbe,
                         ::testing::Values(ContactSettings::Rows::Face, ContactSettings::Rows::Triangle),
                         [](const auto& info) {
                           return info.param == ContactSettings::Rows::Face ? "RowsPerFace" : "RowsPerTriangle";
                         });

// The total contact force on the tissue in each of `frames` frames of a
// probe (r = 1 cm) pressed 6 mm into the block in 0.5 s and held, with the
// organ_instruments material (per-point rotations, consistent tangent,
// light damping) and the given contact rows.
std::vector<double> held_probe_force(ContactSettings::Rows rule, int subdivision, int frames) {
  const Mesh mesh = test::tissue_block_mesh();
  Scene scene = tissue_block();
  scene.material.rayleigh_mass = 1.0;
  scene.material.rayleigh_stiffness = 0.002;
  scene.consistent_tangent = true;
  scene.contact.rows = rule;
  scene.contact.max_rows = 1000;
  scene.render.subdivision = subdivision;
  const double r = 0.01, top = 0.05, indent = 0.006;
  scene.instruments.push_back(probe(r));
  auto sim = make_probe_sim(mesh, scene, [&](double t) {
    const double s = std::min(t / 0.5, 1.0);
    return at(0.045, 0.055, top + r + 0.002 - s * (0.002 + indent));
  });
  std::vector<double> F;
  for (int k = 0; k < frames; ++k) {
    advance_frame(*sim);
    const ContactRows& c = sim->ws.contacts;
    double f[3] = {0, 0, 0};
    for (int i = 0; i < c.nrow(); ++i)
      for (int d = 0; d < 3; ++d) f[d] += c.lambda[i] * c.dir[3 * i + d];
    F.push_back(std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]));
  }
  return F;
}

// Mean of |F_k - F_k-1| / mean F over frames [from, F.size()).
double relative_force_change(const std::vector<double>& F, int from) {
  double change = 0.0, mean = 0.0;
  for (size_t k = from; k < F.size(); ++k) change += std::abs(F[k] - F[k - 1]), mean += F[k];
  return change / mean;
}

// Held still, the probe's force must settle. With each face's row at its
// deepest point the deepest point and its normal jump between places of a
// face the probe covers, and the force alternates frame to frame for the
// whole hold (measured 7.4% here; +-12% on organ_instruments); at the face's
// weighted point (collision/face_contact.h) it changes by 0.3%. The force
// itself is checked against one row per triangle on a surface refined 8x
// per face edge (the converged contact: 4.30 N at 4x, 4.26 N at 8x; the
// weighted rows 4.23 N).
TEST(CollisionStage, AHeldProbesForceSettlesFrameToFrame) {
  const int frames = 60, hold = 30;  // the probe stops at frame 15
  const std::vector<double> face = held_probe_force(ContactSettings::Rows::Face, 2, frames);
  const std::vector<double> deepest = held_probe_force(ContactSettings::Rows::FaceDeepest, 2, frames);
  const std::vector<double> fine = held_probe_force(ContactSettings::Rows::Triangle, 8, frames);
  EXPECT_LT(relative_force_change(face, hold), 0.01);
  EXPECT_GT(relative_force_change(deepest, hold), 0.03) << "the deepest point chatters (what the test guards)";
  EXPECT_LT(relative_force_change(fine, hold), 0.01) << "the reference settles";
  double mean_face = 0.0, mean_fine = 0.0;
  for (int k = hold; k < frames; ++k) mean_face += face[k] / (frames - hold), mean_fine += fine[k] / (frames - hold);
  EXPECT_NEAR(mean_face, mean_fine, 0.03 * mean_fine) << "the weighted rows' force against the converged contact";
  RecordProperty("force_change_face", std::to_string(relative_force_change(face, hold)));
  RecordProperty("force_change_face_deepest", std::to_string(relative_force_change(deepest, hold)));
  RecordProperty("force_face_over_converged", std::to_string(mean_face / mean_fine));
}

// A probe jabbed into the block faster than its radius a frame (1.2 cm in
// one frame for a 5 mm probe, its centre 7 mm below the top face as the
// frame began): a face its axis has passed keeps the face rule's direction
// (-n_out) instead of the weighted point's, which pulled the tissue out
// through the probe. Before, the probe ended the jab inside the block at
// 0 N with no contact row, and stayed there. (A jab whose end pose lies
// wholly below the top face: the next test.)
TEST(CollisionStage, AProbeJabbedFasterThanItsRadiusAFramePushesTheTissue) {
  Scene scene = tissue_block();
  scene.consistent_tangent = true;
  const double r = 0.005, top = 0.05, press = 0.012;
  scene.instruments.push_back(probe(r));
  const double t0 = 0.1, dt = scene.dt;
  auto sim = make_probe_sim(test::tissue_block_mesh(), scene, [&](double t) {
    return at(0.045, 0.055, top + r + 0.0005 - (t >= t0 + 0.5 * dt ? press : 0.0));  // one frame's jump
  });
  int frames = 0, held = 0, lost = 0;
  double f_min = 1e300;
  while (sim->state.time < 0.6) {
    advance_frame(*sim);
    ++frames;
    if (sim->state.time < t0 + 2 * dt) continue;
    const ContactRows& c = sim->ws.contacts;
    double f = 0;
    for (int i = 0; i < c.nrow(); ++i) f += c.lambda[i] * c.dir[3 * i + 2];
    ++held;
    lost += c.nrow() == 0;
    f_min = std::min(f_min, -f);  // pushed down: the force on the tissue along -z
  }
  ASSERT_GT(held, 10);
  EXPECT_EQ(lost, 0) << "frames of the hold without a contact row";
  EXPECT_GT(f_min, 0.0) << "the probe pushes the tissue in every frame of the hold";
  // The top under the probe went down with it (most of the press).
  double uz = 0;
  for (int i = 0; i < sim->model.nnode; ++i) {
    const double* X = &sim->model.X[3 * i];
    if (std::abs(X[2] - top) < 1e-9 && std::hypot(X[0] - 0.045, X[1] - 0.055) < 0.015) uz = std::min(uz, sim->state.u[3 * i + 2]);
  }
  EXPECT_LT(uz, -0.5 * (press - 0.0005)) << "the deepest top node under the probe";
  RecordProperty("penetration_after_hold_mm", std::to_string(1000 * penetration_after_step(*sim)));
}

// A probe jabbed past the surface in one frame: 2.2 cm for an 8 mm probe,
// so that its end pose lies wholly below the top face it started above
// (with its detection margin too). Without the sweep (contact.sweep, off
// by default) it ends inside the block untouched at 0 N (no row) and stays
// there. With it, the faces it
// went through are pushed out ahead of it, and the hold that follows is
// the one the same press reached over 8 frames (each under half the
// radius: no sweep) gives: the top near the probe within 3% of the press
// (measured: 0.3%), the force and the penetration averaged over the hold
// within 10% (6%) and 1.25x (1.05x). A sphere held deeper than its
// diameter has the tissue closed over it, and one row per face then lets
// the held force vary by 10-20% from frame to frame and the probe sink
// 3-8 mm into the faces between rows in both runs, hence the averages:
// that is the face rows' limit (docs/next-steps.md), not the sweep's.
TEST(CollisionStage, AProbeJabbedPastTheSurfaceInOneFramePushesAsASlowPressDoes) {
  Scene scene = tissue_block();
  scene.consistent_tangent = true;
  scene.contact.sweep = true;
  const double r = 0.008, top = 0.06, press = 0.022, x0 = 0.045, y0 = 0.055;
  const Mesh mesh = make_beam(0.1, 0.1, top, 6, 6, 4, 1);
  scene.instruments.push_back(probe(r));
  const double t0 = 0.1, dt = scene.dt;
  double uz[2] = {0, 0}, f_mean[2] = {0, 0}, pen_mean[2] = {0, 0}, uz_jab = 0;
  // The deepest top node near the probe's axis (none lies under it).
  auto top_uz = [&](const Simulation& sim) {
    double u = 0;
    for (int i = 0; i < sim.model.nnode; ++i) {
      const double* X = &sim.model.X[3 * i];
      if (std::abs(X[2] - top) < 1e-9 && std::hypot(X[0] - x0, X[1] - y0) < 0.015) u = std::min(u, sim.state.u[3 * i + 2]);
    }
    return u;
  };
  for (int fast = 0; fast < 2; ++fast) {
    auto sim = make_probe_sim(mesh, scene, [&](double t) {
      const double k = fast ? (t >= t0 + 0.5 * dt ? 1.0 : 0.0) : std::clamp((t - t0) / (8 * dt), 0.0, 1.0);
      return at(x0, y0, top + r + 0.0005 - k * press);
    });
    int lost = 0, held = 0;
    double f_min = 1e300;
    while (sim->state.time < 0.7) {
      advance_frame(*sim);
      if (fast && std::abs(sim->state.time - (t0 + dt)) < 0.5 * dt) uz_jab = top_uz(*sim);
      if (sim->state.time < t0 + 10 * dt) continue;
      const ContactRows& c = sim->ws.contacts;
      double f = 0;
      for (int i = 0; i < c.nrow(); ++i) f += c.lambda[i] * c.dir[3 * i + 2];
      ++held;
      lost += c.nrow() == 0;
      f_min = std::min(f_min, -f);
      f_mean[fast] -= f;
      pen_mean[fast] += penetration_after_step(*sim);
    }
    ASSERT_GT(held, 5);
    f_mean[fast] /= held;
    pen_mean[fast] /= held;
    const char* run = fast ? "jab" : "slow press";
    EXPECT_EQ(lost, 0) << run << ": frames of the hold without a contact row";
    EXPECT_GT(f_min, 0.0) << run << ": the probe pushes in every frame of the hold";
    uz[fast] = top_uz(*sim);
    RecordProperty(fast ? "jab_top_mm" : "slow_top_mm", std::to_string(1000 * uz[fast]));
    RecordProperty(fast ? "jab_mean_force_N" : "slow_mean_force_N", std::to_string(f_mean[fast]));
    RecordProperty(fast ? "jab_mean_penetration_mm" : "slow_mean_penetration_mm", std::to_string(1000 * pen_mean[fast]));
  }
  EXPECT_LT(uz_jab, -0.5 * press) << "the jab's own frame took the top down";
  EXPECT_LT(uz[0], -0.75 * press) << "the slow press took the top down with it";
  EXPECT_NEAR(uz[1], uz[0], 0.03 * press) << "the jab's top against the slow press's, held";
  EXPECT_NEAR(f_mean[1], f_mean[0], 0.1 * f_mean[0]) << "the held force, averaged over the hold";
  EXPECT_LT(pen_mean[1], 1.25 * pen_mean[0]) << "the jab's penetration while held, against the slow press's";
  RecordProperty("jab_frame_top_mm", std::to_string(1000 * uz_jab));
}

// Soft tissue as the bundled beam scenes have it (nu 0.45, rho 1000,
// Rayleigh 1.0 / 0.002, consistent tangent), clamped at x = 0.
Scene clamped_soft_scene(double young) {
  Scene scene = test::block_scene(2);
  scene.material.young = young;
  scene.material.poisson = 0.45;
  scene.material.density = 1000;
  scene.material.rayleigh_mass = 1.0;
  scene.material.rayleigh_stiffness = 0.002;
  scene.consistent_tangent = true;
  scene.fixed.push_back(test::box({-1, -1, -1}, {1e-9, 1, 1}));
  return scene;
}

// contact.sweep on a probe that goes through tissue within a frame: a
// 5 mm probe jabbed 2 cm down through a 4 mm plate (clamped at both ends),
// its end pose across the plate's underside. Its path crosses the plate,
// so there is no side for the struck faces to go to but a tear: no swept
// rows, as without the sweep. Without the crossing checks the top faces
// were pushed to the end pose's far side: 14 swept rows, 43 inverted
// points, 6.1 N here (90 N and 297 inverted points under realtime).
TEST(CollisionStage, ASweptProbeThatGoesThroughAPlateTakesNoSweptRows) {
  Scene scene = clamped_soft_scene(3e5);
  scene.contact.sweep = true;
  scene.fixed.push_back(test::box({0.06 - 1e-9, -1, -1}, {1, 1, 1}, "fixed[1]"));
  const double r = 0.005, t0 = 0.1;
  scene.instruments.push_back(probe(r));
  auto sim = make_probe_sim(make_beam(0.06, 0.06, 0.004, 12, 12, 1, 1), scene,
                            [&](double t) { return at(0.03, 0.03, t >= t0 + 0.5 * scene.dt ? -0.003 : 0.017); });
  int swept = 0, inverted = 0, frames = 0;
  double force = 0.0;
  while (sim->state.time < 0.5) {
    const FrameTiming ft = advance_frame(*sim);
    ++frames;
    swept += ft.swept_rows;
    inverted = std::max(inverted, ft.inverted_points);
    force = std::max(force, ft.contact_force);
  }
  ASSERT_GT(frames, 10);
  EXPECT_EQ(swept, 0) << "swept rows for a path through the plate";
  EXPECT_EQ(inverted, 0) << "inverted points";
  EXPECT_LT(force, 5.0) << "the largest contact force (N)";
}

// A soft cantilever released from rest under gravity swings its free end
// down onto a resting 5 mm probe at about 1 cm a frame, eight times the
// detection margin. Without speculative rows (contact.speculative, off by
// default) the tissue is inside the probe before any row holds it: 3-8 mm
// deep at the frames' start, and 1.5 N impacts. With them the tissue near
// the probe that may move further than the
// margin in a frame has rows within that reach, inactive until the step
// closes their gap: no frame starts more than a tenth of the radius inside
// (measured 0.25 mm; 7.8 mm without), and the beam's end, 1 cm past the
// probe's axis, stays within a fifth of the radius of the probe's top
// (0.4 mm below it; 13.5 mm without: the beam slid past the probe).
TEST(CollisionStage, TissueSwingingOntoARestingProbeStopsAtItsSurface) {
  Scene scene = clamped_soft_scene(1e5);
  scene.contact.speculative = true;
  const double r = 0.005, pz = -0.035;
  scene.instruments.push_back(probe(r));
  auto sim = make_probe_sim(make_beam(0.1, 0.02, 0.02, 10, 2, 2, 1), scene, [&](double) { return at(0.09, 0.01, pz); });
  double depth_max = 0.0, tip_min = 1.0, force_max = 0.0, reach_frames = 0;
  for (int k = 0; k < 30; ++k) {
    const FrameTiming ft = advance_frame(*sim);
    depth_max = std::max(depth_max, ft.max_depth);
    force_max = std::max(force_max, ft.contact_force);
    reach_frames += ft.speculative_rows > 0;
    // The lowest point of the beam's end face x = 0.1 (its bottom edge).
    for (int i = 0; i < sim->model.nnode; ++i)
      if (std::abs(sim->model.X[3 * i] - 0.1) < 1e-9 && std::abs(sim->model.X[3 * i + 1] - 0.01) < 1e-9)
        tip_min = std::min(tip_min, sim->model.X[3 * i + 2] + sim->state.u[3 * i + 2]);
  }
  EXPECT_GT(force_max, 0.0) << "the beam reached the probe";
  EXPECT_GT(reach_frames, 0) << "frames with speculative rows";
  EXPECT_LT(depth_max, 0.1 * r) << "the deepest penetration at a frame's start";
  EXPECT_GT(tip_min, pz + r - 0.2 * r) << "the tip's lowest point, against the probe's top";
  RecordProperty("depth_max_mm", std::to_string(1000 * depth_max));
  RecordProperty("tip_min_over_probe_top_mm", std::to_string(1000 * (tip_min - pz - r)));
}

// Two halves fixed at the base, cut apart by a vertical plane at x = 0.0475
// (inside a column of elements); the probe presses the left half next to
// the cut. Every display point of the right half moves exactly as it does
// without the probe.
TEST(CollisionStage, AProbeOnOneSideOfACutLeavesTheOtherAlone) {
  const Mesh mesh = test::tissue_block_mesh();
  Scene scene = tissue_block();
  scene.cuts = {test::plane_cut({0.0475, 0, 0}, {1, 0, 0})};
  // One Newton iteration per frame in both runs: the adaptive count is a
  // global decision that the probe's side would change for both sides.
  scene.rotation_tolerance = 0.0;
  const double r = 0.008;
  std::unique_ptr<Simulation> sims[2];
  for (int with = 0; with < 2; ++with) {
    Scene s = scene;
    if (with) s.instruments.push_back(probe(r));
    sims[with] = make_probe_sim(mesh, s, [&](double t) {
      const double k = std::min(t / 0.3, 1.0);
      return at(0.035, 0.05, 0.05 + r + 0.001 - k * 0.005);
    });
  }
  int rebuilds = 0;
  for (int k = 0; k < 15; ++k) {
    advance_frame(*sims[0]);
    rebuilds += advance_frame(*sims[1]).bvh_rebuilds;
  }
  EXPECT_EQ(rebuilds, 2) << "built in frame 1, rebuilt after the cut of frame 1 only";
  const DisplayMesh a = display_mesh(sims[0]->model, sims[0]->state), b = display_mesh(sims[1]->model, sims[1]->state);
  ASSERT_EQ(a.npoint(), b.npoint());
  double right = 0.0, left = 0.0;
  for (int c = 0; c < a.ncell(); ++c) {
    double xc = 0.0;
    for (int k = 0; k < 4; ++k) xc += 0.25 * a.X[3 * a.cells[c * a.npe() + k]];
    for (int k = 0; k < a.npe(); ++k) {
      const int p = a.cells[c * a.npe() + k];
      double d = 0.0;
      for (int j = 0; j < 3; ++j) d = std::max(d, std::abs(a.u[3 * p + j] - b.u[3 * p + j]));
      (xc > 0.0475 ? right : left) = std::max(xc > 0.0475 ? right : left, d);
    }
  }
  EXPECT_GT(left, 1e-3) << "the probe pushed the left half";
  EXPECT_LT(right, 1e-9 * left) << "nothing crossed the cut";
}

}  // namespace
}  // namespace incise
