#include "tools/frame_outputs.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include <unistd.h>

#include "engine/output/result_grid.h"
#include "engine/util/error.h"
#include "render/video.h"

namespace incise {

std::string frame_png(const std::string& dir, int frame) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%05d.png", frame);
  return (std::filesystem::path(dir) / name).string();
}

void check_output_finite(const VtuGrid& g, const std::string& where) {
  const auto fail = [&](const std::string& what) {
    throw Error(where + ": the output " + what + " is not finite; it is not written");
  };
  for (size_t i = 0; i < g.points.size(); ++i)
    if (!std::isfinite(g.points[i])) fail("position of point " + std::to_string(i / 3));
  for (const auto* fields : {&g.point_data, &g.cell_data})
    for (const VtuField& f : *fields)
      for (size_t i = 0; i < f.values.size(); ++i)
        if (!std::isfinite(f.values[i]))
          fail("field " + f.name + " at " + (fields == &g.point_data ? "point " : "cell ") +
               std::to_string(i / static_cast<size_t>(std::max(1, f.ncomp))));
}

FrameOutputs::FrameOutputs(Simulation& sim, const std::string& stem, const std::string& out,
                           const std::string& render_dir, const std::string& platform)
    : render_dir_(render_dir) {
  try {
    if (!out.empty() && sim.scene.output.write_vtu) {
      // The series is written into a staging folder inside `out` and moved
      // in by finish(): a run that fails leaves an earlier run's series of
      // the same name whole (it deleted that run's first files), and one
      // that succeeds replaces it whole (no stale .vtu of a longer run).
      std::filesystem::create_directories(out);  // (an error names `out` itself)
      out_dir_ = out;
      stem_ = stem;
      stage_dir_ = (std::filesystem::path(out) / (".incise-partial-" + stem + "-" + std::to_string(getpid()))).string();
      std::filesystem::create_directories(stage_dir_);
      pvd_path_ = (std::filesystem::path(stage_dir_) / (stem + ".pvd")).string();
      series_ = std::make_unique<PvdSeries>(pvd_path_, sim.scene.output.vtu_ascii ? VtuEncoding::Ascii : VtuEncoding::Binary);
      add_to_series(sim);
    }
    if (!render_dir.empty()) {
      std::filesystem::create_directories(render_dir);
      renderer_ = make_renderer(sim.scene.render, platform);
      write_frame_png(render_frame(*renderer_, sim), sim.state.frame);
      install_render_stage(sim, *renderer_, &image_);
    }
  } catch (...) {  // no destructor runs for a constructor that throws
    remove_files();
    throw;
  }
}

FrameOutputs::~FrameOutputs() {
  if (!finished_) remove_files();
}

void FrameOutputs::remove_files() {
  std::vector<std::string> files = pngs_;
  if (series_) {
    files.push_back(pvd_path_);
    for (const std::string& f : series_->files())
      files.push_back((std::filesystem::path(pvd_path_).parent_path() / f).string());
  }
  int removed = 0;
  for (const std::string& f : files) {
    std::error_code ec;
    removed += std::filesystem::remove(f, ec) ? 1 : 0;
  }
  if (!stage_dir_.empty()) {
    std::error_code ec;
    std::filesystem::remove_all(stage_dir_, ec);
  }
  // (the series by the name it would have had, not its staging folder's)
  const std::string series = series_ ? (std::filesystem::path(out_dir_) / (stem_ + ".pvd")).string() : "";
  if (removed > 0)
    std::fprintf(stderr, "incise: removed the %d output file(s) of the failed run (%s%s)\n", removed, series.c_str(),
                 series_ && !pngs_.empty() ? ", PNG frames" : !pngs_.empty() ? "PNG frames" : "");
}

// The staged series replaces the folder's series of the same stem: its
// .pvd and every STEM_NNNNNN.vtu (also those of a longer earlier run).
void FrameOutputs::commit_series() {
  namespace fs = std::filesystem;
  // STEM_NNNNNN.vtu: the stem, '_', six digits, ".vtu".
  const auto numbered = [&](const std::string& name) {
    const size_t n = stem_.size();
    if (name.size() != n + 11 || name.compare(0, n, stem_) != 0 || name[n] != '_' || name.compare(n + 7, 4, ".vtu") != 0)
      return false;
    for (size_t i = n + 1; i < n + 7; ++i)
      if (name[i] < '0' || name[i] > '9') return false;
    return true;
  };
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(out_dir_, ec)) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file() && (name == stem_ + ".pvd" || numbered(name))) fs::remove(e.path(), ec);
  }
  std::vector<std::string> names = series_->files();
  names.push_back(stem_ + ".pvd");
  for (const std::string& f : names) {
    fs::rename(fs::path(stage_dir_) / f, fs::path(out_dir_) / f, ec);
    if (ec) throw Error(out_dir_ + ": cannot move " + f + " out of " + stage_dir_ + ": " + ec.message());
  }
  fs::remove_all(stage_dir_, ec);
  stage_dir_.clear();
  pvd_path_ = (fs::path(out_dir_) / (stem_ + ".pvd")).string();
}

void FrameOutputs::add_to_series(const Simulation& sim) {
  const VtuGrid grid = result_grid(sim.model, sim.state);
  check_output_finite(grid, "frame " + std::to_string(sim.state.frame) + " (t = " + std::to_string(sim.state.time) + ")");
  series_->add(sim.state.time, grid);
}

void FrameOutputs::write_frame_png(const Image& image, int frame) {
  pngs_.push_back(frame_png(render_dir_, frame));
  write_png(image, pngs_.back());
}

void FrameOutputs::after_frame(const Simulation& sim) {
  if (renderer_) write_frame_png(image_, sim.state.frame);
  if (series_ && sim.state.frame % sim.scene.output.every == 0) add_to_series(sim);
}

void FrameOutputs::finish(const Simulation& sim, int frames, double fps) {
  if (series_ && sim.state.frame % sim.scene.output.every != 0) add_to_series(sim);
  if (series_) commit_series();
  finished_ = true;
  if (!renderer_) return;
  std::printf("wrote %d frames %s\n", frames + 1, frame_png(render_dir_, 0).c_str());
  const std::string video = encode_mp4(render_dir_, fps);
  std::printf("%s\n", video.empty() ? "no ffmpeg on PATH: no video (PNG frames only)" : ("wrote " + video).c_str());
}

}  // namespace incise
