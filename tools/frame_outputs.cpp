#include "tools/frame_outputs.h"

#include <cstdio>
#include <filesystem>

#include "engine/output/result_grid.h"
#include "render/video.h"

namespace incise {

std::string frame_png(const std::string& dir, int frame) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%05d.png", frame);
  return (std::filesystem::path(dir) / name).string();
}

FrameOutputs::FrameOutputs(Simulation& sim, const std::string& stem, const std::string& out,
                           const std::string& render_dir, const std::string& platform)
    : render_dir_(render_dir) {
  if (!out.empty() && sim.scene.output.write_vtu) {
    std::filesystem::create_directories(out);
    series_ = std::make_unique<PvdSeries>((std::filesystem::path(out) / (stem + ".pvd")).string(),
                                          sim.scene.output.vtu_ascii ? VtuEncoding::Ascii : VtuEncoding::Binary);
    series_->add(sim.state.time, result_grid(sim.model, sim.state));
  }
  if (!render_dir.empty()) {
    std::filesystem::create_directories(render_dir);
    renderer_ = make_renderer(sim.scene.render, platform);
    write_png(render_frame(*renderer_, sim), frame_png(render_dir, sim.state.frame));
    install_render_stage(sim, *renderer_, &image_);
  }
}

void FrameOutputs::after_frame(const Simulation& sim) {
  if (renderer_) write_png(image_, frame_png(render_dir_, sim.state.frame));
  if (series_ && sim.state.frame % sim.scene.output.every == 0)
    series_->add(sim.state.time, result_grid(sim.model, sim.state));
}

void FrameOutputs::finish(int frames, double fps) {
  if (!renderer_) return;
  std::printf("wrote %d frames %s\n", frames + 1, frame_png(render_dir_, 0).c_str());
  const std::string video = encode_mp4(render_dir_, fps);
  std::printf("%s\n", video.empty() ? "no ffmpeg on PATH: no video (PNG frames only)" : ("wrote " + video).c_str());
}

}  // namespace incise
