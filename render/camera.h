#pragma once
// The viewpoint of a render: from the scene's render.camera, with the absent
// parts framed from the mesh's bounding box so the whole body is in view.
#include <array>

#include "engine/scene/scene.h"

namespace incise {

struct Camera {
  Vec3 eye{}, target{}, up{0, 0, 1};
  double fov_deg = 30.0;   // vertical
  double near = 0.1, far = 100.0;
  Vec3 light{};            // unit direction the light travels (world)
};

// Auto-framing looks at the box centre from the front-right, above
// (direction (1, -1.6, 0.9) from the centre, scaled so the bounding sphere
// fits the narrower field of view). lo/hi: the mesh's bounding box.
Camera frame_camera(const RenderSettings& r, const Vec3& lo, const Vec3& hi);

// Column-major 4x4 projection * view for a width/height aspect ratio.
std::array<float, 16> view_projection(const Camera& c, double aspect);

}  // namespace incise
