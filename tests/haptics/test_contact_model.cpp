// The local contact model and the coupling solve (haptics/contact_model.h)
// against the simulation they stand for: a probe held still against the
// block feels the simulation's contact force; a slowly moving probe's force
// changes between ticks by no more than the bound the coupling and the
// blend give; the solve reproduces the simulation's multipliers at its own
// state and is k-Lipschitz in the device's position.
#include <gtest/gtest.h>

#include "tests/haptics/haptic_test_util.h"

namespace incise {
namespace {

using test::kBlockTop;
using test::kProbeRadius;

// The device starts 2 mm above the block's top (probe resting on nothing),
// goes `deep` below the probe's touching height in 0.5 s and stays.
std::vector<std::array<double, 4>> press(double deep) {
  const double touch = kBlockTop + kProbeRadius;
  return {{0.0, 0.05, 0.05, touch + 0.002}, {0.5, 0.05, 0.05, touch - deep}, {10.0, 0.05, 0.05, touch - deep}};
}

TEST(HapticContactModel, AProbeHeldStillFeelsTheSimulationsContactForce) {
  HapticsSpec h;
  h.damping = 0.0;
  auto b = test::make_haptic_block(test::scripted(press(0.006)), {0.05, 0.05, kBlockTop + kProbeRadius + 0.002}, h);
  b.step_until(3.0);
  const std::array<double, 3> hand = b.records.back().force, sim = b.sim_force();
  ASSERT_GT(test::norm(sim), 0.2) << "the probe presses the block";
  ASSERT_LT(test::norm(sim), b.loop->force_limit()) << "below the device's limit, so no clamping";
  const std::array<double, 3> diff{hand[0] - sim[0], hand[1] - sim[1], hand[2] - sim[2]};
  EXPECT_LT(test::norm(diff), 0.02 * test::norm(sim)) << "hand " << hand[2] << " N, simulation " << sim[2] << " N";
  EXPECT_GT(hand[2], 0.0) << "the tissue pushes the hand up";
  // The proxy sits where the spring carries that force: above the device by f / k.
  const ToolPose proxy = b.loop->proxy_pose();
  EXPECT_DOUBLE_EQ(b.sim->tools[0].after.p[2], press(0.006).back()[3]) << "the simulation holds the tool at the device";
  const double device_z = press(0.006).back()[3];
  EXPECT_NEAR(proxy.p[2] - device_z, hand[2] / h.stiffness, 1e-6);
  RecordProperty("hand_force_n", std::to_string(hand[2]));
  RecordProperty("simulation_force_n", std::to_string(sim[2]));
}

TEST(HapticContactModel, TheSolveReturnsTheSimulationsMultipliersAtItsOwnState) {
  HapticsSpec h;
  h.damping = 0.0;
  auto b = test::make_haptic_block(test::scripted(press(0.006)), {0.05, 0.05, kBlockTop + kProbeRadius + 0.002}, h);
  b.step_until(1.5);
  const HapticContactModel& m = b.loop->current_model();
  ASSERT_GT(m.rows, 0);
  // At the device pose the frame was solved at, the multipliers are the frame's.
  const std::array<double, 3> xd = m.x0;
  std::array<double, kMaxHapticRows> lambda{};
  // Tick after tick, each warm-started from the last (as the haptic thread
  // runs it): rows that nearly repeat each other (two faces' rows beside
  // the edge under the probe) converge slowly in their difference, so one
  // tick's 50 sweeps from zero may not be enough.
  std::array<double, 3> f{};
  int sweeps = 0, ticks = 0;
  do f = coupling_force(m, xd, lambda.data(), &sweeps);
  while (++ticks < 20 && sweeps == 50);
  RecordProperty("ticks_to_converge", std::to_string(ticks));
  const std::array<double, 3> sim = b.sim_force();  // from the simulation's rows, not the model's
  ASSERT_GT(test::norm(sim), 0.2);
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(f[d], sim[d], 1e-6 * test::norm(sim)) << d;
  // Lipschitz: moving the device by e (into the tissue and out) changes the force by at most k |e|.
  for (double e : {1e-5, 1e-4, 1e-3, 3e-3, -1e-4, -1e-3, -3e-3}) {
    for (int axis = 0; axis < 3; ++axis) {
      std::array<double, 3> x2 = xd;
      x2[axis] -= e;
      std::array<double, kMaxHapticRows> l2{};
      const std::array<double, 3> f2 = coupling_force(m, x2, l2.data());
      const std::array<double, 3> df{f2[0] - f[0], f2[1] - f[1], f2[2] - f[2]};
      EXPECT_LE(test::norm(df), h.stiffness * std::abs(e) * (1 + 1e-6) + 1e-9) << "axis " << axis << " e " << e;
    }
  }
}

// Continuity: per tick, the force changes by at most
//   k |x_d(t_i) - x_d(t_i-1)|       (the coupling: f is k-Lipschitz in x_d)
// + |f_new - f_old| / blend_ticks    (a new model blended in over one frame)
// with damping off; docs/haptics.md, "Continuity". Without the blend the
// jump at a model switch would be |f_new - f_old| itself, which the test
// also measures, so the bound is not vacuous.
TEST(HapticContactModel, TheForceIsContinuousAcrossModelUpdates) {
  HapticsSpec h;
  h.damping = 0.0;
  const double touch = kBlockTop + kProbeRadius, speed = 0.004;  // 4 mm/s into the tissue, then 4 mm/s sideways
  const std::vector<std::array<double, 4>> keys{{0.0, 0.05, 0.05, touch + 0.001},
                                                {0.25 + 2.0, 0.05, 0.05, touch + 0.001 - speed * 2.25},
                                                {2.25 + 2.0, 0.05 + speed * 2.0, 0.05, touch + 0.001 - speed * 2.25}};
  auto b = test::make_haptic_block(test::scripted(keys), {0.05, 0.05, touch + 0.001}, h);
  b.step_until(4.25);
  const double N = b.loop->blend_ticks(), k = h.stiffness;
  double worst_ratio = 0.0, largest_gap = 0.0, largest_jump = 0.0;
  for (size_t i = 1; i < b.records.size(); ++i) {
    const TickRecord &a = b.records[i - 1], &c = b.records[i];
    const double dx = speed * (c.t - a.t) * 1.0000001;
    const double bound = k * dx + c.blend_gap / N + 1e-7;
    const std::array<double, 3> df{c.force[0] - a.force[0], c.force[1] - a.force[1], c.force[2] - a.force[2]};
    worst_ratio = std::max(worst_ratio, test::norm(df) / bound);
    largest_gap = std::max(largest_gap, static_cast<double>(c.blend_gap));
    largest_jump = std::max(largest_jump, test::norm(df));
  }
  ASSERT_GT(test::norm(b.records.back().force), 0.3) << "in contact at the end";
  EXPECT_LE(worst_ratio, 1.0) << "largest tick-to-tick change / its bound";
  EXPECT_GT(largest_gap, 2.0 * largest_jump) << "models disagree by more than the jumps the blend lets through";
  RecordProperty("largest_jump_n", std::to_string(largest_jump));
  RecordProperty("largest_model_gap_n", std::to_string(largest_gap));
}

}  // namespace
}  // namespace incise
