#pragma once
// The render stage of a frame, plugged into the pipeline when asked (`run
// --render`, `bench --render`, `render`): the display mesh of the current
// state drawn offscreen; the pipeline times it as the frame's "render" stage.
#include <memory>
#include <string>

#include "engine/runtime/simulation.h"
#include "render/renderer.h"

namespace incise {

// A renderer for the scene's render settings; prints the EGL platform chosen.
std::unique_ptr<Renderer> make_renderer(const RenderSettings& settings, const std::string& platform);

// Draws the simulation's current state.
Image render_frame(Renderer& renderer, const Simulation& sim);

// Fills the pipeline's render slot: each frame drawn by `renderer` into
// `*image` (both must outlive the simulation's frames).
void install_render_stage(Simulation& sim, Renderer& renderer, Image* image);

}  // namespace incise
