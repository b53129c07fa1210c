#pragma once
// The render stage of a frame, shared by `run --render`, `bench --render` and
// `render`: the display mesh of the current state drawn offscreen, its time
// recorded as the frame's "render" stage (and added to the frame time).
#include <cstdio>
#include <memory>
#include <string>

#include "engine/output/display_mesh.h"
#include "engine/runtime/simulation.h"
#include "render/renderer.h"

namespace incise {

// A renderer for the scene's render settings; prints the EGL platform chosen.
inline std::unique_ptr<Renderer> make_renderer(const RenderSettings& settings, const std::string& platform) {
  auto r = std::make_unique<Renderer>(settings, platform.empty() ? egl_platform_from_env()
                                                                 : parse_egl_platform(platform, "--egl-platform"));
  std::printf("render: %dx%d, EGL %s\n", settings.width, settings.height, r->context().description().c_str());
  return r;
}

// Adds its time to `timing` (the frame's record from advance_frame).
inline Image render_stage(Renderer& renderer, const Simulation& sim, FrameTiming& timing) {
  Stopwatch clock;
  renderer.update(display_mesh(sim.model, sim.state));
  Image img = renderer.render();
  const double ms = clock.ms();
  timing.ms[kStageRender] += ms;
  timing.frame_ms += ms;
  return img;
}

}  // namespace incise
