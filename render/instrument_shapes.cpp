#include <algorithm>

#include "render/instrument_shape.h"

namespace incise {

namespace {

// Column-major local -> world of the tool frame moved by `offset` (tool
// coordinates) along its own axes.
std::array<double, 16> pose_matrix(const ToolPose& pose, const std::array<double, 3>& offset) {
  const std::array<double, 9> R = rotation_matrix(pose.q);  // row-major
  const std::array<double, 3> o = tool_to_world(pose, offset);
  std::array<double, 16> m{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m[4 * c + r] = R[3 * r + c];
  m[12] = o[0], m[13] = o[1], m[14] = o[2], m[15] = 1.0;
  return m;
}

InstrumentShape box(const ToolPose& pose, const std::array<double, 3>& centre, const Vec3& half) {
  InstrumentShape s;
  s.kind = InstrumentShape::Kind::Box;
  s.half_extents = half;
  s.pose = pose_matrix(pose, centre);
  return s;
}

// Along the tool's z axis from z0 to z1.
InstrumentShape rod(const ToolPose& pose, double z0, double z1, double radius, InstrumentShape::Kind kind) {
  InstrumentShape s;
  s.kind = kind;
  s.radius = radius;
  s.length = std::abs(z1 - z0);
  s.pose = pose_matrix(pose, {0.0, 0.0, 0.5 * (z0 + z1)});
  return s;
}

}  // namespace

std::vector<InstrumentShape> instrument_shapes(const std::vector<InstrumentSpec>& specs,
                                               const std::vector<ToolFrame>& tools) {
  std::vector<InstrumentShape> out;
  const size_t n = std::min(specs.size(), tools.size());
  for (size_t i = 0; i < n; ++i) {
    const InstrumentSpec& s = specs[i];
    const ToolPose& p = tools[i].after;
    switch (s.kind) {
      case InstrumentSpec::Kind::Probe: {
        // The tip (the collision shape), then a shaft up the tool's z axis.
        out.push_back(rod(p, 0.0, s.length, s.radius, InstrumentShape::Kind::Capsule));
        const double shaft = std::max(0.3 * s.radius, 1e-4);
        out.push_back(rod(p, s.length, s.length + 12.0 * s.radius, shaft, InstrumentShape::Kind::Cylinder));
        break;
      }
      case InstrumentSpec::Kind::Scalpel: {
        const Vec3& b = s.blade;  // [L, T, H]: x in [-L/2, L/2], y in [-T/2, T/2], z in [0, H]
        out.push_back(box(p, {0.0, 0.0, 0.5 * b[2]}, {0.5 * b[0], 0.5 * b[1], 0.5 * b[2]}));
        const double r = std::max(0.05 * b[0], 3.0 * b[1]);
        out.push_back(rod(p, b[2], b[2] + 1.5 * b[0], r, InstrumentShape::Kind::Cylinder));
        break;
      }
      case InstrumentSpec::Kind::Grasper: {
        const Vec3& j = s.jaw_size;  // [W, T, J]: jaws centred at z = 0 across the tool's y axis
        const double y = 0.5 * jaw_gap(s, p.jaw) + 0.5 * j[1];
        for (double side : {-1.0, 1.0}) out.push_back(box(p, {0.0, side * y, 0.0}, {0.5 * j[0], 0.5 * j[1], 0.5 * j[2]}));
        const double r = std::max(0.2 * j[0], 0.5 * j[1]);
        out.push_back(rod(p, -0.5 * j[2] - 3.0 * j[2], -0.5 * j[2], r, InstrumentShape::Kind::Cylinder));
        break;
      }
    }
  }
  return out;
}

}  // namespace incise
