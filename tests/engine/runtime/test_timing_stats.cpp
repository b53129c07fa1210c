// summarize (engine/runtime/timing_stats.h): the contact force's change
// between frames, the chatter of a held tool, over consecutive frames that
// both have rows only.
#include <vector>

#include <gtest/gtest.h>

#include "engine/runtime/timing_stats.h"

namespace incise {
namespace {

FrameTiming frame(int contacts, double force) {
  FrameTiming t;
  t.contacts = contacts;
  t.contact_force = force;
  return t;
}

TEST(TimingStats, ContactForceChangeIsTheMeanOverConsecutiveContactFrames) {
  // A held probe alternating 0.8 / 1.1 N, a frame without rows, a grasp.
  std::vector<FrameTiming> f = {frame(3, 0.8), frame(3, 1.1), frame(3, 0.8), frame(0, 0.0), frame(3, 1.1),
                                frame(0, 2.0)};
  f.back().grasp_rows = 6;
  const TimingSummary s = summarize(f);
  // Pairs (0,1), (1,2): 0.3 each; (4,5): 0.9; none across the frame without rows.
  EXPECT_NEAR(s.contact_force_change, (0.3 + 0.3 + 0.9) / 3, 1e-12);
  EXPECT_EQ(s.contact_frames, 5);
  EXPECT_DOUBLE_EQ(s.contact_force_max, 2.0);
  EXPECT_EQ(summarize({frame(3, 1.0)}).contact_force_change, 0.0) << "one contact frame: no change to measure";
}

}  // namespace
}  // namespace incise
