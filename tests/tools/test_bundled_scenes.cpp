// The bundled scenes as a user runs them (load_checked_simulation: the
// scene's cuts checked at load, then the pipeline's stages), over the frames
// where they are hard.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "tools/frame_loop.h"

namespace incise {
namespace {

// assets/scenes/beam_cut.json: the beam cut through at t = 1 s, the cut-off
// end tumbling (Newton at its cap from frame 33 on). Under the any-point
// rotation test (integrator.rotation_fraction 0, rotation_rms 0: every
// version before the twenty-sixth session) a cut piece at mesh node 400 ran
// away at frame 75 (`incise run assets/scenes/beam_cut.json --frames 90`:
// 1e5 m/s, stopped by check_motion_bounded); with the test over the body
// it runs on (the largest speed after 80 frames 8.1 m/s, the falling end:
// free fall from t = 1 s to 2.67 s is 16.4 m/s, less with Rayleigh's mass
// damping, plus the tumble's turn rate times its 0.1 m).
TEST(BundledScenes, BeamCutRunsPastTheTumble) {
  std::vector<ScenePatch> patches;
  if (const char* any = std::getenv("INCISE_TEST_ANY_POINT"); any && *any == '1')  // the old rule, to see it fail
    patches = {parse_scene_patch("integrator.rotation_fraction=0"), parse_scene_patch("integrator.rotation_rms=0")};
  auto sim = load_checked_simulation(std::string(INCISE_SOURCE_DIR) + "/assets/scenes/beam_cut.json", patches);
  for (int k = 0; k < 80; ++k) ASSERT_NO_THROW(advance_frame(*sim)) << "frame " << k;
  double vmax = 0.0;
  for (double v : sim->state.v) vmax = std::max(vmax, std::abs(v));
  std::printf("[ beam_cut after 80 frames: largest speed %.3g m/s ]\n", vmax);
  EXPECT_LT(vmax, 20.0) << "no faster than the free fall (16.4 m/s) and the tumble";
}

// assets/scenes/beam_scalpel_stroke.json: a scalpel down into the beam to
// z = 0.02, resting until frame 24, then rising (cut_front "enriched",
// docs/cutting.md): its stroke's front is on faces while the blade is in
// and enriched once it is out (frame 27 here: the beam sags about a
// centimetre under it), with no inverted point.
TEST(BundledScenes, BeamScalpelStrokeIsEnrichedOnceTheBladeIsOut) {
  auto sim = load_checked_simulation(std::string(INCISE_SOURCE_DIR) + "/assets/scenes/beam_scalpel_stroke.json");
  int inverted = 0, enriched_from = -1;
  for (int k = 0; k < 45; ++k) {
    FrameTiming t;
    ASSERT_NO_THROW(t = advance_frame(*sim)) << "frame " << k;
    inverted = std::max(inverted, t.inverted_points);
    const bool branch = sim->model.has_cuts() && sim->model.cuts.has_branch();
    if (branch && enriched_from < 0) enriched_from = k;
    if (enriched_from >= 0) {
      EXPECT_TRUE(branch) << "frame " << k;
    }
  }
  std::printf("[ beam_scalpel_stroke: enriched from frame %d, most inverted points %d ]\n", enriched_from, inverted);
  EXPECT_GT(enriched_from, 24) << "not while the blade is in the tissue";
  EXPECT_LE(enriched_from, 33) << "once the blade is above the beam's top";
  EXPECT_EQ(inverted, 0);
}

}  // namespace
}  // namespace incise
