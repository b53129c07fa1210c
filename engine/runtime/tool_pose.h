#pragma once
// Where each instrument is in a frame: the tool-poses stage (tools/,
// tools/instrument_stage.h) fills Simulation::tools from the trajectories (or
// a device) before collision and cutting read them.
#include <array>

namespace incise {

struct ToolPose {
  std::array<double, 3> p{0.0, 0.0, 0.0};       // position of the tool frame's origin (world)
  std::array<double, 4> q{1.0, 0.0, 0.0, 0.0};  // orientation (w, x, y, z), unit: tool frame -> world
  double jaw = 0.0;                             // grasper: 0 open .. 1 closed
};

// x_world = p + R(q) x_tool.
std::array<double, 3> tool_to_world(const ToolPose& pose, const std::array<double, 3>& x_tool);
// The inverse: x_tool = R(q)^T (x_world - p).
std::array<double, 3> world_to_tool(const ToolPose& pose, const std::array<double, 3>& x_world);
// R(q), row-major 3x3.
std::array<double, 9> rotation_matrix(const std::array<double, 4>& q);

// One instrument in the coming frame: at its start (time t, the pose the
// tissue last saw) and at its end (t + dt, the pose the step must respect).
struct ToolFrame {
  ToolPose before, after;
};

}  // namespace incise
