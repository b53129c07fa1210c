#pragma once
// What the renderer needs of an instrument: a simple solid, its pose and a
// colour. The instrument issue (tools/) will fill these from the scene's
// tools and their trajectories each frame; the renderer draws whatever it is given.
#include <array>
#include <optional>
#include <vector>

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

// Appends the shape's triangles in world coordinates: pos and nrm (3 floats
// per vertex, 3 vertices per triangle, counter-clockwise seen from outside).
void instrument_triangles(const InstrumentShape& shape, std::vector<float>& pos, std::vector<float>& nrm);

}  // namespace incise
