// incise bench: step a scene without output and report per-stage timings.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <thread>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "engine/runtime/simulation.h"
#include "engine/util/error.h"
#include "haptics/haptic_stage.h"
#include "tools/haptics_report.h"
#include "tools/record_stage.h"
#include "render/render_stage.h"
#include "engine/runtime/timing_stats.h"
#include "tools/commands.h"
#include "tools/option_checks.h"
#include "tools/spawn.h"
#include "tools/frame_loop.h"
#include "tools/frame_trace.h"
#include "tools/solver_report.h"
#include "tools/timing_json.h"

namespace incise {

namespace {
struct BenchOptions {
  std::string scene, json, trace;
  std::string plot;    // --plot F.png: tools/scripts/plot-budget.py over the JSON
  std::string record;  // --record F: the record stage timed, the replay written
  bool haptics = false;
  int frames = 100, warmup = 0;
  double bandwidth_gbs = 11.0;
  double pace_hz = -1.0;  // start frames at this rate (a real-time loop); 0 = back to back; < 0: 1/dt with --haptics, else 0
  std::vector<ScenePatch> patches;  // --set and the solver flags, in order
  bool render = false;  // the render stage is 0 unless asked for
  std::string platform;
};

// The plot script: INCISE_PLOT_SCRIPT, else the source tree's.
std::string plot_script() {
  const char* env = std::getenv("INCISE_PLOT_SCRIPT");
  return env && *env ? env : INCISE_SCRIPTS_DIR "/plot-budget.py";
}

void draw_plot(const std::string& json, const std::string& png) {
  const std::string script = plot_script();
  if (!std::filesystem::is_regular_file(script))
    throw Error("--plot: the plot script " + script + " is missing (set INCISE_PLOT_SCRIPT); " + json + " was written");
  const std::string python = plot_python();
  const std::string cmd = python + " " + script + " " + json + " " + png;
  int status = 0;
  try {
    status = spawn_and_wait({python, script, json, png});
  } catch (const Error& e) {
    throw Error(std::string("--plot: ") + e.what() + "; " + json + " was written");
  }
  if (status != 0)
    throw Error("--plot: " + cmd + " failed (exit " + std::to_string(status) +
                "; it needs python3 and matplotlib: apt-get install python3-matplotlib); " + json + " was written");
  std::printf("wrote %s\n", png.c_str());
}

void bench(const BenchOptions& o) {
  auto sim = load_checked_simulation(o.scene, o.patches);
  print_model_summary(*sim);
  std::unique_ptr<Renderer> renderer = o.render ? make_renderer(sim->scene.render, o.platform) : nullptr;
  Image image;
  if (renderer) install_render_stage(*sim, *renderer, &image);
  std::shared_ptr<HapticLoop> haptic;
  if (o.haptics) {
    haptic = install_haptics(*sim);
    if (!haptic) std::printf("haptics: %s declares no haptic device (\"haptics\"): no haptic thread\n", o.scene.c_str());
  }
  std::shared_ptr<ReplayWriter> record;
  if (!o.record.empty()) record = install_record_stage(*sim, o.record, o.patches, 30, o.warmup + o.frames);
  const double pace_hz = o.pace_hz >= 0.0 ? o.pace_hz : haptic ? 1.0 / sim->model.dt : 0.0;
  std::vector<TickRecord> records;
  std::vector<HapticEvent> events;
  if (haptic) {
    // (at most 70 min of ticks up front: a long run grows the log as it goes)
    records.reserve(
        static_cast<size_t>(std::min((o.warmup + o.frames) * sim->model.dt * haptic->settings().rate_hz * 1.5, 4e6)) + 64);
    haptic->start();
  }
  std::vector<FrameTiming> timings;
  timings.reserve(o.frames);
  // Paced: a frame starts every 1/pace_hz s, or at once after one that ran
  // over, as a real-time loop does; the frame's own time is what is reported.
  // Work beside the step (the background factorization, the next cut's
  // preparation) then has the rest of each period, as it would in the loop.
  using clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<clock::duration>(
      std::chrono::duration<double>(pace_hz > 0 ? 1.0 / pace_hz : 0.0));
  auto next = clock::now();
  if (pace_hz > 0) std::printf("frames started at %.4g Hz (the rest of each period is idle for background work)\n", pace_hz);
  size_t ticks_recorded = 0;
  for (int k = 0; k < o.warmup + o.frames; ++k) {
    if (pace_hz > 0) std::this_thread::sleep_until(next);
    FrameTiming t = advance_frame(*sim);
    next = std::max(next + period, clock::now());
    if (k >= o.warmup) timings.push_back(t);
    if (haptic) {
      haptic->drain(records, events);
      if (record) record_ticks(*record, records, ticks_recorded, sim->state.frame);
      ticks_recorded = records.size();
      if (k < o.warmup) {  // the statistics cover the timed frames' ticks only
        records.clear();
        ticks_recorded = 0;
      }
    }
  }
  nlohmann::json extra = nlohmann::json::object();
  if (haptic) {
    haptic->stop();
    haptic->drain(records, events);
    extra["haptics"] = report_haptic_loop(*haptic, summarize_ticks(records, haptic->force_limit()), events);
    nlohmann::json& ticks = extra["haptic_ticks"];  // the plot's second panel
    ticks["t"] = nlohmann::json::array();
    ticks["period_ms"] = nlohmann::json::array();
    for (size_t i = 1; i < records.size(); ++i) {
      ticks["t"].push_back(records[i].t);
      ticks["period_ms"].push_back(1e3 * (records[i].t - records[i - 1].t));
    }
  }
  if (record) {
    if (haptic) record_ticks(*record, records, ticks_recorded, sim->state.frame);
    record->finish("");
    std::printf("wrote %s (%d frames, %.2f KB per frame)\n", record->path().c_str(), record->frames(),
                record->bytes() / 1024.0 / std::max(1, record->frames()));
  }
  const TimingSummary s = summarize(timings);
  std::printf("%s", format_summary(s).c_str());
  std::printf("%s", format_solver_report(solver_report(*sim, timings, s, o.bandwidth_gbs)).c_str());
  std::printf("peak resident memory %.0f MB\n", peak_rss_mb());
  const std::string json = !o.json.empty() ? o.json
                           : !o.plot.empty() ? std::filesystem::path(o.plot).replace_extension(".json").string()
                                             : std::string();
  if (!json.empty()) {
    write_timing_json(json, *sim, s, &timings, o.bandwidth_gbs, pace_hz, extra);
    std::printf("wrote %s\n", json.c_str());
  }
  if (!o.plot.empty()) draw_plot(json, o.plot);
  if (!o.trace.empty()) {
    write_frame_trace(o.trace, timings, o.warmup + 1);
    std::printf("wrote %s\n", o.trace.c_str());
  }
}
}  // namespace

void add_bench_command(CLI::App& app) {
  auto opts = std::make_shared<BenchOptions>();
  auto* cmd = app.add_subcommand("bench", "Time the frames of a scene: median/p95/p99/max per stage");
  cmd->add_option("scene", opts->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--frames", opts->frames, "Frames to time")->check(integer_in(1, kMaxOptionFrames, kFramesWhy));
  cmd->add_option("--warmup", opts->warmup, "Frames stepped before timing starts")
      ->check(integer_in(0, kMaxOptionFrames, kFramesWhy));
  cmd->add_option("--json", opts->json, "Write the summary as JSON");
  cmd->add_option("--bandwidth-gbs", opts->bandwidth_gbs,
                  "Memory bandwidth (GB/s) for the one-substitution limit the frame time is compared with")
      ->check(finite_in(0.01, 100000));
  cmd->add_option("--pace", opts->pace_hz,
                  "Start frames at this rate in Hz, as the 30 Hz loop does (0: back to back; default: 1/dt with "
                  "--haptics, else 0); background work gets the rest of each period")
      ->check(pace_rate());
  cmd->add_option("--plot", opts->plot,
                  "Draw the frame budget to F.png (stages stacked per frame, the 33.3 ms line, cut frames, the haptic "
                  "tick period) with tools/scripts/plot-budget.py (python3-matplotlib); the JSON goes to --json or F.json");
  cmd->add_flag("--haptics", opts->haptics,
                "Run the scene's haptic device on its 1 kHz thread (frames paced at 1/dt) and report its tick statistics");
  cmd->add_option("--record", opts->record, "Record the run to a replay file F, timing the record stage (incise replay F)");
  cmd->add_option("--trace", opts->trace, "Write one CSV row per timed frame: stages, cutting parts, CG iterations");
  add_set_option(*cmd, opts->patches);
  add_solver_aliases(*cmd, opts->patches);
  cmd->add_flag("--render", opts->render, "Render each frame offscreen (scene's render settings) and time it as the render stage");
  add_egl_platform_option(*cmd, opts->platform);
  cmd->callback([opts] { bench(*opts); });
}

}  // namespace incise
