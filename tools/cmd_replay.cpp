// incise replay: step a recorded run again from its replay file
// (engine/runtime/replay_file.h): the embedded scene, the recorded instrument
// poses instead of trajectories and devices, the recorded solver choices
// instead of the clock's; --verify compares the State's hashes frame by frame.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "engine/runtime/replay_file.h"
#include "engine/util/error.h"
#include "tools/build_info.h"
#include "tools/commands.h"
#include "tools/option_checks.h"
#include "tools/frame_loop.h"
#include "tools/frame_outputs.h"
#include "tools/progress_bar.h"

namespace incise {

namespace {

struct ReplayOptions {
  std::string file, out, render_dir, platform;
  bool verify = false;
  double tolerance = -1.0;  // >= 0: compare snapshots field by field instead of bit for bit
  int frames = 0;           // 0: all recorded
};

// Largest |a - b| over a field, relative to the largest |recorded value|.
struct FieldDiff {
  double abs = 0.0, rel = 0.0;
};
FieldDiff field_diff(const std::vector<double>& now, const std::vector<double>& rec) {
  FieldDiff d;
  if (now.size() != rec.size()) return {INFINITY, INFINITY};
  double scale = 0.0;
  for (size_t i = 0; i < rec.size(); ++i) {
    d.abs = std::max(d.abs, std::abs(now[i] - rec[i]));
    scale = std::max(scale, std::abs(rec[i]));
  }
  d.rel = scale > 0.0 ? d.abs / scale : d.abs;
  return d;
}

// "u 3.1e-12 (rel 2.0e-09), v ..." against a snapshot; the largest relative difference in *worst.
std::string describe_diff(const State& now, const State& rec, double* worst) {
  const std::pair<const char*, FieldDiff> d[] = {{"u", field_diff(now.u, rec.u)},
                                                 {"v", field_diff(now.v, rec.v)},
                                                 {"a", field_diff(now.a, rec.a)},
                                                 {"R", field_diff(now.R, rec.R)}};
  std::string s;
  *worst = 0.0;
  char buf[96];
  for (const auto& [name, x] : d) {
    std::snprintf(buf, sizeof buf, "%s%s %.2e (rel %.2e)", s.empty() ? "" : ", ", name, x.abs, x.rel);
    s += buf;
    *worst = std::max(*worst, x.rel);
  }
  const bool topo = now.cut_progress == rec.cut_progress && now.swept == rec.swept && now.swept_tool == rec.swept_tool;
  if (!topo) {
    s += ", topology differs";
    *worst = INFINITY;
  }
  return s;
}

std::string differing_fields(const std::array<std::uint64_t, kNumStateFields>& a,
                             const std::array<std::uint64_t, kNumStateFields>& b) {
  std::string s;
  for (int k = 0; k < kNumStateFields; ++k)
    if (a[k] != b[k]) s += std::string(s.empty() ? "" : ", ") + kStateFieldNames[k];
  return s;
}

void replay(const ReplayOptions& o) {
  const ReplayFile r = read_replay(o.file);
  const ReplayMeta& m = r.meta;
  std::printf("replay %s: %zu frames, %.1f KB (%.2f KB per frame), recorded by incise %s (%s)\n", o.file.c_str(),
              r.frames.size(), r.bytes / 1024.0, r.bytes / 1024.0 / std::max<size_t>(1, r.frames.size()),
              m.engine_version.c_str(), m.build.c_str());
  const std::string here = build_flags() + " on " + machine_name();
  const bool same_build = m.engine_version == engine_version() && m.build == here;
  if (!same_build)
    std::printf("  replayed by incise %s (%s): a bit-for-bit match is not expected across builds or machines; "
                "--tolerance compares the fields\n",
                engine_version().c_str(), here.c_str());
  std::vector<ScenePatch> patches;
  for (const auto& p : m.patches) patches.push_back({p[0], p[1], p[2]});
  Scene scene = parse_scene(m.scene_text, m.scene_path, patches, /*trajectories_needed=*/r.frames.empty());
  // The mesh is not embedded (it can be large): the recorded hash says whether it is the same file.
  const std::uint64_t mesh_hash = replay_file_hash(scene.mesh_file, "mesh");
  if (mesh_hash != m.mesh_hash)
    throw Error(o.file + ": the mesh " + scene.mesh_file + " has changed since the recording (its hash differs)");
  for (const auto& [file, hash] : m.files)
    if (replay_file_hash(file, "cut surface") != hash)
      throw Error(o.file + ": the cut surface " + file + " has changed since the recording (its hash differs)");
  // The recorded poses stand in for the trajectories: their files are not
  // needed (a replay used to fail without them).
  auto sim = load_checked_simulation(std::move(scene), r.frames.empty() ? nullptr : &r.frames[0].tools);
  Simulation& s = *sim;
  if (m.compliance.size() != s.scene.instruments.size())
    throw Error(o.file + ": recorded with " + std::to_string(m.compliance.size()) + " instruments, the scene has " +
                std::to_string(s.scene.instruments.size()));
  print_model_summary(s);
  s.ws.contacts.compliance = m.compliance;  // the haptic coupling, without the device
  if (!s.scene.instruments.empty())  // the recorded poses stand in for trajectories and devices
    s.pipeline.set(kStageToolPoses, [&r](Simulation& sm) {
      sm.tools = r.frames[static_cast<size_t>(sm.state.frame)].tools;
    });
  // --out asks for the series: written even where the scene says output.vtu
  // false (it used to write nothing, in silence).
  if (!o.out.empty()) s.scene.output.write_vtu = true;
  FrameOutputs outputs(s, std::filesystem::path(m.scene_path).stem().string(), o.out, o.render_dir, o.platform);
  const int frames = o.frames > 0 ? std::min<int>(o.frames, static_cast<int>(r.frames.size()))
                                  : static_cast<int>(r.frames.size());
  if (o.frames > static_cast<int>(r.frames.size()))
    std::printf("  --frames %d: the recording has %zu frames; replaying those\n", o.frames, r.frames.size());
  const bool compare = o.verify || o.tolerance >= 0.0;
  int matched = 0, snapshots = 0;
  double worst = 0.0;
  ProgressBar progress(frames, s.model.dt);
  for (int k = 0; k < frames; ++k) {
    const ReplayFrame& f = r.frames[static_cast<size_t>(k)];
    s.ws.imposed_late_factor_call = f.late_factor_call;
    advance_frame(s);
    if (s.ws.timing.late_factor_call != f.late_factor_call)
      throw Error(o.file + ": frame " + std::to_string(f.frame) +
                  ": the recorded solver choice (background factor taken at refresh call " +
                  std::to_string(f.late_factor_call) + ") could not be imposed (" +
                  std::to_string(s.ws.timing.late_factor_call) + "); the replay has diverged before this frame");
    outputs.after_frame(s);
    progress.update(k + 1);
    if (!compare) continue;
    const auto h = state_field_hashes(s.state);
    const bool equal = h == f.hashes;
    matched += equal;
    std::string diff;
    double rel = 0.0;
    if (!f.snapshot.empty()) {
      std::istringstream is(f.snapshot);
      diff = describe_diff(s.state, read_state(is, o.file + ": frame " + std::to_string(f.frame) + " snapshot"), &rel);
      ++snapshots;
      worst = std::max(worst, rel);
    }
    if (o.tolerance >= 0.0) {
      if (!f.snapshot.empty()) std::printf("frame %d: %s%s\n", f.frame, equal ? "equal; " : "", diff.c_str());
      continue;
    }
    if (!equal) {
      progress.finish();
      throw Error(o.file + ": frame " + std::to_string(f.frame) + " (t = " + std::to_string(f.time) +
                  " s) differs from the recording in " + differing_fields(h, f.hashes) +
                  (diff.empty() ? " (no snapshot at this frame)" : "; largest differences: " + diff) +
                  (f.frame > 1 ? "; frames 1-" + std::to_string(f.frame - 1) + " matched bit for bit"
                               : "; it is the first frame"));
    }
  }
  progress.finish();
  outputs.finish(s, frames, 1.0 / s.model.dt);
  if (o.tolerance >= 0.0) {
    std::printf("replay: %d of %d frames equal bit for bit; largest relative difference over %d snapshots %.3g "
                "(tolerance %g)\n",
                matched, frames, snapshots, worst, o.tolerance);
    if (snapshots == 0 && matched < frames)
      throw Error(o.file + ": no State snapshot among the replayed frames to compare, and " +
                  std::to_string(frames - matched) + " frames differ bit for bit (record with --record-states N)");
    if (!(worst <= o.tolerance)) {
      char buf[160];
      std::snprintf(buf, sizeof buf, ": a snapshot differs by %.3g relative, more than --tolerance %g", worst, o.tolerance);
      throw Error(o.file + buf);
    }
  } else if (o.verify) {
    if (frames > 0) std::printf("replay: all %d frames match bit for bit (u, v, a, R, topology and clock hashes)\n", frames);
    else std::printf("replay: the recording holds no frame to compare\n");
  } else {
    std::printf("replay: %d frames stepped\n", frames);
  }
  if (r.end_status.empty() || frames != static_cast<int>(r.frames.size())) return;
  std::printf("the recorded run stopped after frame %zu: %s\n", r.frames.size(), r.end_status.c_str());
  if (!compare) return;
  // The failing frame itself is not in the recording (it stopped before its
  // end). Without instruments nothing else drives it: step it and check the
  // run fails again, so a verified replay of a failed run checks the
  // failure too (it used to end "all 0 frames match bit for bit").
  if (!s.scene.instruments.empty()) {
    std::printf("replay: the failing frame's instrument poses are not in the recording: the failure is not replayed\n");
    return;
  }
  std::string again;
  try {
    advance_frame(s);
  } catch (const std::exception& e) {
    again = e.what();
  }
  if (again.empty())
    throw Error(o.file + ": the recorded run stopped after frame " + std::to_string(r.frames.size()) + " (" +
                r.end_status + "), the replay stepped the next frame without error");
  std::printf("replay: the failure reproduces at frame %zu: %s\n", r.frames.size() + 1, again.c_str());
}

}  // namespace

void add_replay_command(CLI::App& app) {
  auto opts = std::make_shared<ReplayOptions>();
  auto* cmd = app.add_subcommand("replay", "Step a recorded run again (incise run --record F) and check it");
  cmd->add_option("file", opts->file, "Replay file")->required();
  cmd->add_flag("--verify", opts->verify,
                "Compare the State's hash after every frame with the recording; report the first frame that differs "
                "and in which field (u, v, a, R, topology)");
  cmd->add_option("--tolerance", opts->tolerance,
                  "Across builds or machines: compare the recorded State snapshots field by field and report the "
                  "largest relative difference per snapshot frame; fail above this")
      ->check(finite_in(0, 1e6));
  cmd->add_option("--frames", opts->frames, "Replay only the first N frames")
      ->check(integer_in(1, kMaxOptionFrames, kFramesWhy));
  cmd->add_option("--out", opts->out, "Output folder for a .pvd/.vtu series of the replay (written whatever the scene's output.vtu says)");
  cmd->add_option("--render", opts->render_dir, "Render every frame offscreen to DIR/frame_00000.png ... (+ MP4)");
  add_egl_platform_option(*cmd, opts->platform);
  cmd->callback([opts] { replay(*opts); });
}

}  // namespace incise
