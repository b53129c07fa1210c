// Embedding incise: load a scene, attach an instrument driven from this
// program, step 100 frames, read the displacement at a point (and the
// instrument's contact force) every 10.
//
//   embed SCENE.json [X Y Z]   (X Y Z: a point 7 mm under an upper surface;
//                               default: the bundled organ's, for
//                               assets/scenes/organ_drag.json)
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "engine/output/probe.h"
#include "engine/runtime/simulation.h"
#include "engine/util/error.h"
#include "tools/frame_loop.h"

int main(int argc, char** argv) {
  if (argc != 2 && argc != 5) {
    std::fprintf(stderr, "usage: %s SCENE.json [X Y Z]\n", argv[0]);
    return 2;
  }
  try {
    incise::Scene scene = incise::load_scene(argv[1]);
    // A probe (a 5 mm sphere) that this program moves: no trajectory file.
    incise::InstrumentSpec finger;
    finger.kind = incise::InstrumentSpec::Kind::Probe;
    finger.name = "finger";
    finger.radius = 0.005;
    finger.json_path = "instruments[" + std::to_string(scene.instruments.size()) + "]";
    scene.instruments.push_back(finger);
    auto sim = incise::load_checked_simulation(scene);
    const int me = static_cast<int>(sim->scene.instruments.size()) - 1;
    const double x[3] = {argc == 5 ? std::atof(argv[2]) : 0.02, argc == 5 ? std::atof(argv[3]) : -0.01,
                         argc == 5 ? std::atof(argv[4]) : 0.03};
    // The tool-poses stage: the frame's start and end poses of every
    // instrument. Ours (radius 5 mm) comes down above the point at 2 cm/s
    // until its lowest point is 4 mm above it: 3 mm into the surface.
    auto pose_at = [x](double t) {
      incise::ToolPose p;
      p.p = {x[0], x[1], x[2] + 0.004 + 0.005 + 0.02 * (1.0 - std::min(t, 1.0))};
      return p;
    };
    sim->pipeline.set(incise::kStageToolPoses, [me, pose_at](incise::Simulation& s) {
      s.tools.resize(s.scene.instruments.size());
      s.tools[me].before = pose_at(s.state.time);
      s.tools[me].after = pose_at(s.state.time + s.model.dt);
    });
    std::printf("frame  t (s)   u at (%g, %g, %g) (m)               contact force (N)\n", x[0], x[1], x[2]);
    for (int k = 1; k <= 100; ++k) {
      const incise::FrameTiming t = incise::advance_frame(*sim);
      if (k % 10 != 0) continue;
      const incise::ProbeHit hit = incise::locate_point(sim->model, x);  // again: a cut renumbers
      if (hit.elem < 0) throw incise::Error("the point is outside the mesh");
      const auto u = incise::interpolate_displacement(sim->model, sim->state.u.data(), hit);
      std::printf("%5d  %5.2f   %+.6f %+.6f %+.6f   %.3f\n", k, sim->state.time, u[0], u[1], u[2], t.contact_force);
    }
  } catch (const incise::Error& e) {
    std::fprintf(stderr, "embed: %s\n", e.what());
    return 1;
  }
  return 0;
}
