// Render-only timing of the ~20k-DOF tet10 beam (uncut and with the hand-made
// cut), for docs/benchmarks.md. Disabled in the suite; run with
//   build/tests/render_tests --gtest_also_run_disabled_tests --gtest_filter='*RenderTiming*'
#include <gtest/gtest.h>

#include "engine/runtime/timing.h"
#include "engine/runtime/timing_stats.h"
#include "render_test_util.h"

namespace incise::test {
namespace {

TEST(RenderTiming, DISABLED_Beam20kDof) {
  const DisplayMesh uncut = display_of(make_beam(0.2, 0.05, 0.05, 28, 5, 5, 2));
  const DisplayMesh cut = split_block(uncut, 0.1, 0.005);
  std::printf("| mesh | resolution | faces drawn (boundary + cut) | triangles | update ms | render+readback ms | total ms |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  for (auto [w, h] : {std::pair{640, 480}, std::pair{1280, 720}})
    for (const DisplayMesh* base : {&uncut, &cut}) {
      RenderSettings s;
      s.width = w, s.height = h;
      auto r = make_test_renderer(s);
      ASSERT_TRUE(r);
      DisplayMesh d = *base;
      std::vector<double> t_update, t_render, t_total;
      for (int k = 0; k < 22; ++k) {
        for (size_t i = 2; i < d.u.size(); i += 3) d.u[i] = -0.01 * k * d.X[i - 2];  // bend a little more each frame
        Stopwatch clock;
        r->update(d);
        const double a = clock.lap();
        r->render();
        const double b = clock.lap();
        if (k >= 2) t_update.push_back(a), t_render.push_back(b), t_total.push_back(a + b);
      }
      std::printf("| %s | %dx%d | %d + %d | %d | %.2f | %.2f | %.2f |\n", base == &uncut ? "uncut" : "hand-made cut", w,
                  h, r->stats().nboundary, r->stats().ncut, r->stats().ntriangle, percentiles(t_update).median_ms,
                  percentiles(t_render).median_ms, percentiles(t_total).median_ms);
    }
}

}  // namespace
}  // namespace incise::test
