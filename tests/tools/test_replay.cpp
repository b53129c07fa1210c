// incise run --record and incise replay, as a user runs them: a run with a
// progressive scalpel cut, a probe pressing and a scripted haptic device on
// its own thread, under the realtime preset (background factor taken when the
// clock says), replays bit for bit; an edited pose is found at its frame.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <sys/wait.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

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
  int contact_frames = 0, cut_frames = 0, snapshots = 0;
  for (const ReplayFrame& f : r.frames) {
    contact_frames += f.contacts > 0;
    cut_frames += f.cut_frame;
    snapshots += !f.snapshot.empty();
  }
  EXPECT_GE(contact_frames, 10) << "the probe pressed from frame 6 on";
  EXPECT_GE(cut_frames, 5) << "the scalpel cut progressively";
  EXPECT_GT(r.frames.back().swept_triangles, 0);
  EXPECT_EQ(snapshots, 3) << "frames 10, 20 and the last";
  // (Which frames took a background factor depends on the machine's load:
  // none at all when both cores are busy, the job running at idle priority.
  // tests/engine/solve/test_linear_solve.cpp imposes the choices instead.)
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

  // --out writes the series though the scene says output.vtu false (it
  // wrote nothing).
  const Result o = incise("replay " + path("r.replay") + " --frames 3 --out " + path("series"));
  ASSERT_EQ(o.code, 0) << o.out;
  EXPECT_TRUE(std::filesystem::exists(path("series/scene.pvd"))) << o.out;
  int vtu = 0;
  for (const auto& e : std::filesystem::directory_iterator(path("series"))) vtu += e.path().extension() == ".vtu";
  EXPECT_EQ(vtu, 4) << "frames 0-3";

  // The recorded poses stand in for the trajectories: a replay needs not
  // their files (it failed without them).
  std::filesystem::remove(path("press.csv"));
  std::filesystem::remove(path("cut.csv"));
  const Result gone = incise("replay " + path("r.replay") + " --verify");
  ASSERT_EQ(gone.code, 0) << gone.out;
  EXPECT_NE(gone.out.find("replay: all 24 frames match bit for bit"), std::string::npos) << gone.out;
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
  EXPECT_NE(v.out.find("differs from the recording in u, v/du, a"), std::string::npos) << v.out;
  EXPECT_NE(v.out.find("frames 1-" + std::to_string(k - 1) + " matched bit for bit"), std::string::npos) << v.out;
}

// The mesh is not in the file, only its hash: a changed mesh is refused.
// A scene with a mesh-type cut, run by a relative path and replayed from
// another folder: the recording names the cut file absolutely (it named it
// relative to the folder the run started in, and the replay failed with
// "no such cut surface file").
TEST_F(Replay, AReplayFromAnotherFolderFindsTheCutFile) {
  std::filesystem::create_directories(dir_ / "c");
  ASSERT_EQ(incise("mesh beam --size 4 1 1 --cells 8 2 2 --out " + path("c/beam.vtu")).code, 0);
  write("c/cut.obj", "v 1.3 -1 -1\nv 1.3 2 -1\nv 1.3 2 2\nv 1.3 -1 2\nf 1 2 3 4\n");
  write("c/scene.json", R"({"mesh": {"file": "beam.vtu", "order": 2},
    "material": {"young": 1e5, "poisson": 0.3, "density": 1},
    "gravity": [0, 0, -1], "fixed": [{"box": [[-1, -1, -1], [0, 2, 2]]}],
    "cuts": [{"type": "mesh", "file": "cut.obj"}], "output": {"vtu": false}})");
  const std::string bin = INCISE_BINARY;
  const auto in = [&](const std::string& where, const std::string& args) {
    const std::string log = path("log.txt");
    const int status = std::system(("cd " + where + " && " + bin + " " + args + " > " + log + " 2>&1").c_str());
    std::ifstream is(log);
    std::stringstream ss;
    ss << is.rdbuf();
    return Result{WEXITSTATUS(status), ss.str()};
  };
  const Result run = in(dir_.string(), "run c/scene.json --frames 3 --record c/r.replay");
  ASSERT_EQ(run.code, 0) << run.out;
  const Result v = in(path("c"), "replay r.replay --verify");
  EXPECT_EQ(v.code, 0) << v.out;
  EXPECT_NE(v.out.find("match bit for bit"), std::string::npos) << v.out;
}

