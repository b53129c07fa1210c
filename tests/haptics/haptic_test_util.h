#pragma once
// The tissue block of the instrument tests (tests/collision/
// collision_test_util.h) with a probe driven by a haptic device through a
// HapticLoop. `step_until` drives both loops on one thread, ticks at the
// loop's rate and a frame whenever the simulation's time falls behind the
// tick's: the same interleaving as the threads, but repeatable.
#include <memory>
#include <string>
#include <vector>

#include "collision/collision_stage.h"
#include "engine/runtime/trajectory.h"
#include "haptics/haptic_stage.h"
#include "haptics/scripted_device.h"
#include "tests/collision/collision_test_util.h"

namespace incise::test {

inline constexpr double kBlockTop = 0.05, kProbeRadius = 0.015;

struct HapticBlock {
  std::unique_ptr<Simulation> sim;
  std::shared_ptr<HapticLoop> loop;
  std::vector<TickRecord> records;
  std::vector<HapticEvent> events;
  double t = 0.0;  // loop time of the last tick

  // Ticks (and frames) until loop time `until`.
  void step_until(double until) {
    const double period = 1.0 / loop->settings().rate_hz;
    while (t + 0.5 * period < until) {
      t += period;
      loop->tick(t, t);
      if (sim->state.time + 0.5 * period < t) advance_frame(*sim);
      loop->drain(records, events);
    }
  }
  // The simulation's contact force on the probe: -sum lambda_i d_i over its rows.
  std::array<double, 3> sim_force() const {
    const ContactRows& c = sim->ws.contacts;
    std::array<double, 3> f{0, 0, 0};
    for (int i = 0; i < c.nrow(); ++i)
      if (c.tool[i] == 0)
        for (int d = 0; d < 3; ++d) f[d] -= c.lambda[i] * c.dir[3 * i + d];
    return f;
  }
};

// A trajectory text "t,x,y,z,qw,qx,qy,qz" through the keyframes (t, x, y, z).
inline std::string probe_path(const std::vector<std::array<double, 4>>& keys) {
  std::string s = "t,x,y,z,qw,qx,qy,qz\n";
  for (const auto& k : keys)
    s += std::to_string(k[0]) + "," + std::to_string(k[1]) + "," + std::to_string(k[2]) + "," + std::to_string(k[3]) +
         ",1,0,0,0\n";
  return s;
}

// The block (E = 30 kPa, heavily damped) and a 1.5 cm probe starting at
// `start`, driven by `device`; the haptics settings from `haptics` (device
// and instrument are set here).
inline HapticBlock make_haptic_block(std::unique_ptr<HapticDevice> device, const std::array<double, 3>& start,
                                     HapticsSpec haptics = {}) {
  HapticBlock b;
  Scene scene = tissue_block_scene(3e4, 8.0);
  InstrumentSpec probe;
  probe.kind = InstrumentSpec::Kind::Probe;
  probe.radius = kProbeRadius;
  probe.name = "probe";
  probe.json_path = "instruments[0]";
  probe.position = start;
  scene.instruments.push_back(probe);
  haptics.device = HapticsSpec::Device::Scripted;
  haptics.instrument = 0;
  scene.haptics = haptics;
  b.sim = make_sim(tissue_block_mesh(), scene);
  b.sim->tools.assign(1, ToolFrame{});
  b.sim->tools[0].before.p = b.sim->tools[0].after.p = start;
  b.sim->pipeline.set(kStageToolPoses, [](Simulation&) {});  // the haptic stage sets the pose
  install_collision_stage(*b.sim);
  b.loop = install_haptics(*b.sim, std::move(device));
  return b;
}

inline std::unique_ptr<HapticDevice> scripted(const std::vector<std::array<double, 4>>& keys, double max_force = 3.3) {
  return std::make_unique<ScriptedDevice>(Trajectory::parse(probe_path(keys), "probe.csv"), "probe.csv", max_force);
}

inline double norm(const std::array<double, 3>& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

}  // namespace incise::test
