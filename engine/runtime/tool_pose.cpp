#include "engine/runtime/tool_pose.h"

#include <Eigen/Geometry>

namespace incise {

std::array<double, 9> rotation_matrix(const std::array<double, 4>& q) {
  const Eigen::Matrix3d R = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).toRotationMatrix();
  return {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)};
}

std::array<double, 3> tool_to_world(const ToolPose& pose, const std::array<double, 3>& a) {
  const auto R = rotation_matrix(pose.q);
  std::array<double, 3> x{};
  for (int i = 0; i < 3; ++i) x[i] = pose.p[i] + R[3 * i] * a[0] + R[3 * i + 1] * a[1] + R[3 * i + 2] * a[2];
  return x;
}

std::array<double, 3> world_to_tool(const ToolPose& pose, const std::array<double, 3>& x) {
  const auto R = rotation_matrix(pose.q);
  const double d[3] = {x[0] - pose.p[0], x[1] - pose.p[1], x[2] - pose.p[2]};
  std::array<double, 3> a{};
  for (int j = 0; j < 3; ++j) a[j] = R[j] * d[0] + R[3 + j] * d[1] + R[6 + j] * d[2];
  return a;
}

}  // namespace incise
