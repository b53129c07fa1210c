// The replay file (engine/runtime/replay_file.h): what is written is read
// back exactly, and a damaged file is an error naming where, never a crash,
// a wrong replay or a huge allocation.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "engine/runtime/replay_file.h"
#include "engine/util/error.h"
#include "engine/util/fnv.h"

namespace incise {
namespace {

namespace fs = std::filesystem;

std::string slurp(const std::string& path) {
  std::ifstream is(path, std::ios::binary);
  std::ostringstream ss;
  ss << is.rdbuf();
  return ss.str();
}

// A replay of 12 frames of two instruments, ticks after every frame and a
// snapshot every 5th frame, written through ReplayWriter.
struct Sample {
  ReplayMeta meta;
  std::vector<ReplayFrame> frames;
  std::vector<std::vector<ReplayTick>> ticks;
  std::string path;

  explicit Sample(const std::string& name) : path((fs::temp_directory_path() / name).string()) {
    meta.engine_version = "0.1.0";
    meta.build = "Release GNU 12.2.0 on test";
    meta.scene_path = "/abs/scene.json";
    meta.scene_text = R"({"mesh": {"file": "m.msh"}, "note": "quotes \" and \\ survive"})";
    meta.patches = {{"solver.preset", "\"realtime\"", "--set solver.preset=realtime"}};
    meta.mesh_file = "/abs/m.msh";
    meta.mesh_hash = 0x0123456789abcdefULL;
    meta.compliance = {1e-3, 0.0};
    meta.snapshot_every = 5;
    for (int k = 1; k <= 12; ++k) {
      ReplayFrame f;
      f.frame = k;
      f.time = k / 30.0;
      f.tools.resize(2);
      f.tools[0].before.p = {0.01 * k, -0.02, 0.3};
      f.tools[0].after.p = {0.01 * (k + 1), -0.02, 0.3};
      f.tools[1].after.q = {std::sqrt(0.5), 0.0, std::sqrt(0.5), 0.0};
      f.tools[1].after.jaw = 0.25 * (k % 4);
      f.late_factor_call = k % 3 == 0 ? 1 : -1;
      f.cut_frame = k == 7;
      f.contacts = k;
      f.grasp_rows = 3;
      f.swept_triangles = 2 * k;
      for (int h = 0; h < kNumStateFields; ++h) f.hashes[h] = 1000003ULL * k + h;
      if (k % 5 == 0) {
        State s;
        s.time = f.time;
        s.frame = k;
        s.u = {1.0 * k, 2.0, 3.0};
        s.v = s.a = {0.0, 0.0, 0.0};
        s.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
        std::ostringstream os;
        write_state(os, s);
        f.snapshot = os.str();
      }
      frames.push_back(f);
      std::vector<ReplayTick> t(33);
      for (int i = 0; i < 33; ++i) {
        t[i].frame = k;
        t[i].t = (k - 1) / 30.0 + i * 1e-3;
        t[i].raw.p = {0.1, 0.2, i * 1e-4};
        t[i].raw.jaw = i == 5 ? NAN : 0.0;  // a device may report nan
        t[i].buttons = i % 2;
        t[i].have_reading = i != 7;
        t[i].force = {0.0, 0.0, 0.01 * i};
      }
      ticks.push_back(t);
    }
    ReplayWriter w(path, meta);
    for (int k = 0; k < 12; ++k) {
      w.add_frame(frames[k]);
      w.add_ticks(ticks[k]);
    }
    w.finish("");
  }
  ~Sample() { fs::remove(path); }
};

void expect_pose_eq(const ToolPose& a, const ToolPose& b) {
  EXPECT_EQ(a.p, b.p);
  EXPECT_EQ(a.q, b.q);
  EXPECT_EQ(a.jaw, b.jaw);
}

TEST(ReplayFile, RoundTripsEveryRecordExactly) {
  const Sample s("incise_replay_roundtrip.replay");
  EXPECT_FALSE(fs::exists(s.path + ".tmp")) << "the temporary file is renamed into place";
  const ReplayFile r = read_replay(s.path);
  EXPECT_EQ(r.bytes, fs::file_size(s.path));
  EXPECT_EQ(r.meta.engine_version, s.meta.engine_version);
  EXPECT_EQ(r.meta.build, s.meta.build);
  EXPECT_EQ(r.meta.scene_path, s.meta.scene_path);
  EXPECT_EQ(r.meta.scene_text, s.meta.scene_text);
  EXPECT_EQ(r.meta.patches, s.meta.patches);
  EXPECT_EQ(r.meta.mesh_file, s.meta.mesh_file);
  EXPECT_EQ(r.meta.mesh_hash, s.meta.mesh_hash);
  EXPECT_EQ(r.meta.compliance, s.meta.compliance);
  EXPECT_EQ(r.meta.snapshot_every, 5);
  ASSERT_EQ(r.frames.size(), 12u);
  for (size_t k = 0; k < 12; ++k) {
    const ReplayFrame &a = r.frames[k], &b = s.frames[k];
    EXPECT_EQ(a.frame, b.frame);
    EXPECT_EQ(a.time, b.time);
    ASSERT_EQ(a.tools.size(), 2u);
    for (size_t i = 0; i < 2; ++i) {
      expect_pose_eq(a.tools[i].before, b.tools[i].before);
      expect_pose_eq(a.tools[i].after, b.tools[i].after);
    }
    EXPECT_EQ(a.late_factor_call, b.late_factor_call);
    EXPECT_EQ(a.cut_frame, b.cut_frame);
    EXPECT_EQ(a.contacts, b.contacts);
    EXPECT_EQ(a.grasp_rows, b.grasp_rows);
    EXPECT_EQ(a.swept_triangles, b.swept_triangles);
    EXPECT_EQ(a.hashes, b.hashes);
    EXPECT_EQ(a.snapshot, b.snapshot);
  }
  std::istringstream snap(r.frames[9].snapshot);
  EXPECT_EQ(read_state(snap, "snapshot").u, (std::vector<double>{10.0, 2.0, 3.0}));
  ASSERT_EQ(r.ticks.size(), 12u * 33u);
  const ReplayTick& t = r.ticks[33 + 5];
  EXPECT_EQ(t.frame, 2);
  EXPECT_TRUE(std::isnan(t.raw.jaw));
  EXPECT_EQ(r.ticks[33 + 7].have_reading, false);
  EXPECT_EQ(r.ticks[33 + 9].force[2], 0.09);
  EXPECT_EQ(r.end_status, "");
}

