// The input guard (haptics/input_guard.h) on its own: a 30 Hz tracker moving
// at 0.2 m/s is a hand, not a string of jumps; a turn faster than max_turn
// is a jump; a jaw outside [0, 1] is rejected; a reacquired reading is
// reached at glide_speed and max_turn, position and orientation both.
#include <cmath>

#include <gtest/gtest.h>

#include "haptics/input_guard.h"

namespace incise {
namespace {

ToolPose at(double x, double angle = 0.0) {
  ToolPose p;
  p.p = {x, 0.0, 0.0};
  p.q = {std::cos(angle / 2), 0.0, 0.0, std::sin(angle / 2)};
  return p;
}

TEST(InputGuard, ASlowTrackerMovingFastIsAHandNotJumps) {
  InputGuard g(GuardSettings{}, at(0.0));
  HapticEvent e;
  bool has = false;
  int events = 0;
  double t = 0.0;
  for (int tick = 1; tick <= 1000; ++tick) {  // 1 kHz ticks, a reading every 33 ms at 0.2 m/s
    t = 1e-3 * tick;
    const bool fresh = tick % 33 == 0;
    const ToolPose& p = g.filter(t, at(0.2 * t), fresh, &e, &has);
    events += has;
    if (fresh) {
      ASSERT_DOUBLE_EQ(p.p[0], 0.2 * t) << "tick " << tick;
    }
  }
  EXPECT_EQ(events, 0);
}

TEST(InputGuard, FastTurnsAndBadJawsAreRejected) {
  GuardSettings s;
  InputGuard g(s, at(0.0));
  HapticEvent e;
  bool has = false;
  g.filter(1e-3, at(0.0, 0.01), true, &e, &has);  // 10 rad/s: a hand
  EXPECT_FALSE(has);
  const ToolPose& p = g.filter(2e-3, at(0.0, 0.5), true, &e, &has);  // 490 rad/s
  EXPECT_TRUE(has);
  EXPECT_EQ(e.kind, HapticEventKind::Jump);
  EXPECT_NEAR(p.q[3], std::sin(0.005), 1e-12) << "held";
  InputGuard j(s, at(0.0));
  ToolPose bad = at(0.0);
  bad.jaw = 1.5;
  j.filter(1e-3, bad, true, &e, &has);
  EXPECT_TRUE(has);
  EXPECT_EQ(e.kind, HapticEventKind::JawRange);
  EXPECT_EQ(e.value[0], 1.5);
}

TEST(InputGuard, AReacquiredReadingIsReachedAtGlideSpeedAndMaxTurn) {
  GuardSettings s;
  s.reacquire = 0.05;
  InputGuard g(s, at(0.0));
  HapticEvent e;
  bool has = false;
  int reacquired = 0;
  double t = 0.0, fastest = 0.0, fastest_turn = 0.0;
  ToolPose prev = at(0.0);
  for (int tick = 1; tick <= 2000; ++tick) {
    t = 1e-3 * tick;
    const ToolPose p = g.filter(t, at(0.04, 1.0), true, &e, &has);  // 4 cm and 1 rad away, from the first tick
    reacquired += has && e.kind == HapticEventKind::Reacquired;
    fastest = std::max(fastest, std::abs(p.p[0] - prev.p[0]) / 1e-3);
    const double dot = std::min(1.0, std::abs(p.q[0] * prev.q[0] + p.q[3] * prev.q[3]));
    fastest_turn = std::max(fastest_turn, 2.0 * std::acos(dot) / 1e-3);
    prev = p;
    if (tick == 49) {
      EXPECT_EQ(p.p[0], 0.0) << "held until guard.reacquire";
    }
  }
  EXPECT_EQ(reacquired, 1);
  EXPECT_LE(fastest, s.glide_speed * (1 + 1e-9));
  EXPECT_LE(fastest_turn, s.max_turn * (1 + 1e-6));
  EXPECT_NEAR(prev.p[0], 0.04, 1e-12) << "arrived: 4 cm at 5 cm/s takes 0.8 s";
  EXPECT_NEAR(prev.q[3], std::sin(0.5), 1e-12);
}

}  // namespace
}  // namespace incise
