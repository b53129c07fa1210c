#include "collision/tool_shape.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/sphere.h>

#include "engine/util/error.h"

namespace incise {
namespace {

bool positive(double v) { return std::isfinite(v) && v > 0; }

void check_positive(const InstrumentSpec& s, const char* key, double v) {
  if (!positive(v))
    throw Error(s.json_path + "." + key + " must be positive and finite, got " + std::to_string(v));
}

}  // namespace

ToolShape make_tool_shape(const InstrumentSpec& s, const ToolPose& pose) {
  ToolShape t;
  t.kind = s.kind;
  switch (s.kind) {
    case InstrumentSpec::Kind::Probe:
      check_positive(s, "radius", s.radius);
      if (!(std::isfinite(s.length) && s.length >= 0))
        throw Error(s.json_path + ".length must be >= 0 and finite, got " + std::to_string(s.length));
      t.part[0].radius = s.radius;
      if (s.length > 0) {
        t.part[0].kind = ToolPart::Kind::Capsule;
        t.part[0].geometry = std::make_shared<fcl::Capsuled>(s.radius, s.length);
      } else {
        t.part[0].kind = ToolPart::Kind::Sphere;
        t.part[0].geometry = std::make_shared<fcl::Sphered>(s.radius);
      }
      break;
    case InstrumentSpec::Kind::Scalpel:
      for (int k = 0; k < 3; ++k) check_positive(s, "blade", s.blade[k]);
      t.part[0].kind = ToolPart::Kind::Box;
      t.part[0].half = 0.5 * Eigen::Vector3d(s.blade[0], s.blade[1], s.blade[2]);
      t.part[0].geometry = std::make_shared<fcl::Boxd>(s.blade[0], s.blade[1], s.blade[2]);
      break;
    case InstrumentSpec::Kind::Grasper:
      for (int k = 0; k < 3; ++k) check_positive(s, "jaw", s.jaw_size[k]);
      check_positive(s, "opening", s.opening);
      t.nparts = 2;
      for (int j = 0; j < 2; ++j) {
        t.part[j].kind = ToolPart::Kind::Box;
        t.part[j].half = 0.5 * Eigen::Vector3d(s.jaw_size[0], s.jaw_size[1], s.jaw_size[2]);
        t.part[j].geometry = std::make_shared<fcl::Boxd>(s.jaw_size[0], s.jaw_size[1], s.jaw_size[2]);
      }
      break;
  }
  set_tool_pose(t, s, pose);
  return t;
}

void set_probe_radius(ToolShape& t, double radius) {
  ToolPart& part = t.part[0];
  if (t.kind != InstrumentSpec::Kind::Probe || part.radius == radius) return;
  part.radius = radius;
  if (part.kind == ToolPart::Kind::Sphere) static_cast<fcl::Sphered&>(*part.geometry).radius = radius;
  else static_cast<fcl::Capsuled&>(*part.geometry).radius = radius;
  part.geometry->computeLocalAABB();
}

void set_tool_pose(ToolShape& t, const InstrumentSpec& s, const ToolPose& pose) {
  const double qn = std::sqrt(pose.q[0] * pose.q[0] + pose.q[1] * pose.q[1] + pose.q[2] * pose.q[2] +
                              pose.q[3] * pose.q[3]);
  bool finite = std::isfinite(qn) && qn > 0;
  for (double v : pose.p) finite = finite && std::isfinite(v);
  if (!finite) throw Error(s.json_path + ": tool pose has a NaN, infinite or zero component");
  const auto Rm = rotation_matrix({pose.q[0] / qn, pose.q[1] / qn, pose.q[2] / qn, pose.q[3] / qn});
  Eigen::Matrix3d R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R(i, j) = Rm[3 * i + j];
  const Eigen::Vector3d p(pose.p[0], pose.p[1], pose.p[2]);
  // Part centre in the tool frame -> its world transform.
  auto place = [&](ToolPart& part, const Eigen::Vector3d& centre_tool) {
    part.tf.setIdentity();
    part.tf.linear() = R;
    part.tf.translation() = p + R * centre_tool;
  };
  switch (s.kind) {
    case InstrumentSpec::Kind::Probe: {
      ToolPart& part = t.part[0];
      place(part, Eigen::Vector3d(0, 0, 0.5 * s.length));
      part.a = p;
      part.b = p + R * Eigen::Vector3d(0, 0, s.length);
      break;
    }
    case InstrumentSpec::Kind::Scalpel:
      place(t.part[0], Eigen::Vector3d(0, 0, 0.5 * s.blade[2]));
      break;
    case InstrumentSpec::Kind::Grasper: {
      if (!std::isfinite(pose.jaw)) throw Error(s.json_path + ": jaw value is not finite");
      const double y = 0.5 * jaw_gap(s, pose.jaw) + 0.5 * s.jaw_size[1];
      place(t.part[0], Eigen::Vector3d(0, -y, 0));
      place(t.part[1], Eigen::Vector3d(0, y, 0));
      break;
    }
  }
}

}  // namespace incise
