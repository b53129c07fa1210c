// Tool poses: the rotation of a quaternion against the analytic matrix, and
// world_to_tool as the inverse of tool_to_world.
#include "engine/runtime/tool_pose.h"

#include <gtest/gtest.h>

#include <cmath>

namespace incise {
namespace {

TEST(ToolPose, NinetyDegreesAboutZMapsXToY) {
  const double h = std::sqrt(0.5);
  ToolPose pose;
  pose.q = {h, 0.0, 0.0, h};
  const std::array<double, 9> R = rotation_matrix(pose.q);
  const std::array<double, 9> ref{0, -1, 0, 1, 0, 0, 0, 0, 1};
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(R[k], ref[k], 1e-15) << k;
  pose.p = {1.0, 2.0, 3.0};
  const std::array<double, 3> x = tool_to_world(pose, {1.0, 0.0, 0.0});
  EXPECT_NEAR(x[0], 1.0, 1e-15);
  EXPECT_NEAR(x[1], 3.0, 1e-15);
  EXPECT_NEAR(x[2], 3.0, 1e-15);
}

TEST(ToolPose, WorldToToolInvertsToolToWorld) {
  ToolPose pose;
  pose.p = {0.3, -1.2, 2.5};
  // A unit quaternion of a rotation about (1, 2, -2)/3 by 1.1 rad.
  const double s = std::sin(0.55), c = std::cos(0.55);
  pose.q = {c, s / 3.0, 2.0 * s / 3.0, -2.0 * s / 3.0};
  const std::array<double, 3> a{0.7, -0.4, 1.9};
  const std::array<double, 3> back = world_to_tool(pose, tool_to_world(pose, a));
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(back[d], a[d], 1e-14) << d;
  // R is orthonormal with det +1.
  const std::array<double, 9> R = rotation_matrix(pose.q);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double dot = 0.0;
      for (int k = 0; k < 3; ++k) dot += R[3 * k + i] * R[3 * k + j];
      EXPECT_NEAR(dot, i == j ? 1.0 : 0.0, 1e-15);
    }
  const double det = R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) + R[2] * (R[3] * R[7] - R[4] * R[6]);
  EXPECT_NEAR(det, 1.0, 1e-14);
}

}  // namespace
}  // namespace incise
