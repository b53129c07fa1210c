#pragma once
// A haptic device as the 1 kHz loop (haptics/haptic_loop.h) sees it: read the
// tool's pose and buttons, write a force, state the largest force it can
// render. Three ship with incise: scripted (a keyframe trajectory,
// haptics/scripted_device.h), replay (a recorded device stream,
// haptics/replay_device.h) and OpenIGTLink (a tracker or navigation system
// over TCP, haptics/igtl_device.h). docs/haptics.md says how to add a real
// device's SDK.
//
// read() and write_force() run on the haptic thread once per tick: they must
// not allocate, block or take a lock another thread holds for long. A device
// that talks to hardware or a network does that on its own thread and hands
// the latest values over (haptics/triple_buffer.h).
#include <array>
#include <string>

#include "engine/runtime/tool_pose.h"

namespace incise {

struct DeviceSample {
  ToolPose pose;             // in the device's coordinates (the loop maps them: haptics.scale, offset)
  unsigned buttons = 0;      // bit i: button i pressed
  bool fresh = false;        // a reading arrived since the previous read()
};

class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  // One line for the log: "scripted (assets/trajectories/organ_probe.csv)".
  virtual std::string describe() const = 0;
  // The largest force the device renders (N, > 0); the loop clamps to it.
  virtual double max_force() const = 0;
  // Before the first tick (open the device, start its own thread); may
  // throw incise::Error. stop() after the last tick; idempotent.
  virtual void start() {}
  virtual void stop() {}
  // The reading at device time t (s since the loop started). false: the
  // device has no reading yet (nothing connected); `out` is then untouched.
  virtual bool read(double t, DeviceSample& out) = 0;
  // The force on the hand (N, world axes), already clamped to max_force().
  virtual void write_force(double t, const std::array<double, 3>& force) = 0;
};

}  // namespace incise
