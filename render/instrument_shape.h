#pragma once
// What the renderer needs of an instrument: a simple solid, its pose and a
// colour; instrument_shapes makes them from the scene's instruments and
// their poses each frame (render_frame); the renderer draws whatever it is
// given.
#include <array>
#include <optional>
#include <vector>

#include "engine/runtime/tool_pose.h"
#include "engine/scene/scene.h"

namespace incise {

struct InstrumentShape {
  enum class Kind { Capsule, Cylinder, Box };
  Kind kind = Kind::Cylinder;
  double radius = 0.0;      // capsule, cylinder
  double length = 0.0;      // capsule, cylinder: along local z, centred on the origin (capsule: without the caps)
  Vec3 half_extents{};      // box
  std::array<double, 16> pose{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  // column-major local -> world
  std::optional<Vec3> color;  // absent: render.colors.instrument
};

// The solids of the scene's instruments at their poses (tools[i].after, the
// pose at the frame's end, where the tissue is drawn): a probe's sphere or
// capsule with a shaft, a scalpel's blade box with a handle, a grasper's two
// jaw boxes at their gap with a shaft. Empty when there are no poses yet.
std::vector<InstrumentShape> instrument_shapes(const std::vector<InstrumentSpec>& specs,
                                               const std::vector<ToolFrame>& tools);

// Appends the shape's triangles in world coordinates: pos and nrm (3 floats
// per vertex, 3 vertices per triangle, counter-clockwise seen from outside).
void instrument_triangles(const InstrumentShape& shape, std::vector<float>& pos, std::vector<float>& nrm);

}  // namespace incise
