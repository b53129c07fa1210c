// incise_render_bench: Google Benchmark of the render stage alone (no
// stepping) on the ~20k-DOF tet10 beam of bench-beams.sh (28x5x5 cells),
// uncut and with the hand-made cut of the render tests (split_block: the
// right half moved 5 mm away, its cut faces drawn in the interior colour),
// at 640x480 and 1280x720. One iteration = one frame: the display mesh bent
// a little more (update: tessellation and upload), then render() (draw into
// the FBO and glReadPixels). Counters: update_ms and render_ms per frame,
// faces drawn (boundary, cut) and triangles. Needs EGL (Mesa surfaceless on
// the CPU, or a GPU); not part of ctest (docs/benchmarks.md, "Render").
// Run: build/tools/incise_render_bench [--benchmark_filter=...]
#include <memory>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "engine/runtime/timing.h"
#include "engine/util/error.h"
#include "render/renderer.h"
#include "tests/engine/output/display_fixtures.h"

namespace {

using namespace incise;

const DisplayMesh& beam20k(bool cut) {
  static const DisplayMesh uncut = test::display_of(make_beam(0.2, 0.05, 0.05, 28, 5, 5, 2));
  static const DisplayMesh with_cut = test::split_block(uncut, 0.1, 0.005);
  return cut ? with_cut : uncut;
}

void BM_Render(benchmark::State& state, int width, int height, bool cut) {
  RenderSettings s;
  s.width = width;
  s.height = height;
  std::unique_ptr<Renderer> r;
  try {
    r = std::make_unique<Renderer>(s);
  } catch (const Error& e) {
    state.SkipWithError((std::string("EGL could not initialise: ") + e.what()).c_str());
    return;
  }
  DisplayMesh d = beam20k(cut);
  int frame = 0;
  auto bend = [&] {  // bend a little more each frame (22 frames, then again)
    const double k = frame++ % 22;
    for (size_t i = 2; i < d.u.size(); i += 3) d.u[i] = -0.01 * k * d.X[i - 2];
  };
  for (int k = 0; k < 2; ++k) {  // warm-up: first upload, shader and buffer set-up
    bend();
    r->update(d);
    r->render();
  }
  double update_ms = 0, render_ms = 0;
  for (auto _ : state) {
    bend();
    Stopwatch clock;
    r->update(d);
    update_ms += clock.lap();
    r->render();
    render_ms += clock.lap();
  }
  const double frames = static_cast<double>(state.iterations());
  state.counters["update_ms"] = update_ms / frames;
  state.counters["render_ms"] = render_ms / frames;
  state.counters["faces_boundary"] = r->stats().nboundary;
  state.counters["faces_cut"] = r->stats().ncut;
  state.counters["triangles"] = r->stats().ntriangle;
}

}  // namespace

BENCHMARK_CAPTURE(BM_Render, beam20k_uncut_640x480, 640, 480, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Render, beam20k_cut_640x480, 640, 480, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Render, beam20k_uncut_1280x720, 1280, 720, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Render, beam20k_cut_1280x720, 1280, 720, true)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
