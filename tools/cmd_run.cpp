// incise run: step the dynamics, write a ParaView series and a timing summary.
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "engine/util/error.h"
#include "engine/output/result_grid.h"
#include "engine/runtime/simulation.h"
#include "engine/runtime/timing_stats.h"
#include "render/video.h"
#include "tools/commands.h"
#include "tools/frame_loop.h"
#include "render/render_stage.h"
#include "tools/solver_report.h"
#include "tools/timing_json.h"

namespace incise {

namespace {
struct RunOptions {
  std::string scene;
  int frames = 0;  // 0: the scene's run.frames
  std::string out;
  std::string render_dir, platform;  // --render DIR: PNG frames (and an MP4 when ffmpeg is installed)
  std::vector<ScenePatch> patches;   // --set
};

std::string frame_png(const std::string& dir, int frame) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%05d.png", frame);
  return (std::filesystem::path(dir) / name).string();
}

void run(const RunOptions& o) {
  auto sim = load_checked_simulation(o.scene, o.patches);
  const State& s = sim->state;
  print_model_summary(*sim);
  const int frames = o.frames > 0 ? o.frames : sim->scene.frames;
  const std::string out = !o.out.empty() ? o.out : sim->scene.output.dir;
  std::unique_ptr<PvdSeries> series;
  if (!out.empty() && sim->scene.output.write_vtu) {
    std::filesystem::create_directories(out);
    const std::string stem = std::filesystem::path(o.scene).stem().string();
    series = std::make_unique<PvdSeries>((std::filesystem::path(out) / (stem + ".pvd")).string());
    series->add(0.0, result_grid(sim->model, s));
  }
  std::unique_ptr<Renderer> renderer;
  Image image;
  if (!o.render_dir.empty()) {
    std::filesystem::create_directories(o.render_dir);
    renderer = make_renderer(sim->scene.render, o.platform);
    write_png(render_frame(*renderer, *sim), frame_png(o.render_dir, 0));
    install_render_stage(*sim, *renderer, &image);
  }
  std::vector<FrameTiming> timings;
  timings.reserve(frames);
  Stopwatch wall, progress;
  for (int k = 0; k < frames; ++k) {
    FrameTiming t = advance_frame(*sim);
    if (renderer) write_png(image, frame_png(o.render_dir, s.frame));
    timings.push_back(t);
    if (series && s.frame % sim->scene.output.every == 0) series->add(s.time, result_grid(sim->model, s));
    if (progress.ms() > 1000.0 || k + 1 == frames) {
      std::fprintf(stderr, "frame %d/%d  t = %.3f s  %.2f ms/frame  %d DOF\n", k + 1, frames, s.time,
                   timings.back().frame_ms, sim->model.ndof());
      progress.lap();
    }
  }
  const TimingSummary summary = summarize(timings);
  std::printf("%d frames in %.1f ms (%.2fx real time); %d numeric factorizations\n", frames, wall.ms(),
              frames * sim->model.dt * 1000.0 / wall.ms(), sim->ws.refactorizations);
  std::printf("%s", format_summary(summary).c_str());
  if (renderer) {
    std::printf("wrote %d frames %s\n", frames + 1, frame_png(o.render_dir, 0).c_str());
    const std::string video = encode_mp4(o.render_dir, 1.0 / sim->model.dt);
    std::printf("%s\n", video.empty() ? "no ffmpeg on PATH: no video (PNG frames only)" : ("wrote " + video).c_str());
  }
  if (!out.empty()) {
    const std::string json = (std::filesystem::path(out) / "timing.json").string();
    write_timing_json(json, *sim, summary, &timings);
    std::printf("wrote %s%s\n", series ? (series->files().size() ? (out + "/*.vtu + .pvd, ").c_str() : "") : "",
                json.c_str());
  }
}
}  // namespace

void add_run_command(CLI::App& app) {
  auto opts = std::make_shared<RunOptions>();
  auto* cmd = app.add_subcommand("run", "Step the dynamics at the scene's fixed dt");
  cmd->add_option("scene", opts->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--frames", opts->frames, "Frames to step (default: the scene's run.frames)")->check(CLI::PositiveNumber);
  cmd->add_option("--out", opts->out, "Output folder for the .pvd/.vtu series and timing.json (default: output.dir)");
  cmd->add_option("--render", opts->render_dir, "Render every frame offscreen to DIR/frame_00000.png ... (+ DIR/frames.mp4 with ffmpeg)");
  cmd->add_option("--egl-platform", opts->platform, "auto (default; or INCISE_EGL_PLATFORM), device or surfaceless")
      ->check(CLI::IsMember({"auto", "device", "surfaceless"}));
  add_set_option(*cmd, opts->patches);
  cmd->callback([opts] { run(*opts); });
}

}  // namespace incise
