// incise bench: step a scene without output and report per-stage timings.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <thread>

#include "engine/runtime/simulation.h"
#include "render/render_stage.h"
#include "engine/runtime/timing_stats.h"
#include "tools/commands.h"
#include "tools/frame_loop.h"
#include "tools/frame_trace.h"
#include "tools/solver_report.h"
#include "tools/timing_json.h"

namespace incise {

namespace {
struct BenchOptions {
  std::string scene, json, trace;
  int frames = 100, warmup = 0;
  double bandwidth_gbs = 11.0;
  double pace_hz = 0.0;  // start frames at this rate (a real-time loop); 0 = back to back
  std::vector<ScenePatch> patches;  // --set and the solver flags, in order
  bool render = false;  // the render stage is 0 unless asked for
  std::string platform;
};

void bench(const BenchOptions& o) {
  auto sim = load_checked_simulation(o.scene, o.patches);
  print_model_summary(*sim);
  std::unique_ptr<Renderer> renderer = o.render ? make_renderer(sim->scene.render, o.platform) : nullptr;
  Image image;
  if (renderer) install_render_stage(*sim, *renderer, &image);
  std::vector<FrameTiming> timings;
  timings.reserve(o.frames);
  // Paced: a frame starts every 1/pace_hz s, or at once after one that ran
  // over, as a real-time loop does; the frame's own time is what is reported.
  // Work beside the step (the background factorization, the next cut's
  // preparation) then has the rest of each period, as it would in the loop.
  using clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<clock::duration>(
      std::chrono::duration<double>(o.pace_hz > 0 ? 1.0 / o.pace_hz : 0.0));
  auto next = clock::now();
  if (o.pace_hz > 0) std::printf("frames started at %.4g Hz (the rest of each period is idle for background work)\n", o.pace_hz);
  for (int k = 0; k < o.warmup + o.frames; ++k) {
    if (o.pace_hz > 0) std::this_thread::sleep_until(next);
    FrameTiming t = advance_frame(*sim);
    next = std::max(next + period, clock::now());
    if (k >= o.warmup) timings.push_back(t);
  }
  const TimingSummary s = summarize(timings);
  std::printf("%s", format_summary(s).c_str());
  std::printf("%s", format_solver_report(solver_report(*sim, timings, s, o.bandwidth_gbs)).c_str());
  if (!o.json.empty()) {
    write_timing_json(o.json, *sim, s, &timings, o.bandwidth_gbs, o.pace_hz);
    std::printf("wrote %s\n", o.json.c_str());
  }
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
  cmd->add_option("--frames", opts->frames, "Frames to time")->check(CLI::PositiveNumber);
  cmd->add_option("--warmup", opts->warmup, "Frames stepped before timing starts")->check(CLI::NonNegativeNumber);
  cmd->add_option("--json", opts->json, "Write the summary as JSON");
  cmd->add_option("--bandwidth-gbs", opts->bandwidth_gbs,
                  "Memory bandwidth (GB/s) for the one-substitution limit the frame time is compared with")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--pace", opts->pace_hz,
                  "Start frames at this rate in Hz, as the 30 Hz loop does (0: back to back, the default); background "
                  "work gets the rest of each period")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--trace", opts->trace, "Write one CSV row per timed frame: stages, cutting parts, CG iterations");
  add_set_option(*cmd, opts->patches);
  add_solver_aliases(*cmd, opts->patches);
  cmd->add_flag("--render", opts->render, "Render each frame offscreen (scene's render settings) and time it as the render stage");
  cmd->add_option("--egl-platform", opts->platform, "auto (default; or INCISE_EGL_PLATFORM), device or surfaceless")
      ->check(CLI::IsMember({"auto", "device", "surfaceless"}));
  cmd->callback([opts] { bench(*opts); });
}

}  // namespace incise