// Cut off at every 1/50th of its length: an error each time, naming the
// offset (and, past the META record, the frame it stops after).
TEST(ReplayFile, TruncatedAnywhereIsAnErrorNamingTheOffset) {
  const Sample s("incise_replay_truncated.replay");
  const std::string bytes = slurp(s.path);
  for (int k = 0; k < 50; ++k) {
    const size_t n = bytes.size() * k / 50;
    try {
      parse_replay(bytes.substr(0, n), "t.replay");
      ADD_FAILURE() << "cut at " << n << " of " << bytes.size() << " bytes was accepted";
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind("t.replay: ", 0), 0u) << msg;
      if (n >= 12) {
        EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;
      }
      if (n > bytes.size() / 5) {
        EXPECT_NE(msg.find("frame"), std::string::npos) << msg;
      }
    }
  }
}

// A single byte changed anywhere (every 7th byte, and every byte of the
// header and of the last record): an error each time, never a replay that
// differs from what was recorded.
TEST(ReplayFile, AFlippedByteAnywhereIsAnError) {
  const Sample s("incise_replay_flipped.replay");
  const std::string bytes = slurp(s.path);
  int tried = 0;
  for (size_t i = 0; i < bytes.size(); ++i) {
    if (!(i < 64 || i % 7 == 0 || i + 64 > bytes.size())) continue;
    for (unsigned char mask : {0x01, 0x80}) {
      std::string b = bytes;
      b[i] = static_cast<char>(static_cast<unsigned char>(b[i]) ^ mask);
      ++tried;
      EXPECT_THROW(parse_replay(b, "f.replay"), Error) << "byte " << i << " ^ " << int(mask);
    }
  }
  EXPECT_GT(tried, 2000);
}

TEST(ReplayFile, WrongMagicVersionAndTrailingBytesAreNamed) {
  const Sample s("incise_replay_version.replay");
  const std::string bytes = slurp(s.path);
  const auto message = [](const std::string& b) {
    try {
      parse_replay(b, "v.replay");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("{\"mesh\": 1}").find("not an incise replay"), std::string::npos);
  std::string v2 = bytes;
  v2[8] = 2;
  EXPECT_NE(message(v2).find("replay format version 2; this build reads version 1"), std::string::npos) << message(v2);
  EXPECT_NE(message(bytes + "x").find("1 bytes after the END record"), std::string::npos) << message(bytes + "x");
}

// A chunk with a valid checksum whose counts claim more records than it
// holds: refused before anything is allocated for them.
TEST(ReplayFile, CountsBeyondTheChunkAreRefusedBeforeAllocating) {
  const Sample s("incise_replay_counts.replay");
  std::string b = slurp(s.path);
  // The first TICK chunk: u32 tag, u64 length, then the u64 tick count.
  const size_t at = b.find("TICK");
  ASSERT_NE(at, std::string::npos);
  std::uint64_t len = 0;
  std::memcpy(&len, b.data() + at + 4, 8);
  const std::uint64_t huge = 1ULL << 60;
  std::memcpy(b.data() + at + 12, &huge, 8);
  const std::uint64_t sum = fnv1a(b.data() + at, 12 + len);
  std::memcpy(b.data() + at + 12 + len, &sum, 8);
  try {
    parse_replay(b, "c.replay");
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("ticks claims 1152921504606846976 records"), std::string::npos) << e.what();
  }
}

// An unfinished writer leaves nothing behind: no file, no temporary.
TEST(ReplayFile, AnUnfinishedWriterRemovesItsTemporaryFile) {
  const std::string path = (fs::temp_directory_path() / "incise_replay_unfinished.replay").string();
  {
    ReplayMeta m;
    ReplayWriter w(path, m);
    EXPECT_TRUE(fs::exists(path + ".tmp"));
  }
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  EXPECT_FALSE(fs::exists(path));
  EXPECT_THROW(read_replay(path), Error);
  EXPECT_THROW(read_replay(fs::temp_directory_path().string()), Error) << "a folder is not a replay";
}

}  // namespace
}  // namespace incise
