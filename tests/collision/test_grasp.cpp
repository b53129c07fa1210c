// Grasping (collision/grasp.cpp): a grasper closes on the free end of a flap
// (a block partly cut along a horizontal plane), lifts it, lets it go, and
// the flap falls back.
#include <algorithm>
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "collision/collision_stage.h"
#include "engine/dynamics/step.h"
#include "tests/collision/collision_test_util.h"

namespace incise {
namespace {

constexpr double kLift = 0.02;

// Tool pose at t: jaws across world z (90 deg about x: tool y -> world z),
// centred on the flap's free end; closes in 0.2 s, lifts kLift by 0.7 s,
// opens from 0.9 s to 1.0 s.
ToolPose grasper_pose(double t, bool close = true, double above = 0.0) {
  ToolPose p;
  const double lift = kLift * std::clamp((t - 0.2) / 0.5, 0.0, 1.0);
  p.p = {0.1, 0.05, 0.0405 + lift + above};
  p.q = {std::sqrt(0.5), std::sqrt(0.5), 0.0, 0.0};
  p.jaw = !close ? 0.0 : t < 0.2 ? t / 0.2 : (t < 0.9 ? 1.0 : std::max(0.0, 1.0 - (t - 0.9) / 0.1));
  return p;
}

// Mean vertical displacement of the flap's free end (mesh nodes at x = 0.1 above the cut).
double flap_end_lift(const Simulation& sim) {
  double z = 0.0;
  int n = 0;
  for (int i = 0; i < sim.model.nnode; ++i)
    if (sim.model.X[3 * i] > 0.1 - 1e-9 && sim.model.X[3 * i + 2] > 0.045) z += sim.state.u[3 * i + 2], ++n;
  return z / n;
}

std::unique_ptr<Simulation> flap_sim(bool close, double above = 0.0, bool lagged = false) {
  const Mesh mesh = test::tissue_block_mesh();
  Scene scene = test::tissue_block_scene(3e5, 4.0);
  // The flap: 2 cm thick, a horizontal cut at z = 0.03 under x > 0.03 (hinged at x = 0.03).
  CutSpec cut;
  cut.type = CutSpec::Type::Polygon;
  cut.points = {Vec3{0.03, -0.01, 0.03}, Vec3{0.12, -0.01, 0.03}, Vec3{0.12, 0.11, 0.03}, Vec3{0.03, 0.11, 0.03}};
  cut.json_path = "cuts[0]";
  scene.cuts = {cut};
  InstrumentSpec g;
  g.kind = InstrumentSpec::Kind::Grasper;
  g.jaw_size = {0.01, 0.004, 0.02};
  g.opening = 0.02;
  g.contact = false;  // its jaws would press the block below the flap; here it only holds
  g.json_path = "instruments[0]";
  scene.instruments.push_back(g);
  if (lagged) scene.solver.policy = SolverPolicy::Lagged;
  auto sim = test::make_sim(mesh, scene);
  sim->tools.assign(1, ToolFrame{});
  sim->pipeline.set(kStageToolPoses, [close, above](Simulation& s) {
    s.tools[0].before = grasper_pose(s.state.time, close, above);
    s.tools[0].after = grasper_pose(s.state.time + s.model.dt, close, above);
  });
  install_collision_stage(*sim);
  return sim;
}

TEST(Grasp, AGrasperLiftsAFlapAndLetsItFallBack) {
  auto sim = flap_sim(true);
  ASSERT_TRUE(sim->pipeline.has(kStageCollision));
  double held_lift = 0.0;
  int held_frames = 0;
  while (sim->state.time < 0.85) {
    const FrameTiming t = advance_frame(*sim);
    if (sim->state.time > 0.75) {
      EXPECT_GT(t.grasp_rows, 0);
      held_lift = flap_end_lift(*sim);
      ++held_frames;
    }
  }
  EXPECT_GT(held_frames, 0);
  // The held points are where the jaws carry them, to roundoff.
  const CollisionData& cd = *collision_data(*sim);
  ASSERT_TRUE(cd.grasps[0].holding);
  ASSERT_FALSE(cd.grasps[0].held.empty());
  CollisionModel now(2);
  now.sync(sim->model, sim->state, sim->model_version);
  for (const HeldPoint& h : cd.grasps[0].held) {
    const PointWeights w = now.surface().point_weights(h.elem, h.piece, h.rst);
    double X[3], x[3];
    now.surface().reference_position(h.elem, h.rst, X);
    point_position(w, X, sim->state.u.data(), x);
    const auto goal = tool_to_world(grasper_pose(sim->state.time), {h.local[0], h.local[1], h.local[2]});
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(x[d], goal[d], 1e-9 * kLift);
  }
  // The flap's end came up with them (it bends about its hinge).
  EXPECT_GT(held_lift, 0.5 * kLift);
  while (sim->state.time < 3.0) {
    const FrameTiming t = advance_frame(*sim);
    if (sim->state.time > 1.05) {
      EXPECT_EQ(t.grasp_rows, 0) << "let go at t = " << sim->state.time;
    }
  }
  // Back to where the same flap rests when never grasped (hanging a little
  // into the block below: the cut's faces do not touch each other).
  auto untouched = flap_sim(false);
  while (untouched->state.time < 3.0) advance_frame(*untouched);
  EXPECT_NEAR(flap_end_lift(*sim), flap_end_lift(*untouched), 0.02 * held_lift) << "the flap fell back";
}

// A probe pressed onto the flap's end where the grasper holds it asks the
// held points to be in two places: with the probe's rows on the held
// elements' faces beside the grasp's, the LCP had no solution (pressed 2
// cm, measured without the rule: 130 N and 14 inverted points under
// `exact`, 6.7 kN and 492 under `lagged`). Those rows are left out (a
// warning says so, once): the grasp keeps its points where the jaws carry
// them, nothing inverts, the force stays that of the grasp (9.8 N), and the
// probe's rows elsewhere still push.
TEST(Grasp, AProbePressingTissueTheGrasperHoldsLeavesTheGraspAlone) {
  for (const bool lagged : {false, true}) {
    auto sim = flap_sim(true, 0.0, lagged);
    InstrumentSpec probe;
    probe.kind = InstrumentSpec::Kind::Probe;
    probe.radius = 0.006;
    probe.json_path = "instruments[1]";
    probe.name = "probe";
    sim->scene.instruments.push_back(probe);
    install_collision_stage(*sim);
    sim->tools.assign(2, ToolFrame{});
    // The grasp as grasper_pose has it (held from 0.2 s, lifted from 0.2 to 0.7 s);
    // the probe over the jaws' centre, down 2 cm into the held flap's top by 0.6 s.
    const auto probe_pose = [](double t) {
      ToolPose p;
      const double down = 0.02 * std::clamp((t - 0.3) / 0.3, 0.0, 1.0);
      p.p = {0.1, 0.05, 0.05 + 0.006 + kLift * std::clamp((t - 0.2) / 0.5, 0.0, 1.0) - down};
      return p;
    };
    sim->pipeline.set(kStageToolPoses, [probe_pose](Simulation& s) {
      s.tools[0].before = grasper_pose(s.state.time);
      s.tools[0].after = grasper_pose(s.state.time + s.model.dt);
      s.tools[1].before = probe_pose(s.state.time);
      s.tools[1].after = probe_pose(s.state.time + s.model.dt);
    });
    testing::internal::CaptureStderr();
    int dropped = 0, inverted = 0, probe_rows = 0;
    double force = 0.0;
    while (sim->state.time < 0.85) {
      const FrameTiming t = advance_frame(*sim);
      dropped += t.held_rows_dropped;
      inverted = std::max(inverted, t.inverted_points);
      probe_rows += t.contacts;
      force = std::max(force, t.contact_force);
    }
    const std::string err = testing::internal::GetCapturedStderr();
    const char* what = lagged ? "lagged" : "exact";
    EXPECT_GT(dropped, 0) << what;
    EXPECT_GT(probe_rows, 0) << what << ": the probe's rows off the held elements stay";
    EXPECT_EQ(inverted, 0) << what;
    EXPECT_LT(force, 50.0) << what;  // measured: a few newtons
    const std::string warn = "instruments[1] (\"probe\") pressed tissue that a grasper holds at t = ";
    const size_t at = err.find(warn);
    ASSERT_NE(at, std::string::npos) << err;
    EXPECT_EQ(err.find(warn, at + 1), std::string::npos) << "warned more than once: " << err;
    const CollisionData& cd = *collision_data(*sim);
    ASSERT_TRUE(cd.grasps[0].holding);
    CollisionModel now(2);
    now.sync(sim->model, sim->state, sim->model_version);
    for (const HeldPoint& h : cd.grasps[0].held) {  // held where the jaws carry them
      const PointWeights w = now.surface().point_weights(h.elem, h.piece, h.rst);
      double X[3], x[3];
      now.surface().reference_position(h.elem, h.rst, X);
      point_position(w, X, sim->state.u.data(), x);
      const auto goal = tool_to_world(grasper_pose(sim->state.time), {h.local[0], h.local[1], h.local[2]});
      for (int d = 0; d < 3; ++d) EXPECT_NEAR(x[d], goal[d], 1e-6 * kLift) << what;
    }
  }
}

// A grasper with contact closing over a plate thicker than the jaws'
// closed gap: the jaws push it from both sides, and once they do the grasp
// takes hold (before the jaw reaches grasp_at) instead of squeezing the
// tissue between two contacts. Squeezed to grasp_at, a 1.5 cm bite of the
// liver had no solution (618 N, 99 inverted points). Here: held from jaw
// 0.56, no inverted point, 4.6 N at most, and let go once the jaw opens
// below the value it took hold at (measured without the rule: held from
// jaw 1, 1 inverted point, 6.4 N).
TEST(Grasp, JawsThatPressTheTissueFromBothSidesTakeHold) {
  const Mesh mesh = make_beam(0.1, 0.02, 0.05, 5, 2, 3, 1);  // a 2 cm plate, fixed at its base
  Scene scene = test::tissue_block_scene(3e4, 4.0);
  InstrumentSpec g;
  g.kind = InstrumentSpec::Kind::Grasper;
  g.jaw_size = {0.02, 0.004, 0.01};
  g.opening = 0.035;
  g.json_path = "instruments[0]";
  scene.instruments.push_back(g);  // contact: true (the default)
  auto sim = test::make_sim(mesh, scene);
  sim->tools.assign(1, ToolFrame{});
  // Jaws across y over the plate's top edge; closing from 0.1 to 0.4 s, opening from 0.6 to 0.9 s.
  const auto jaw = [](double t) { return std::clamp((t - 0.1) / 0.3, 0.0, 1.0) - std::clamp((t - 0.6) / 0.3, 0.0, 1.0); };
  sim->pipeline.set(kStageToolPoses, [jaw](Simulation& s) {
    for (ToolPose* p : {&s.tools[0].before, &s.tools[0].after}) p->p = {0.05, 0.01, 0.046};
    s.tools[0].before.jaw = jaw(s.state.time);
    s.tools[0].after.jaw = jaw(s.state.time + s.model.dt);
  });
  install_collision_stage(*sim);
  double took = -1.0, let_go = -1.0, force = 0.0;
  int inverted = 0;
  while (sim->state.time < 1.0) {
    const FrameTiming t = advance_frame(*sim);
    const double j = jaw(sim->state.time);
    if (t.grasp_rows > 0 && took < 0) took = j;
    if (took >= 0 && t.grasp_rows == 0 && let_go < 0) let_go = j;
    inverted = std::max(inverted, t.inverted_points);
    force = std::max(force, t.contact_force);
  }
  EXPECT_GT(took, 0.2) << "the jaws' gap is the plate's first (0.035 -> 0.02 m at jaw 0.43)";
  EXPECT_LT(took, 0.8) << "held before grasp_at (0.9)";
  EXPECT_GE(let_go, 0.0) << "let go while opening";
  EXPECT_LT(let_go, took);
  EXPECT_EQ(inverted, 0);
  EXPECT_LT(force, 20.0);
}

// Jaws that close 5 cm above the flap take nothing: a warning says so once
// (it used to hold nothing silently, and the tissue not following looked
// like a solver fault), and again only after they open and close again.
TEST(Grasp, JawsThatCloseOnNothingSayWhyNothingIsHeld) {
  auto sim = flap_sim(true, 0.05);
  testing::internal::CaptureStderr();
  while (sim->state.time < 0.85) advance_frame(*sim);
  const std::string err = testing::internal::GetCapturedStderr();
  const CollisionData& cd = *collision_data(*sim);
  EXPECT_FALSE(cd.grasps[0].holding);
  EXPECT_TRUE(cd.grasps[0].closed_empty);
  const std::string want = "instruments[0] closed its jaws at t = ";
  const size_t at = err.find(want);
  ASSERT_NE(at, std::string::npos) << err;
  EXPECT_EQ(err.find(want, at + 1), std::string::npos) << "warned more than once: " << err;
  EXPECT_NE(err.find("with no tissue surface between them: it holds nothing"), std::string::npos) << err;
  // Closing on the flap: no warning.
  auto held = flap_sim(true);
  testing::internal::CaptureStderr();
  while (held->state.time < 0.3) advance_frame(*held);
  EXPECT_EQ(testing::internal::GetCapturedStderr().find("closed its jaws"), std::string::npos);
  EXPECT_TRUE(collision_data(*held)->grasps[0].holding);
}

// Jaws that close inside the tissue (a grasper started in it) take nothing
// either, and the warning says where they are: it sent the user to close
// them over the tissue when they already were in it.
TEST(Grasp, JawsClosedInsideTheTissueSaySo) {
  const Mesh mesh = test::tissue_block_mesh();  // 0.1 x 0.1 x 0.05
  Scene scene = test::tissue_block_scene(3e5, 4.0);
  InstrumentSpec g;
  g.kind = InstrumentSpec::Kind::Grasper;
  g.jaw_size = {0.01, 0.004, 0.02};
  g.opening = 0.02;
  g.contact = false;
  g.json_path = "instruments[0]";
  scene.instruments.push_back(g);
  for (const double z : {0.025, 0.1}) {  // the block's middle; 5 cm above it
    auto sim = test::make_sim(mesh, scene);
    sim->tools.assign(1, ToolFrame{});
    sim->pipeline.set(kStageToolPoses, [z](Simulation& s) {
      for (ToolPose* p : {&s.tools[0].before, &s.tools[0].after}) {
        p->p = {0.05, 0.05, z};
        p->q = {std::sqrt(0.5), std::sqrt(0.5), 0.0, 0.0};
      }
      s.tools[0].before.jaw = std::min(1.0, s.state.time / 0.2);
      s.tools[0].after.jaw = std::min(1.0, (s.state.time + s.model.dt) / 0.2);
    });
    install_collision_stage(*sim);
    testing::internal::CaptureStderr();
    while (sim->state.time < 0.3) advance_frame(*sim);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_FALSE(collision_data(*sim)->grasps[0].holding);
    const bool inside = err.find("closed its jaws at t = 0.2 s inside the tissue: it holds nothing") != std::string::npos;
    const bool above = err.find("with no tissue surface between them: it holds nothing") != std::string::npos;
    EXPECT_EQ(inside, z < 0.05) << err;
    EXPECT_EQ(above, z > 0.05) << err;
  }
}

// A recovery step (State::recovery) is not taken in a frame with grasp rows
// under a policy whose contact compliance comes from a factor of Newmark's
// matrix (a dragged grasp under the realtime preset pulled 132 N instead of
// 7 N through backward Euler's 4x smaller mass term); under `exact` it is.
TEST(Grasp, NoRecoveryStepWhileHoldingUnderTheLaggedPolicy) {
  for (const bool lagged : {false, true}) {
    auto sim = flap_sim(true, 0.0, lagged);
    while (sim->state.time < 0.3) advance_frame(*sim);
    ASSERT_TRUE(collision_data(*sim)->grasps[0].holding);
    sim->state.recovery = true;  // as after a capped Newton iteration
    const FrameTiming t = advance_frame(*sim);
    EXPECT_GT(t.grasp_rows, 0);
    EXPECT_EQ(t.recovery, !lagged) << (lagged ? "lagged" : "exact");
  }
}

// The collision stage logs the points each grasp took when it closed; a
// second run given that log (as incise compare gives the policy the
// reference's) takes exactly those points, here a run started with the
// flap's upper layer 2 mm higher, which left alone takes other points.
TEST(Grasp, ARunTakesTheGraspPointsItIsGiven) {
  auto first = flap_sim(true);
  while (first->state.time < 0.3) advance_frame(*first);
  const std::vector<GraspTaken> taken = collision_data(*first)->taken;
  ASSERT_EQ(taken.size(), 1u);
  ASSERT_FALSE(taken[0].held.empty());
  auto second = flap_sim(true);
  for (double& u : second->state.u) u = 0.0;
  for (int i = 0; i < second->model.nnode; ++i)  // another position at closing: other vertices between the jaws
    if (second->model.X[3 * i + 2] > 0.045) second->state.u[3 * i + 2] = 0.002;
  auto third = flap_sim(true);
  for (int i = 0; i < third->model.nnode; ++i) third->state.u[3 * i + 2] = second->state.u[3 * i + 2];
  collision_data(*second)->imposed = taken;
  while (second->state.time < 0.3) advance_frame(*second), advance_frame(*third);
  const std::vector<HeldPoint>& got = collision_data(*second)->grasps[0].held;
  ASSERT_EQ(got.size(), taken[0].held.size());
  for (size_t k = 0; k < got.size(); ++k) {
    EXPECT_EQ(got[k].elem, taken[0].held[k].elem);
    for (int d = 0; d < 3; ++d) {
      EXPECT_EQ(got[k].rst[d], taken[0].held[k].rst[d]);
      EXPECT_EQ(got[k].local[d], taken[0].held[k].local[d]);
    }
  }
  EXPECT_EQ(collision_data(*second)->taken[0].frame, taken[0].frame);
  // Left to itself the same start takes other points.
  const std::vector<HeldPoint>& free = collision_data(*third)->grasps[0].held;
  bool differs = free.size() != taken[0].held.size();
  for (size_t k = 0; !differs && k < free.size(); ++k)
    for (int d = 0; d < 3; ++d) differs = differs || free[k].local[d] != taken[0].held[k].local[d];
  EXPECT_TRUE(differs) << "the test needs a start whose grasp takes other points";
}

}  // namespace
}  // namespace incise
