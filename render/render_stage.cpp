#include "render/render_stage.h"

#include <cstdio>

#include "engine/output/display_mesh.h"

namespace incise {

std::unique_ptr<Renderer> make_renderer(const RenderSettings& settings, const std::string& platform) {
  auto r = std::make_unique<Renderer>(settings, platform.empty() ? egl_platform_from_env()
                                                                 : parse_egl_platform(platform, "--egl-platform"));
  std::printf("render: %dx%d, EGL %s\n", settings.width, settings.height, r->context().description().c_str());
  return r;
}

Image render_frame(Renderer& renderer, const Simulation& sim) {
  renderer.update(display_mesh(sim.model, sim.state));
  renderer.set_instruments(instrument_shapes(sim.scene.instruments, sim.tools));
  return renderer.render();
}

void install_render_stage(Simulation& sim, Renderer& renderer, Image* image) {
  sim.pipeline.set(kStageRender, [&renderer, image](Simulation& s) { *image = render_frame(renderer, s); });
}

}  // namespace incise
