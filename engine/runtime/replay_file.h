#pragma once
// The replay file (`incise run --record F`, `incise replay F`): everything a
// run consumed that is not in the scene, mesh and code, so the run can be
// stepped again bit for bit, and the State's hash after every frame to check
// that it was.
//
// Layout (little-endian, docs/replay.md):
//   header   "INCREPLY" (8 bytes), u32 version
//   chunks   u32 tag, u64 payload length, payload, u64 FNV-1a of (tag, length, payload)
//     META   JSON: engine version and build, the scene's text and path, the
//            --set patches, the mesh file and its hash, the coupling
//            compliance of each instrument, the snapshot interval
//     FRAM   one per frame, in order: its poses, clock decisions, events, hashes
//     TICK   haptic device samples (1 kHz) drained after a frame
//     END    the frame count and how the run ended ("" completed, else the error)
// Every byte after the header is under a checksum, so a flipped byte or a
// cut-off file is an error naming the offset and frame, never a wrong replay.
#include <array>
#include <cstdint>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "engine/dynamics/state.h"
#include "engine/runtime/tool_pose.h"

namespace incise {

inline constexpr std::uint32_t kReplayVersion = 1;

struct ReplayMeta {
  std::string engine_version, build;  // of the recording binary (tools/build_info.h)
  std::string scene_path;             // absolute: relative paths in the scene resolve against its folder
  std::string scene_text;             // the scene file as read
  std::vector<std::array<std::string, 3>> patches;  // --set: key, value, as given
  std::string mesh_file;              // as the scene resolved it
  std::uint64_t mesh_hash = 0;        // FNV-1a of its bytes (replay_file_hash)
  // Other files the run read whose content a replay needs (cut surfaces), with their hashes.
  std::vector<std::pair<std::string, std::uint64_t>> files;
  std::vector<double> compliance;     // (instruments) ContactRows::compliance of the run (a haptic coupling)
  int snapshot_every = 0;             // a State snapshot every this many frames (0: none)
};

// One frame: state.frame goes from frame - 1 to frame.
struct ReplayFrame {
  int frame = 0;
  double time = 0.0;               // state.time after it
  std::vector<ToolFrame> tools;    // (instruments) the poses its tool-poses stage produced
  int late_factor_call = -1;       // FrameTiming::late_factor_call (the clock's choice)
  bool cut_frame = false;          // events, for reading and for a replay's report
  int contacts = 0, grasp_rows = 0, swept_triangles = 0;
  std::array<std::uint64_t, kNumStateFields> hashes{};  // state_field_hashes after it
  std::string snapshot;            // write_state bytes, or empty
};

// A device reading of the 1 kHz loop (haptics/haptic_loop.h, TickRecord).
struct ReplayTick {
  int frame = 0;                   // the frames done when it was drained
  double t = 0.0;                  // s since the loop started
  ToolPose raw;                    // as the device reported it
  std::uint32_t buttons = 0;
  bool have_reading = false;
  std::array<double, 3> force{};   // sent to the device (N)
};

struct ReplayFile {
  ReplayMeta meta;
  std::vector<ReplayFrame> frames;
  std::vector<ReplayTick> ticks;
  std::string end_status;          // "" the run completed, else why it stopped
  size_t bytes = 0;                // file size
};

// Parses a whole file's bytes. Throws incise::Error naming `what`, the byte
// offset and the frame: not a replay, another version, a checksum mismatch,
// a truncation, a count larger than the bytes left, a frame out of order.
ReplayFile parse_replay(const std::string& bytes, const std::string& what);
// Reads `path` (a regular file, at most 16 GiB) and parses it.
ReplayFile read_replay(const std::string& path);

// FNV-1a of a file's bytes (the mesh's, a cut surface's). Throws
// incise::Error naming `what` when it cannot be read.
std::uint64_t replay_file_hash(const std::string& path, const char* what);

// Writes a replay as the run goes: the header and META at construction,
// then frames and ticks, END at finish(). Everything goes to PATH.tmp, renamed
// to PATH by finish(); destroyed unfinished, the temporary file is removed.
class ReplayWriter {
 public:
  ReplayWriter(std::string path, const ReplayMeta& meta);
  ~ReplayWriter();
  ReplayWriter(const ReplayWriter&) = delete;
  ReplayWriter& operator=(const ReplayWriter&) = delete;
  void add_frame(const ReplayFrame& f);
  void add_ticks(const std::vector<ReplayTick>& ticks);
  void finish(const std::string& status);
  size_t bytes() const { return bytes_; }
  int frames() const { return frames_; }
  const std::string& path() const { return path_; }

 private:
  void chunk(const char tag[4]);
  std::string path_, tmp_;
  std::ofstream os_;
  std::string buf_;  // the chunk being built (reused)
  size_t bytes_ = 0;
  int frames_ = 0;
  bool finished_ = false;
};

}  // namespace incise