// A recorded run that failed: its failing frame is not in the recording
// (it stopped before the frame's end), so `replay --verify` steps it again
// and checks the run fails the same way. It used to end "all 0 frames
// match bit for bit" and exit 0 without stepping it.
TEST_F(Replay, AFailedRunsFailureIsReplayedToo) {
  ASSERT_EQ(incise("mesh beam --size 0.1 0.02 0.02 --cells 4 1 1 --out " + path("b.vtu")).code, 0);
  // The free end yanked 1 m in one step: the motion diverges in frame 1.
  write("fail.json", R"({"mesh": {"file": "b.vtu", "order": 2},
    "material": {"young": 1e5, "poisson": 0.45, "density": 1000},
    "gravity": [0, 0, 0], "fixed": [{"box": [[-1, -1, -1], [0, 1, 1]]}],
    "prescribed": [{"plane": {"point": [0.1, 0, 0], "normal": [-1, 0, 0]}, "displacement": {"z": 1e4}}],
    "output": {"vtu": false}})");
  const Result run = incise("run " + path("fail.json") + " --frames 3 --record " + path("f.replay"));
  ASSERT_NE(run.code, 0) << run.out;
  ASSERT_NE(run.out.find("the motion diverged at frame 1"), std::string::npos) << run.out;
  const Result v = incise("replay " + path("f.replay") + " --verify");
  EXPECT_EQ(v.code, 0) << v.out;
  EXPECT_NE(v.out.find("replay: the recording holds no frame to compare"), std::string::npos) << v.out;
  EXPECT_NE(v.out.find("replay: the failure reproduces at frame 1: step: the motion diverged at frame 1"),
            std::string::npos)
      << v.out;
}

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

namespace incise {
namespace {

using Budget = Replay;  // the same scene

// bench's budget report: every stage of a frame with instruments, a cut, the
// haptic thread, render and record, with percentiles, per-frame columns, tick
// statistics and memory; and a plot drawn by tools/scripts/plot-budget.py.
TEST_F(Budget, BenchReportAndPlotWithEveryStage) {
  scene();
  const test::Result r = test::incise("bench " + path("scene.json") + " --frames 20 --haptics --render --record " +
                                      path("b.replay") + " --json " + path("b.json") + " --plot " + path("b.png"));
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream js(path("b.json"));
  const auto j = nlohmann::json::parse(js);
  for (const char* s : {"tool_poses", "collision", "cutting", "integration", "contact_publish", "render", "record"})
    EXPECT_EQ(j["stages"][s]["runs"].get<int>(), 20) << s;
  for (const char* s : {"assembly", "factorization", "solve", "contact"}) EXPECT_GE(j["stages"][s]["runs"].get<int>(), 1) << s;
  for (const char* k : {"median_ms", "p95_ms", "p99_ms", "max_ms"}) {
    EXPECT_GT(j["frame"][k].get<double>(), 0.0) << k;
    EXPECT_LE(j["stages"]["record"][k].get<double>(), j["frame"][k].get<double>()) << k;
  }
  EXPECT_TRUE(j["frame"].contains("over_budget"));
  EXPECT_GE(j["cut_frames"]["count"].get<int>(), 1);
  EXPECT_EQ(j["cut_frames"]["count"].get<int>() + j["plain_frames"]["count"].get<int>(), 20);
  EXPECT_GT(j["haptics"]["ticks"].get<int>(), 400);
  EXPECT_EQ(j["haptic_ticks"]["period_ms"].size() + 1, j["haptics"]["ticks"].get<size_t>());
  EXPECT_GT(j["peak_rss_mb"].get<double>(), 1.0);
  ASSERT_EQ(j["per_frame"]["frame_ms"].size(), 20u);
  EXPECT_EQ(j["per_frame"]["stages"]["record"].size(), 20u);
  EXPECT_EQ(read_replay(path("b.replay")).frames.size(), 20u);
  ASSERT_TRUE(std::filesystem::exists(path("b.png")));
  EXPECT_GT(std::filesystem::file_size(path("b.png")), 10000u);
}

// A scene with no instrument, cut, device, render or record: those stages
// are listed with 0 runs, and the plot says there was no haptic thread.
TEST_F(Budget, BenchReportOfAMinimalSceneListsAbsentStagesWithZeroRuns) {
  ASSERT_EQ(test::incise("mesh beam --size 4 1 1 --cells 4 1 1 --out " + path("beam.vtu")).code, 0);
  write("scene.json", R"({"mesh": {"file": "beam.vtu", "order": 2},
      "material": {"model": "linear", "young": 1e5, "poisson": 0.3, "density": 1},
      "gravity": [0, 0, -1], "fixed": [{"box": [[-1, -1, -1], [0, 2, 2]]}]})");
  const test::Result r = test::incise("bench " + path("scene.json") + " --frames 5 --plot " + path("m.png"));
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream js(path("m.json"));  // beside the plot when --json is not given
  const auto j = nlohmann::json::parse(js);
  for (const char* s : {"tool_poses", "collision", "cutting", "contact", "contact_publish", "render", "record"}) {
    EXPECT_EQ(j["stages"][s]["runs"].get<int>(), 0) << s;
    EXPECT_FALSE(j["per_frame"]["stages"].contains(s)) << s;
  }
  EXPECT_EQ(j["stages"]["integration"]["runs"].get<int>(), 5);
  EXPECT_FALSE(j.contains("haptics"));
  EXPECT_TRUE(std::filesystem::exists(path("m.png")));
}

}  // namespace
}  // namespace incise
