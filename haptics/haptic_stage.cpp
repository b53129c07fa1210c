#include "haptics/haptic_stage.h"

#include <algorithm>
#include <utility>

#include "engine/runtime/trajectory.h"
#include "engine/util/error.h"
#include "haptics/replay_device.h"
#include "haptics/scripted_device.h"
#ifdef INCISE_WITH_OPENIGTLINK
#include "haptics/igtl_device.h"
#endif

namespace incise {

std::unique_ptr<HapticDevice> make_haptic_device(const Scene& scene) {
  const HapticsSpec& h = scene.haptics;
  const std::string at = scene.path + ": haptics.";
  switch (h.device) {
    case HapticsSpec::Device::None:
      return nullptr;
    case HapticsSpec::Device::Scripted: {
      const InstrumentSpec& tool = scene.instruments.at(static_cast<size_t>(h.instrument));
      try {
        return std::make_unique<ScriptedDevice>(Trajectory::read(h.trajectory), h.trajectory, h.max_force, tool.jaw);
      } catch (const Error& e) {
        throw Error(at + "trajectory: " + e.what());
      }
    }
    case HapticsSpec::Device::Replay:
      try {
        return std::make_unique<ReplayDevice>(ReplayDevice::read_file(h.stream, h.max_force));
      } catch (const Error& e) {
        throw Error(at + "stream: " + e.what());  // the force limit is the parser's, > 0: only the file can fail
      }
    case HapticsSpec::Device::OpenIGTLink:
#ifdef INCISE_WITH_OPENIGTLINK
      return std::make_unique<IgtlDevice>(h.port, h.max_force);  // start() names the port when it cannot listen
#else
      throw Error(at + "device: \"openigtlink\" needs a build with OpenIGTLink (apt-get install libopenigtlink-dev, "
                       "then configure again)");
#endif
  }
  return nullptr;
}

HapticSettings haptic_settings(const Simulation& sim) {
  const HapticsSpec& h = sim.scene.haptics;
  HapticSettings s;
  s.instrument = h.instrument;
  s.rate_hz = h.rate_hz;
  s.frame_dt = sim.model.dt;
  s.stiffness = h.stiffness;
  s.damping = h.damping;
  s.max_force = h.max_force;
  s.scale = h.scale;
  s.offset = h.offset;
  s.realtime = h.realtime;
  s.guard.radius = h.workspace_radius;
  s.guard.max_speed = h.max_speed;
  s.guard.reacquire = h.reacquire;
  s.guard.max_turn = h.max_turn;
  s.guard.glide_speed = h.glide_speed;
  if (h.center) {
    s.guard.center = *h.center;
  } else if (sim.mesh.nnode() > 0) {
    std::array<double, 3> lo, hi;
    for (int d = 0; d < 3; ++d) lo[d] = hi[d] = sim.mesh.X[d];
    for (int n = 1; n < sim.mesh.nnode(); ++n)
      for (int d = 0; d < 3; ++d) {
        lo[d] = std::min(lo[d], sim.mesh.X[3 * n + d]);
        hi[d] = std::max(hi[d], sim.mesh.X[3 * n + d]);
      }
    for (int d = 0; d < 3; ++d) s.guard.center[d] = 0.5 * (lo[d] + hi[d]);
  }
  return s;
}

std::shared_ptr<HapticLoop> install_haptics(Simulation& sim, std::unique_ptr<HapticDevice> device) {
  if (sim.scene.haptics.device == HapticsSpec::Device::None && !device) return nullptr;
  const int h = sim.scene.haptics.instrument;
  if (!sim.pipeline.has(kStageToolPoses) || sim.tools.size() != sim.scene.instruments.size())
    throw Error(sim.scene.path + ": haptics: the instrument stage is not installed (install_instrument_stage first)");
  if (h < 0 || static_cast<size_t>(h) >= sim.tools.size())
    throw Error(sim.scene.path + ": haptics.instrument: index " + std::to_string(h) + " is not one of the scene's " +
                std::to_string(sim.tools.size()) + " instruments");
  if (!device) device = make_haptic_device(sim.scene);
  auto loop = std::make_shared<HapticLoop>(std::move(device), haptic_settings(sim), sim.tools[static_cast<size_t>(h)].after);
  const StageFn inner = sim.pipeline.get(kStageToolPoses);
  auto last = std::make_shared<ToolPose>(sim.tools[static_cast<size_t>(h)].after);
  sim.pipeline.set(kStageToolPoses, [inner, loop, h, last](Simulation& s) {
    inner(s);
    ToolFrame& f = s.tools[static_cast<size_t>(h)];
    f.before = *last;
    f.after = loop->device_pose();
    *last = f.after;
  });
  const double k = loop->settings().stiffness;
  // The simulation holds the instrument through the same spring (contact_rows.h, compliance).
  sim.ws.contacts.compliance.assign(sim.tools.size(), 0.0);
  sim.ws.contacts.compliance[static_cast<size_t>(h)] = 1.0 / k;
  sim.pipeline.set(kStageContactPublish, [loop, h, k](Simulation& s) {
    fill_contact_model(s, h, k, loop->model_buffer());
    loop->publish_model();
  });
  sim.module_data[kStageContactPublish] = loop;
  return loop;
}

}  // namespace incise
