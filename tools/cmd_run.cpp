// incise run: step the dynamics, write a ParaView series and a timing summary;
// with --haptics, beside the 1 kHz haptic loop of the scene's device, in real time.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include <nlohmann/json.hpp>

#include "engine/util/error.h"
#include "engine/output/result_grid.h"
#include "engine/runtime/simulation.h"
#include "engine/runtime/timing_stats.h"
#include "render/video.h"
#include "tools/commands.h"
#include "tools/option_checks.h"
#include "tools/frame_loop.h"
#include "render/render_stage.h"
#include "tools/solver_report.h"
#include "tools/timing_json.h"
#include "haptics/haptic_stage.h"
#include "haptics/tick_stats.h"
#include "engine/util/file_io.h"
#include "haptics/tick_log.h"
#include "tools/frame_outputs.h"
#include "tools/haptics_report.h"
#include "tools/interrupt.h"
#include "tools/progress_bar.h"
#include "tools/record_stage.h"

namespace incise {

namespace {
struct RunOptions {
  std::string scene;
  int frames = 0;  // 0: the scene's run.frames
  std::string out;
  std::string render_dir, platform;  // --render DIR: PNG frames (and an MP4 when ffmpeg is installed)
  std::vector<ScenePatch> patches;   // --set
  bool haptics = false;              // --haptics: the scene's device on its 1 kHz thread
  std::string haptics_dir;           // where the haptic logs go (default: --out, output.dir, else .)
  double pace_hz = -1.0;             // frames started at this rate; < 0: 1/dt with --haptics, else back to back
  std::string record;                // --record F: a replay file (docs/replay.md)
  int record_states = 30;            // --record-states N: a State snapshot every N frames
};

// A haptic run's ticks as they are drained each frame: handed to the replay
// record, summed into the figures and appended to the force and device logs,
// then dropped, so a long run holds none (haptics/tick_log.h).
struct HapticRunLog {
  HapticRunLog(const HapticLoop& loop, const std::string& dir)
      : dir(dir), summary(loop.force_limit()), files((create(dir), file("haptics_force.csv")), file("haptics_device.csv")) {}
  std::string dir;
  TickSummary summary;
  TickLogWriter files;
  std::vector<TickRecord> records;  // drained, not yet taken
  std::vector<HapticEvent> events;
  std::string file(const char* name) const { return (std::filesystem::path(dir.empty() ? "." : dir) / name).string(); }
  static void create(const std::string& d) {
    if (!d.empty()) std::filesystem::create_directories(d);
  }
  void take(ReplayWriter* record, int frame) {
    if (record) record_ticks(*record, records, 0, frame);
    for (const TickRecord& r : records) summary.add(r);
    files.append(records);
    records.clear();
  }
  // Stops the loop and writes the logs and figures.
  void finish(HapticLoop& loop, ReplayWriter* record, int frame) {
    loop.stop();
    loop.drain(records, events);
    take(record, frame);
    const nlohmann::json j = report_haptic_loop(loop, summary.stats(), events);
    files.finish();
    write_event_log(file("haptics_events.csv"), events);
    write_file_atomic(file("haptics.json"), j.dump(2) + "\n");
    std::printf("wrote %s, haptics_device.csv, haptics_events.csv, haptics.json\n", file("haptics_force.csv").c_str());
  }
};

void run(const RunOptions& o) {
  auto sim = load_checked_simulation(o.scene, o.patches);
  const State& s = sim->state;
  print_model_summary(*sim);
  const int frames = o.frames > 0 ? o.frames : sim->scene.frames;
  const std::string out = !o.out.empty() ? o.out : sim->scene.output.dir;
  FrameOutputs outputs(*sim, std::filesystem::path(o.scene).stem().string(), out, o.render_dir, o.platform);
  std::shared_ptr<HapticLoop> haptic;
  if (o.haptics) {
    haptic = install_haptics(*sim);
    if (!haptic) std::printf("haptics: %s declares no haptic device (\"haptics\"): no haptic thread\n", o.scene.c_str());
  }
  // After the haptics: the replay keeps the coupling compliance they set.
  std::shared_ptr<ReplayWriter> record;
  if (!o.record.empty()) record = install_record_stage(*sim, o.record, o.patches, o.record_states, frames);
  const double pace = o.pace_hz >= 0.0 ? o.pace_hz : haptic ? 1.0 / sim->model.dt : 0.0;
  size_t events_shown = 0;
  const std::string haptics_dir = !o.haptics_dir.empty() ? o.haptics_dir : out;
  std::unique_ptr<HapticRunLog> ticks;
  if (haptic) {
    ticks = std::make_unique<HapticRunLog>(*haptic, haptics_dir);
    // a frame's ticks, and twice that for a late frame, without reallocating
    ticks->records.reserve(static_cast<size_t>(2 * sim->model.dt * haptic->settings().rate_hz) + 64);
    haptic->start();
    std::printf("haptics: %s drives %s at %.0f Hz; %s\n", haptic->device().describe().c_str(),
                sim->scene.instruments[static_cast<size_t>(sim->scene.haptics.instrument)].name.c_str(),
                haptic->settings().rate_hz, haptic->scheduling().c_str());
  }
  if (pace > 0.0) std::printf("frames started at %.4g Hz\n", pace);
  using clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<clock::duration>(std::chrono::duration<double>(pace > 0.0 ? 1.0 / pace : 0.0));
  auto next = clock::now();
  std::vector<FrameTiming> timings;
  timings.reserve(frames);
  Stopwatch wall;
  ProgressBar progress(frames, sim->model.dt);
  catch_interrupts();
  int done = frames;  // frames stepped: fewer when interrupted
  for (int k = 0; k < frames; ++k) {
    if (interrupt_signal()) {
      done = k;
      break;
    }
    if (pace > 0.0) std::this_thread::sleep_until(next);
    FrameTiming t;
    try {
      t = advance_frame(*sim);
    } catch (...) {  // the hand's record and the replay of a run that failed are worth keeping
      progress.finish();
      std::string what = "unknown error";
      try {
        throw;
      } catch (const std::exception& e) {
        what = e.what();
      } catch (...) {
      }
      try {
        if (haptic) ticks->finish(*haptic, record.get(), s.frame);
        if (record) {
          record->finish("failed after " + std::to_string(record->frames()) + " recorded frames: " + what);
          std::printf("wrote %s (%d frames, up to the failure)\n", record->path().c_str(), record->frames());
        }
      } catch (const std::exception& e) {  // (the run's own error is the one to report)
        std::fprintf(stderr, "incise: could not keep the logs of the failed run: %s\n", e.what());
      }
      throw;
    }
    next = std::max(next + period, clock::now());
    if (haptic) {
      haptic->drain(ticks->records, ticks->events);
      ticks->take(record.get(), s.frame);
      const std::vector<HapticEvent>& events = ticks->events;
      for (; events_shown < events.size() && events_shown < 20; ++events_shown)
        std::fprintf(stderr, "haptics: %s%s\n", format_event(events[events_shown]).c_str(),
                     events_shown == 19 ? " (further events: haptics_events.csv)" : "");
    }
    outputs.after_frame(*sim);
    timings.push_back(t);
    progress.update(k + 1);
  }
  progress.finish();
  if (interrupt_signal())
    std::printf("interrupted by %s: stopped after frame %d of %d; the outputs cover the frames done\n", interrupt_name(),
                done, frames);
  const double run_ms = wall.ms();
  if (haptic) ticks->finish(*haptic, record.get(), s.frame);
  if (record) {
    record->finish(interrupt_signal() ? std::string("interrupted by ") + interrupt_name() : std::string());
    std::printf("wrote %s: %d frames, %.1f KB (%.2f KB per frame)\n", record->path().c_str(), record->frames(),
                record->bytes() / 1024.0, record->bytes() / 1024.0 / std::max(1, record->frames()));
  }
  const TimingSummary summary = summarize(timings);
  std::printf("%d frames in %.1f ms (%.2fx real time); %d numeric factorizations\n", done, run_ms,
              done * sim->model.dt * 1000.0 / run_ms, sim->ws.refactorizations);
  std::printf("%s", format_summary(summary).c_str());
  outputs.finish(*sim, done, 1.0 / sim->model.dt);
  if (!out.empty()) {
    std::filesystem::create_directories(out);
    const std::string json = (std::filesystem::path(out) / "timing.json").string();
    write_timing_json(json, *sim, summary, &timings);
    std::printf("wrote %s%s\n", outputs.writes_series() ? (out + "/*.vtu + .pvd, ").c_str() : "", json.c_str());
  }
}
}  // namespace

void add_run_command(CLI::App& app) {
  auto opts = std::make_shared<RunOptions>();
  auto* cmd = app.add_subcommand("run", "Step the dynamics at the scene's fixed dt");
  cmd->add_option("scene", opts->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--frames", opts->frames, "Frames to step (default: the scene's run.frames)")
      ->check(integer_in(1, kMaxOptionFrames, kFramesWhy));
  cmd->add_option("--out", opts->out, "Output folder for the .pvd/.vtu series and timing.json (default: output.dir)");
  cmd->add_option("--render", opts->render_dir, "Render every frame offscreen to DIR/frame_00000.png ... (+ DIR/frames.mp4 with ffmpeg)");
  add_egl_platform_option(*cmd, opts->platform);
  auto* haptics = cmd->add_flag("--haptics", opts->haptics,
                "Run the scene's haptic device (\"haptics\") on a 1 kHz thread beside frames paced at 1/dt; writes "
                "haptics_force.csv (t,fx,fy,fz,tick_us,late_us), haptics_device.csv, haptics_events.csv, haptics.json");
  cmd->add_option("--haptics-dir", opts->haptics_dir, "Folder for the haptic logs (default: --out, else output.dir, else .)")
      ->needs(haptics);  // without the thread there are no logs (it was ignored in silence)
  cmd->add_option("--pace", opts->pace_hz, "Start frames at this rate in Hz (default: 1/dt with --haptics, else back to back; 0: back to back)")
      ->check(pace_rate());
  auto* record = cmd->add_option("--record", opts->record,
                  "Record the run to a replay file F (the scene, every instrument pose and device sample, the "
                  "clock's solver choices, the State's hash after every frame): incise replay F --verify");
  cmd->add_option("--record-states", opts->record_states,
                  "With --record: a full State snapshot every N frames (default 30; 0: only the last), for "
                  "replay --tolerance and for naming the largest difference")
      ->check(integer_in(0, kMaxOptionFrames))
      ->needs(record);  // without a recording it did nothing, in silence
  add_set_option(*cmd, opts->patches);
  cmd->callback([opts] { run(*opts); });
}

}  // namespace incise
