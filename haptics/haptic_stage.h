#pragma once
// The haptic device plugged into a simulation (engine/runtime/pipeline.h):
// the device the scene's "haptics" key names (engine/scene/scene.h,
// HapticsSpec) drives its instrument through a HapticLoop
// (haptics/haptic_loop.h). Installed, the frame
//   - takes the instrument's pose from the device (tool poses: the pose at
//     the frame's end is the device's, as checked, when the frame starts;
//     at its start, the previous frame's end),
//   - holds the instrument through the coupling spring (its contact rows
//     yield by 1/k times their force: ContactRows::compliance), and
//   - publishes the local contact model once per frame (contact publish,
//     haptics/contact_model.h).
// A scene without "haptics" installs nothing and starts no thread.
#include <memory>

#include "engine/runtime/simulation.h"
#include "haptics/device.h"
#include "haptics/haptic_loop.h"

namespace incise {

// The device the scene declares (nullptr without one). Throws incise::Error
// naming the scene and key (a bad trajectory or stream, a build without
// OpenIGTLink).
std::unique_ptr<HapticDevice> make_haptic_device(const Scene& scene);

// The loop's settings from the scene: coupling, limits, guard (workspace
// centre: the mesh's bounding-box centre unless given), blend over one frame.
HapticSettings haptic_settings(const Simulation& sim);

// Builds the device and the loop and plugs them into the pipeline; the
// caller starts the loop (HapticLoop::start) when its frames start. Needs the
// instrument stage installed (load_checked_simulation does). Returns nullptr
// (and changes nothing) when the scene has no haptic device. `device`
// replaces the scene's (tests, an embedding application's own SDK).
std::shared_ptr<HapticLoop> install_haptics(Simulation& sim, std::unique_ptr<HapticDevice> device = nullptr);

}  // namespace incise
