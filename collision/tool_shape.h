#pragma once
// An instrument as FCL shapes in the world, for one pose. The tool-frame
// geometry is the scene's (engine/scene/scene.h, InstrumentSpec):
//   probe    fcl::Sphere of `radius` at the origin, or (length > 0) an
//            fcl::Capsule from the origin to (0, 0, length): FCL's capsule is
//            centred on its frame, so that frame sits at (0, 0, length / 2);
//   scalpel  one fcl::Box blade, x in [-L/2, L/2], y in [-T/2, T/2], z in [0, H];
//   grasper  two fcl::Box jaws [W, T, J] centred at y = -(g/2 + T/2) (part 0)
//            and y = +(g/2 + T/2) (part 1), z = 0, with the gap between their
//            inner faces g = (1 - jaw) * opening (jaw_gap).
// The FCL geometry is made once (make_tool_shape); a new pose or jaw value
// only moves the parts (set_tool_pose), allocating nothing.
#include <memory>

#include <Eigen/Core>
#include <fcl/geometry/collision_geometry.h>
#include <fcl/common/types.h>

#include "engine/runtime/tool_pose.h"
#include "engine/scene/scene.h"

namespace incise {

struct ToolPart {
  enum class Kind { Sphere, Capsule, Box };
  Kind kind = Kind::Sphere;
  std::shared_ptr<fcl::CollisionGeometryd> geometry;  // centred on its own frame
  fcl::Transform3d tf = fcl::Transform3d::Identity();  // part frame -> world
  // The same solid in closed form, world coordinates (collision/narrowphase.h):
  double radius = 0.0;          // sphere, capsule
  Eigen::Vector3d a{0, 0, 0};   // sphere: centre; capsule: axis end at the tool origin
  Eigen::Vector3d b{0, 0, 0};   // capsule: the other axis end (sphere: = a)
  Eigen::Vector3d half{0, 0, 0};  // box: half extents along its axes
  // tf.translation() is the box centre, tf.linear() its axes (columns).
};

struct ToolShape {
  InstrumentSpec::Kind kind = InstrumentSpec::Kind::Probe;
  int nparts = 1;   // 2 for a grasper (part 0 the -y jaw, part 1 the +y jaw)
  ToolPart part[2];
};

// Throws incise::Error naming spec.json_path for sizes that are not positive
// and finite, or a pose with a NaN or zero quaternion.
ToolShape make_tool_shape(const InstrumentSpec& spec, const ToolPose& pose);
// Moves the parts to `pose` (q is normalised; jaw clamped to [0, 1]).
void set_tool_pose(ToolShape& shape, const InstrumentSpec& spec, const ToolPose& pose);
// A probe's round part with another radius (the collision stage's detection
// margin changes from frame to frame); allocates nothing.
void set_probe_radius(ToolShape& shape, double radius);


}  // namespace incise
