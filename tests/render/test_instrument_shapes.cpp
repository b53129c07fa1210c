// The instruments as the renderer draws them (render/instrument_shapes.cpp):
// the solids at the tools' end-of-frame poses, a grasper's jaws at their gap.
#include <cmath>

#include <gtest/gtest.h>

#include "render/instrument_shape.h"

namespace incise {
namespace {

std::array<double, 3> origin(const InstrumentShape& s) { return {s.pose[12], s.pose[13], s.pose[14]}; }

TEST(InstrumentShapes, SolidsSitWhereTheToolsAreAndJawsAtTheirGap) {
  InstrumentSpec probe, scalpel, grasper;
  probe.kind = InstrumentSpec::Kind::Probe;
  probe.radius = 0.01;
  scalpel.kind = InstrumentSpec::Kind::Scalpel;
  scalpel.blade = {0.04, 0.001, 0.01};
  grasper.kind = InstrumentSpec::Kind::Grasper;
  grasper.jaw_size = {0.01, 0.002, 0.02};
  grasper.opening = 0.02;
  std::vector<ToolFrame> tools(3);
  tools[0].after.p = {0.1, 0.2, 0.3};
  tools[1].after.p = {0.0, 0.0, 0.0};
  tools[1].after.q = {std::sqrt(0.5), 0.0, std::sqrt(0.5), 0.0};  // 90 deg about y: tool z -> world x
  tools[2].after.p = {-0.1, 0.0, 0.0};
  tools[2].after.jaw = 0.5;  // gap 0.01
  EXPECT_TRUE(instrument_shapes({probe, scalpel, grasper}, {}).empty()) << "no poses yet: nothing drawn";
  const auto s = instrument_shapes({probe, scalpel, grasper}, tools);
  ASSERT_EQ(s.size(), 2u + 2u + 3u);  // probe tip + shaft, blade + handle, two jaws + shaft
  EXPECT_EQ(s[0].kind, InstrumentShape::Kind::Capsule);
  EXPECT_DOUBLE_EQ(s[0].radius, 0.01);
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(origin(s[0])[d], tools[0].after.p[d], 1e-15);
  // The blade box spans z in [0, H] of the tool: its centre at H/2 along the tool's z = world x.
  EXPECT_EQ(s[2].kind, InstrumentShape::Kind::Box);
  EXPECT_NEAR(origin(s[2])[0], 0.005, 1e-12);
  EXPECT_NEAR(origin(s[2])[2], 0.0, 1e-12);
  // Jaws: centres at y = +-(gap/2 + T/2) = +-0.006 from the tool origin.
  EXPECT_NEAR(origin(s[4])[1], -0.006, 1e-15);
  EXPECT_NEAR(origin(s[5])[1], 0.006, 1e-15);
  EXPECT_NEAR(origin(s[4])[0], -0.1, 1e-15);
  EXPECT_DOUBLE_EQ(s[4].half_extents[1], 0.001);
}

}  // namespace
}  // namespace incise
