// incise render: step K frames and render that frame to a PNG.
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <string>

#include "engine/runtime/simulation.h"
#include "engine/util/error.h"
#include "tools/commands.h"
#include "tools/option_checks.h"
#include "tools/frame_loop.h"
#include "render/render_stage.h"
#include "tools/solver_report.h"

namespace incise {

namespace {
struct RenderOptions {
  std::string scene, out, platform;
  int frame = 0, width = 0, height = 0;  // 0: the scene's render.width/height
  std::vector<ScenePatch> patches;        // --set
};

void render_command(const RenderOptions& o) {
  // PNG only: a .jpg name got PNG bytes.
  std::string ext = std::filesystem::path(o.out).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".png") throw Error("--out: the image is written as PNG: the file must end in .png, got " + o.out);
  auto sim = load_checked_simulation(o.scene, o.patches);
  RenderSettings settings = sim->scene.render;
  if (o.width > 0) settings.width = o.width;
  if (o.height > 0) settings.height = o.height;
  auto renderer = make_renderer(settings, o.platform);
  for (int k = 0; k < o.frame; ++k) advance_frame(*sim);  // cuts included
  Stopwatch clock;
  const Image img = render_frame(*renderer, *sim);
  const double render_ms = clock.ms();
  write_png(img, o.out);
  const auto& st = renderer->stats();
  std::printf("frame %d (t = %.4f s): %d boundary + %d cut faces, %d triangles, rendered in %.2f ms\nwrote %s\n",
              o.frame, sim->state.time, st.nboundary, st.ncut, st.ntriangle, render_ms,
              o.out.c_str());
}
}  // namespace

void add_render_command(CLI::App& app) {
  auto opts = std::make_shared<RenderOptions>();
  auto* cmd = app.add_subcommand("render", "Step K frames and render that frame offscreen (EGL) to a PNG");
  cmd->add_option("scene", opts->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--frame", opts->frame, "Frames to step before rendering (0: the initial state)")
      ->check(integer_in(0, kMaxOptionFrames, kFramesWhy));
  cmd->add_option("--out", opts->out, "PNG file to write")->required();
  cmd->add_option("--width", opts->width, "Width in pixels (default: render.width)")->check(CLI::Range(16, 8192));
  cmd->add_option("--height", opts->height, "Height in pixels (default: render.height)")->check(CLI::Range(16, 8192));
  add_egl_platform_option(*cmd, opts->platform);
  add_set_option(*cmd, opts->patches);
  cmd->callback([opts] { render_command(*opts); });
}

void add_egl_platform_option(CLI::App& cmd, std::string& platform) {
  cmd.add_option("--egl-platform", platform, "auto (default; or INCISE_EGL_PLATFORM), device or surfaceless")
      ->check(CLI::IsMember({"auto", "device", "surfaceless"}));
}

}  // namespace incise
