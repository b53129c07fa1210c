// incise run --record and incise replay, as a user runs them: a run with a
// progressive scalpel cut, a probe pressing and a scripted haptic device on
// its own thread, under the realtime preset (background factor taken when the
// clock says), replays bit for bit; an edited pose is found at its frame.
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "engine/runtime/replay_file.h"
#include "tests/tools/cli_test_util.h"
#include "tests/tools/temp_dir_test.h"

namespace incise {
namespace {

using test::incise;
using test::Result;

class Replay : public test::TempDirTest {
 protected:
  // A corotated cantilever (4 x 1 x 1, fixed at x = 0); a probe (the haptic
  // device's instrument) pressing its free end from t = 0.2 s; a scalpel
  // whose 1.6 m edge, along y, goes down through the top 40% at x = 1
  // between 0.1 and 0.5 s.
  void scene() const {
    ASSERT_EQ(incise("mesh beam --size 4 1 1 --cells 8 2 2 --out " + path("beam.vtu")).code, 0);
    write("press.csv", "t,x,y,z,qw,qx,qy,qz\n0, 3.5, 0.5, 1.3, 1, 0, 0, 0\n0.2, 3.5, 0.5, 1.1, 1, 0, 0, 0\n");
    write("cut.csv",
          "t,x,y,z,qw,qx,qy,qz\n"
          "0, 1, 0.5, 1.3, 0.7071067811865476, 0, 0, 0.7071067811865476\n"
          "0.1, 1, 0.5, 1.3, 0.7071067811865476, 0, 0, 0.7071067811865476\n"
          "0.5, 1, 0.5, 0.6, 0.7071067811865476, 0, 0, 0.7071067811865476\n");
    write("scene.json", R"({"mesh": {"file": "beam.vtu", "order": 2},
      "material": {"model": "corotated", "young": 1e5, "poisson": 0.3, "density": 1,
                   "rayleigh": {"mass": 1.0, "stiffness": 0.002}},
      "gravity": [0, 0, -1],
      "fixed": [{"box": [[-1, -1, -1], [0, 2, 2]]}],
      "instruments": [{"type": "probe", "name": "probe", "radius": 0.2, "trajectory": "press.csv"},
                      {"type": "scalpel", "name": "scalpel", "blade": [1.6, 0.01, 0.3], "trajectory": "cut.csv"}],
      "haptics": {"device": "scripted", "instrument": "probe", "realtime": false, "guard": {"workspace_radius": 10}},
      "solver": {"preset": "realtime"},
      "output": {"vtu": false}})");
  }
};

TEST_F(Replay, ARecordedRunWithCutContactAndHapticsReplaysBitForBit) {
  scene();
  const Result run = incise("run " + path("scene.json") + " --frames 24 --haptics --haptics-dir " + path("h") +
                            " --record " + path("r.replay") + " --record-states 10");
  ASSERT_EQ(run.code, 0) << run.out;
  EXPECT_NE(run.out.find("wrote " + path("r.replay") + ": 24 frames"), std::string::npos) << run.out;
  const ReplayFile r = read_replay(path("r.replay"));
  ASSERT_EQ(r.frames.size(), 24u);
  int contact_frames = 0, cut_frames = 0, snapshots = 0, taken = 0;
  for (const ReplayFrame& f : r.frames) {
    taken += f.late_factor_call >= 0;
    contact_frames += f.contacts > 0;
    cut_frames += f.cut_frame;
    snapshots += !f.snapshot.empty();
  }
  EXPECT_GE(contact_frames, 10) << "the probe pressed from frame 6 on";
  EXPECT_GE(cut_frames, 5) << "the scalpel cut progressively";
  EXPECT_GT(r.frames.back().swept_triangles, 0);
  EXPECT_EQ(snapshots, 3) << "frames 10, 20 and the last";
  EXPECT_GE(taken, 5) << "background factors taken when the clock said (late_factor skip), every 2nd frame";
  EXPECT_GT(r.ticks.size(), 400u) << "24 frames at 30 Hz: 0.8 s of 1 kHz device samples";
  EXPECT_EQ(r.meta.compliance.size(), 2u);
  EXPECT_GT(r.meta.compliance[0], 0.0) << "the probe is held through the coupling spring";

  const Result v = incise("replay " + path("r.replay") + " --verify");
  ASSERT_EQ(v.code, 0) << v.out;
  EXPECT_NE(v.out.find("replay: all 24 frames match bit for bit"), std::string::npos) << v.out;

  const Result t = incise("replay " + path("r.replay") + " --tolerance 0");
  ASSERT_EQ(t.code, 0) << t.out;
  EXPECT_NE(t.out.find("replay: 24 of 24 frames equal bit for bit; largest relative difference over 3 snapshots 0"),
            std::string::npos)
      << t.out;
}

// One recorded pose of the pressing probe moved by 1 mm: the replay differs
// from the recording at exactly that frame, and all frames before it match.
TEST_F(Replay, AnEditedInstrumentPoseIsFoundAtItsFrame) {
  scene();
  ASSERT_EQ(incise("run " + path("scene.json") + " --frames 20 --haptics --haptics-dir " + path("h") + " --record " +
                   path("r.replay"))
                .code,
            0);
  const ReplayFile r = read_replay(path("r.replay"));
  int k = 0;  // a frame well into the contact
  for (const ReplayFrame& f : r.frames)
    if (f.contacts > 0 && k == 0) k = f.frame + 3;
  ASSERT_GT(k, 0);
  ASSERT_LE(k, 20);
  {
    ReplayWriter w(path("edited.replay"), r.meta);
    for (ReplayFrame f : r.frames) {
      if (f.frame == k) f.tools[0].after.p[2] -= 1e-3;
      w.add_frame(f);
    }
    w.add_ticks(r.ticks);
    w.finish(r.end_status);
  }
  const Result v = incise("replay " + path("edited.replay") + " --verify");
  EXPECT_EQ(v.code, 1) << v.out;
  EXPECT_NE(v.out.find("frame " + std::to_string(k) + " (t = "), std::string::npos) << v.out;
  EXPECT_NE(v.out.find("differs from the recording in u, v, a"), std::string::npos) << v.out;
  EXPECT_NE(v.out.find("frames 1-" + std::to_string(k - 1) + " matched bit for bit"), std::string::npos) << v.out;
}

// The mesh is not in the file, only its hash: a changed mesh is refused.
TEST_F(Replay, AChangedMeshIsRefused) {
  scene();
  ASSERT_EQ(incise("run " + path("scene.json") + " --frames 2 --record " + path("r.replay")).code, 0);
  ASSERT_EQ(incise("mesh beam --size 4 1 1.01 --cells 8 2 2 --out " + path("beam.vtu")).code, 0);
  const Result v = incise("replay " + path("r.replay") + " --verify");
  EXPECT_EQ(v.code, 1) << v.out;
  EXPECT_NE(v.out.find("the mesh " + path("beam.vtu") + " has changed since the recording"), std::string::npos) << v.out;
}

// A replay cut short is a clear error naming where.
TEST_F(Replay, ADamagedReplayIsAClearError) {
  scene();
  ASSERT_EQ(incise("run " + path("scene.json") + " --frames 3 --record " + path("r.replay")).code, 0);
  std::string bytes;
  {
    std::ifstream is(path("r.replay"), std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(is), {});
  }
  std::ofstream(path("cut.replay"), std::ios::binary) << bytes.substr(0, bytes.size() - 10);
  const Result v = incise("replay " + path("cut.replay"));
  EXPECT_EQ(v.code, 1) << v.out;
  EXPECT_NE(v.out.find("incise: error: " + path("cut.replay") + ": truncated at offset"), std::string::npos) << v.out;
  EXPECT_NE(v.out.find("after frame 3"), std::string::npos) << v.out;
}

}  // namespace
}  // namespace incise
