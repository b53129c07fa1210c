// Refit versus rebuild: frames without a topology change refit the tree and
// rebuild nothing (counters); a new model version rebuilds once; the refitted
// tree finds contacts where the surface now is.
#include "collision/collision_model.h"

#include <gtest/gtest.h>

#include "collision/contact_query.h"
#include "tests/collision/collision_test_util.h"

namespace incise::test {
namespace {

InstrumentSpec sphere_probe(double r) {
  InstrumentSpec s;
  s.json_path = "instruments[0]";
  s.radius = r;
  return s;
}

TEST(CollisionModel, FramesRefitAndOnlyANewModelVersionRebuilds) {
  for (TissueBV bv : {TissueBV::AABB, TissueBV::OBBRSS}) {
    const Model uncut = block_model(false), cut = block_model(true);
    CollisionModel cm(2, bv);
    const Field rest[2] = {affine({}, {}), affine({}, {})};
    EXPECT_EQ(cm.sync(uncut, side_state(uncut, rest), 0), SyncAction::Rebuild);
    EXPECT_EQ(cm.rebuilds(), 1);
    const InstrumentSpec probe = sphere_probe(0.1);
    for (int frame = 1; frame <= 5; ++frame) {
      // The body rises by 0.1 a frame; a sphere 0.05 above the new top face touches it.
      const double lift = 0.1 * frame;
      const Field up[2] = {affine({}, {0, 0, lift}), affine({}, {0, 0, lift})};
      EXPECT_EQ(cm.sync(uncut, side_state(uncut, up), 0), SyncAction::Refit);
      ToolPose pose;
      pose.p = {0.6, 0.4, 1.0 + lift + 0.05};
      ContactResult res;
      query_contacts(cm, make_tool_shape(probe, pose), ContactRequest{}, res);
      ASSERT_FALSE(res.contacts.empty()) << "frame " << frame;
      EXPECT_NEAR(res.max_depth(), 0.05, 1e-12) << "the refitted tree must hold the moved triangles";
      pose.p[2] = 1.0 + lift - 0.3;  // inside the moved body, 0.2 from every face
      query_contacts(cm, make_tool_shape(probe, pose), ContactRequest{}, res);
      EXPECT_TRUE(res.contacts.empty()) << "frame " << frame;
    }
    EXPECT_EQ(cm.refits(), 5);
    EXPECT_EQ(cm.rebuilds(), 1) << "frames without a topology change rebuild no BVH";
    // A cut: the next model version rebuilds once, then refits again.
    const State cs = side_state(cut, rest);
    EXPECT_EQ(cm.sync(cut, cs, 1), SyncAction::Rebuild);
    EXPECT_EQ(cm.sync(cut, cs, 1), SyncAction::Refit);
    EXPECT_EQ(cm.rebuilds(), 2);
    EXPECT_EQ(cm.refits(), 6);
    EXPECT_EQ(cm.model_version(), 1);
    EXPECT_GT(cm.surface().nface, cm.surface().nboundary);
  }
}

}  // namespace
}  // namespace incise::test
