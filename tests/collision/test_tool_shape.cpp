// Instruments as FCL shapes: the tool-frame geometry of scene.h, placed by
// the pose; the grasper's jaws close with the jaw value; bad input is refused.
#include "collision/tool_shape.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/sphere.h>

#include "engine/util/error.h"

namespace incise {
namespace {

// A quarter turn about x: tool z -> world -y, tool y -> world z.
ToolPose turned_pose() {
  ToolPose p;
  p.p = {1.0, 2.0, 3.0};
  p.q = {std::sqrt(0.5), std::sqrt(0.5), 0.0, 0.0};
  return p;
}

TEST(ToolShape, ProbeSphereAndCapsuleSitOnTheToolAxis) {
  InstrumentSpec s;
  s.json_path = "instruments[0]";
  s.radius = 0.1;
  ToolShape t = make_tool_shape(s, turned_pose());
  ASSERT_EQ(t.nparts, 1);
  EXPECT_EQ(t.part[0].kind, ToolPart::Kind::Sphere);
  EXPECT_DOUBLE_EQ(static_cast<const fcl::Sphered&>(*t.part[0].geometry).radius, 0.1);
  EXPECT_LT((t.part[0].a - Eigen::Vector3d(1, 2, 3)).norm(), 1e-15);
  s.length = 0.4;
  t = make_tool_shape(s, turned_pose());
  EXPECT_EQ(t.part[0].kind, ToolPart::Kind::Capsule);
  EXPECT_DOUBLE_EQ(static_cast<const fcl::Capsuled&>(*t.part[0].geometry).lz, 0.4);
  // FCL's capsule is centred: its frame sits half way along the tool's z axis.
  EXPECT_LT((t.part[0].tf.translation() - Eigen::Vector3d(1, 1.8, 3)).norm(), 1e-15);
  EXPECT_LT((t.part[0].b - Eigen::Vector3d(1, 1.6, 3)).norm(), 1e-15);
  EXPECT_LT((t.part[0].a - Eigen::Vector3d(1, 2, 3)).norm(), 1e-15);
}

TEST(ToolShape, ScalpelBladeSpansZeroToHeight) {
  InstrumentSpec s;
  s.kind = InstrumentSpec::Kind::Scalpel;
  s.blade = {0.3, 0.01, 0.2};
  const ToolShape t = make_tool_shape(s, ToolPose{});
  const auto& box = static_cast<const fcl::Boxd&>(*t.part[0].geometry);
  EXPECT_LT((box.side - Eigen::Vector3d(0.3, 0.01, 0.2)).norm(), 1e-15);
  EXPECT_LT((t.part[0].tf.translation() - Eigen::Vector3d(0, 0, 0.1)).norm(), 1e-15);
}

TEST(ToolShape, GrasperGapFollowsTheJaw) {
  InstrumentSpec s;
  s.kind = InstrumentSpec::Kind::Grasper;
  s.jaw_size = {0.02, 0.01, 0.05};
  s.opening = 0.04;
  for (double jaw : {0.0, 0.25, 0.5, 1.0}) {
    ToolPose pose = turned_pose();
    pose.jaw = jaw;
    const ToolShape t = make_tool_shape(s, pose);
    ASSERT_EQ(t.nparts, 2);
    EXPECT_NEAR(jaw_gap(s, jaw), (1 - jaw) * 0.04, 1e-17);
    // Inner faces: centres minus half the thickness, along the tool's y (world z here).
    const Eigen::Vector3d y_axis = t.part[0].tf.linear().col(1);
    EXPECT_LT((y_axis - Eigen::Vector3d(0, 0, 1)).norm(), 1e-15);
    const double inner0 = (t.part[0].tf.translation() - Eigen::Vector3d(1, 2, 3)).dot(y_axis) + 0.005;
    const double inner1 = (t.part[1].tf.translation() - Eigen::Vector3d(1, 2, 3)).dot(y_axis) - 0.005;
    EXPECT_NEAR(inner1 - inner0, (1 - jaw) * 0.04, 1e-15) << "jaw " << jaw;
    EXPECT_NEAR(inner0, -inner1, 1e-15) << "the jaws close symmetrically";
  }
}

TEST(ToolShape, BadSizesAndPosesAreRefusedWithTheirPath) {
  InstrumentSpec s;
  s.json_path = "instruments[2]";
  s.radius = -1;
  try {
    make_tool_shape(s, ToolPose{});
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "instruments[2].radius must be positive and finite, got -1.000000");
  }
  s.radius = 0.1;
  ToolPose bad;
  bad.q = {std::numeric_limits<double>::quiet_NaN(), 0, 0, 0};
  EXPECT_THROW(make_tool_shape(s, bad), Error);
  ToolShape t = make_tool_shape(s, ToolPose{});
  bad = ToolPose{};
  bad.p[1] = std::numeric_limits<double>::infinity();
  try {
    set_tool_pose(t, s, bad);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("instruments[2]: tool pose has a NaN"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace incise
