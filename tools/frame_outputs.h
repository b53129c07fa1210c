#pragma once
// What `incise run` and `incise replay` write as frames go: the ParaView
// series (`--out`, when the scene's output.vtu is on) and PNG frames with an
// MP4 at the end (`--render`, render/render_stage.h).
#include <memory>
#include <string>

#include "engine/mesh/mesh_io.h"
#include "engine/runtime/simulation.h"
#include "render/render_stage.h"

namespace incise {

class FrameOutputs {
 public:
  // Writes frame 0 and plugs in the render stage when render_dir is given.
  // `stem` names the .pvd (the scene file's stem).
  FrameOutputs(Simulation& sim, const std::string& stem, const std::string& out, const std::string& render_dir,
               const std::string& platform);
  void after_frame(const Simulation& sim);  // after each advance_frame
  // The PNG count and the video (when ffmpeg is there), printed.
  void finish(int frames, double fps);
  bool writes_series() const { return static_cast<bool>(series_); }

 private:
  std::unique_ptr<PvdSeries> series_;
  std::unique_ptr<Renderer> renderer_;
  Image image_;
  std::string render_dir_;
};

std::string frame_png(const std::string& dir, int frame);  // DIR/frame_00012.png

}  // namespace incise
