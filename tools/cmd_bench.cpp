// incise bench: step a scene without output and report per-stage timings.
#include <cstdio>

#include "engine/simulation.h"
#include "engine/timing_stats.h"
#include "tools/commands.h"
#include "tools/frame_loop.h"
#include "tools/frame_trace.h"
#include "tools/solver_report.h"
#include "tools/render_stage.h"
#include "tools/timing_json.h"

namespace incise {

namespace {
struct BenchOptions {
  std::string scene, json, trace;
  int frames = 100, warmup = 0;
  double bandwidth_gbs = 11.0;
  SolverOverrides solver;
  bool render = false;  // the render stage is 0 unless asked for
  std::string platform;
};

void bench(const BenchOptions& o) {
  auto sim = load_checked_simulation(o.scene);
  apply_solver_overrides(*sim, o.solver);
  print_model_summary(*sim);
  std::unique_ptr<Renderer> renderer = o.render ? make_renderer(sim->scene.render, o.platform) : nullptr;
  std::vector<FrameTiming> timings;
  timings.reserve(o.frames);
  for (int k = 0; k < o.warmup + o.frames; ++k) {
    FrameTiming t = advance_frame(*sim);
    if (renderer) render_stage(*renderer, *sim, t);
    if (k >= o.warmup) timings.push_back(t);
  }
  const TimingSummary s = summarize(timings);
  std::printf("%s", format_summary(s).c_str());
  std::printf("%s", format_solver_report(solver_report(*sim, timings, s, o.bandwidth_gbs)).c_str());
  if (!o.json.empty()) {
    write_timing_json(o.json, *sim, s, &timings, o.bandwidth_gbs);
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
  cmd->add_option("--trace", opts->trace, "Write one CSV row per timed frame: stages, cutting parts, CG iterations");
  add_solver_options(cmd, opts->solver);
  cmd->add_flag("--render", opts->render, "Render each frame offscreen (scene's render settings) and time it as the render stage");
  cmd->add_option("--egl-platform", opts->platform, "auto (default; or INCISE_EGL_PLATFORM), device or surfaceless")
      ->check(CLI::IsMember({"auto", "device", "surfaceless"}));
  cmd->callback([opts] { bench(*opts); });
}

}  // namespace incise
