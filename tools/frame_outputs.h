#pragma once
// What `incise run` and `incise replay` write as frames go: the ParaView
// series (`--out`, when the scene's output.vtu is on) and PNG frames with an
// MP4 at the end (`--render`, render/render_stage.h).
#include <memory>
#include <string>
#include <vector>

#include "engine/mesh/mesh_io.h"
#include "engine/runtime/simulation.h"
#include "render/render_stage.h"

namespace incise {

// Nothing half-done is left: a frame whose fields are not finite (NaN, inf)
// is not written (Error naming the field and where), and the files of a run
// that does not reach finish() (an exception unwinds past it) are removed,
// so no .pvd lists frames of a run that failed.
class FrameOutputs {
 public:
  // Writes frame 0 and plugs in the render stage when render_dir is given.
  // `stem` names the .pvd (the scene file's stem).
  FrameOutputs(Simulation& sim, const std::string& stem, const std::string& out, const std::string& render_dir,
               const std::string& platform);
  ~FrameOutputs();  // removes this run's files unless finish() was reached
  FrameOutputs(const FrameOutputs&) = delete;
  FrameOutputs& operator=(const FrameOutputs&) = delete;
  void after_frame(const Simulation& sim);  // after each advance_frame
  // The last frame into the series when output.every skipped it (a run of
  // 10 frames at every 3 ended at frame 9), the PNG count and the video
  // (when ffmpeg is there), printed; the files are kept.
  void finish(const Simulation& sim, int frames, double fps);
  bool writes_series() const { return static_cast<bool>(series_); }

 private:
  void add_to_series(const Simulation& sim);
  void commit_series();
  void remove_files();
  void write_frame_png(const Image& image, int frame);
  std::string pvd_path_;
  std::string out_dir_, stem_, stage_dir_;  // the series' folder, its name, the staging folder while it runs
  std::vector<std::string> pngs_;  // written by this run
  bool finished_ = false;

  std::unique_ptr<PvdSeries> series_;
  std::unique_ptr<Renderer> renderer_;
  Image image_;
  std::string render_dir_;
};

// Throws Error "WHERE: the output field stress at cell 12 is not finite; it
// is not written" unless every position and field value of g is finite.
void check_output_finite(const VtuGrid& g, const std::string& where);

std::string frame_png(const std::string& dir, int frame);  // DIR/frame_00012.png

}  // namespace incise
