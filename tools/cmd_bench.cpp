// incise bench: step a scene without output and report per-stage timings.
#include <cstdio>

#include "engine/simulation.h"
#include "engine/timing_stats.h"
#include "tools/commands.h"
#include "tools/frame_loop.h"
#include "tools/timing_json.h"

namespace incise {

namespace {
struct BenchOptions {
  std::string scene, json;
  int frames = 100, warmup = 0;
};

void bench(const BenchOptions& o) {
  auto sim = load_simulation(o.scene);
  print_model_summary(*sim);
  std::vector<FrameTiming> timings;
  timings.reserve(o.frames);
  for (int k = 0; k < o.warmup + o.frames; ++k) {
    const FrameTiming t = advance_frame(*sim);
    if (k >= o.warmup) timings.push_back(t);
  }
  const TimingSummary s = summarize(timings);
  std::printf("%s", format_summary(s).c_str());
  const FactorStats& f = sim->state.solver.stats();
  const double fact_ms = s.stages[kStageFactorization].median_ms;
  if (fact_ms > 0) std::printf("factorization: %.2f GFLOP/s (median)\n", f.flops / (fact_ms * 1e-3) * 1e-9);
  if (!o.json.empty()) {
    write_timing_json(o.json, *sim, s);
    std::printf("wrote %s\n", o.json.c_str());
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
  cmd->callback([opts] { bench(*opts); });
}

}  // namespace incise
