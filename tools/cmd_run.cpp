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
#include "tools/frame_loop.h"
#include "render/render_stage.h"
#include "tools/solver_report.h"
#include "tools/timing_json.h"
#include "haptics/haptic_stage.h"
#include "haptics/tick_stats.h"
#include "engine/mesh/mesh_text.h"  // write_atomic

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
};

// The haptic run's logs and figures (haptics/tick_stats.h), into `dir`.
void finish_haptics(HapticLoop& loop, std::vector<TickRecord>& records, std::vector<HapticEvent>& events,
                    const std::string& dir) {
  loop.stop();
  loop.drain(records, events);
  const TickStats st = summarize_ticks(records, loop.force_limit());
  std::printf("%s", format_tick_stats(st).c_str());
  if (loop.dropped() > 0)
    std::printf("haptics: %llu records or events dropped (the main loop drained too late)\n",
                static_cast<unsigned long long>(loop.dropped()));
  std::map<std::string, int> counts;
  for (const HapticEvent& e : events) ++counts[event_name(e.kind)];
  for (const auto& [name, n] : counts) std::printf("haptics: %d %s event%s\n", n, name.c_str(), n == 1 ? "" : "s");
  if (!dir.empty()) std::filesystem::create_directories(dir);
  const auto file = [&](const char* name) { return (std::filesystem::path(dir.empty() ? "." : dir) / name).string(); };
  write_force_log(file("haptics_force.csv"), records);
  write_device_stream(file("haptics_device.csv"), records);
  write_event_log(file("haptics_events.csv"), events);
  const nlohmann::json j = {{"device", loop.device().describe()},
                            {"scheduling", loop.scheduling()},
                            {"rate_hz", loop.settings().rate_hz},
                            {"force_limit_n", loop.force_limit()},
                            {"ticks", st.ticks},
                            {"period_ms", {{"median", st.period_median_ms}, {"p99", st.period_p99_ms}, {"max", st.period_max_ms}}},
                            {"late_us", {{"median", st.late_median_us}, {"p99", st.late_p99_us}, {"max", st.late_max_us}}},
                            {"late_over_0_5_ms", st.late_over_half_ms},
                            {"compute_us", {{"median", st.compute_median_us}, {"p99", st.compute_p99_us}, {"max", st.compute_max_us}}},
                            {"allocations", st.allocations},
                            {"force_max_n", st.force_max},
                            {"force_jump_max_n", st.jump_max},
                            {"clamped_ticks", st.clamped},
                            {"events", counts},
                            {"dropped", loop.dropped()}};
  meshio::write_atomic(file("haptics.json"), j.dump(2) + "\n");
  std::printf("wrote %s, haptics_device.csv, haptics_events.csv, haptics.json\n", file("haptics_force.csv").c_str());
}


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
  std::shared_ptr<HapticLoop> haptic;
  if (o.haptics) {
    haptic = install_haptics(*sim);
    if (!haptic) std::printf("haptics: %s declares no haptic device (\"haptics\"): no haptic thread\n", o.scene.c_str());
  }
  const double pace = o.pace_hz >= 0.0 ? o.pace_hz : haptic ? 1.0 / sim->model.dt : 0.0;
  std::vector<TickRecord> records;
  std::vector<HapticEvent> events;
  size_t events_shown = 0;
  if (haptic) {
    records.reserve(static_cast<size_t>(frames * sim->model.dt * haptic->settings().rate_hz * 1.1) + 64);
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
  Stopwatch wall, progress;
  const std::string haptics_dir = !o.haptics_dir.empty() ? o.haptics_dir : out;
  for (int k = 0; k < frames; ++k) {
    if (pace > 0.0) std::this_thread::sleep_until(next);
    FrameTiming t;
    try {
      t = advance_frame(*sim);
    } catch (...) {  // the hand's record of a run that failed is worth keeping
      if (haptic) finish_haptics(*haptic, records, events, haptics_dir);
      throw;
    }
    next = std::max(next + period, clock::now());
    if (haptic) {
      haptic->drain(records, events);
      for (; events_shown < events.size() && events_shown < 20; ++events_shown)
        std::fprintf(stderr, "haptics: %s%s\n", format_event(events[events_shown]).c_str(),
                     events_shown == 19 ? " (further events: haptics_events.csv)" : "");
    }
    if (renderer) write_png(image, frame_png(o.render_dir, s.frame));
    timings.push_back(t);
    if (series && s.frame % sim->scene.output.every == 0) series->add(s.time, result_grid(sim->model, s));
    if (progress.ms() > 1000.0 || k + 1 == frames) {
      std::fprintf(stderr, "frame %d/%d  t = %.3f s  %.2f ms/frame  %d DOF\n", k + 1, frames, s.time,
                   timings.back().frame_ms, sim->model.ndof());
      progress.lap();
    }
  }
  const double run_ms = wall.ms();
  if (haptic) finish_haptics(*haptic, records, events, haptics_dir);
  const TimingSummary summary = summarize(timings);
  std::printf("%d frames in %.1f ms (%.2fx real time); %d numeric factorizations\n", frames, run_ms,
              frames * sim->model.dt * 1000.0 / run_ms, sim->ws.refactorizations);
  std::printf("%s", format_summary(summary).c_str());
  if (renderer) {
    std::printf("wrote %d frames %s\n", frames + 1, frame_png(o.render_dir, 0).c_str());
    const std::string video = encode_mp4(o.render_dir, 1.0 / sim->model.dt);
    std::printf("%s\n", video.empty() ? "no ffmpeg on PATH: no video (PNG frames only)" : ("wrote " + video).c_str());
  }
  if (!out.empty()) {
    std::filesystem::create_directories(out);
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
  cmd->add_flag("--haptics", opts->haptics,
                "Run the scene's haptic device (\"haptics\") on a 1 kHz thread beside frames paced at 1/dt; writes "
                "haptics_force.csv (t,fx,fy,fz,tick_us,late_us), haptics_device.csv, haptics_events.csv, haptics.json");
  cmd->add_option("--haptics-dir", opts->haptics_dir, "Folder for the haptic logs (default: --out, else output.dir, else .)");
  cmd->add_option("--pace", opts->pace_hz, "Start frames at this rate in Hz (default: 1/dt with --haptics, else back to back; 0: back to back)")
      ->check(CLI::NonNegativeNumber);
  add_set_option(*cmd, opts->patches);
  cmd->callback([opts] { run(*opts); });
}

}  // namespace incise
