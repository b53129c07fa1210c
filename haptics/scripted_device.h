#pragma once
// A device that follows a keyframe trajectory (engine/runtime/trajectory.h)
// at the loop's rate: a hand that always does the same thing, for tests,
// benchmarks and demos. Each tick reads the trajectory at the device time
// (clamped to its last keyframe); it never runs out of readings.
#include <string>

#include "engine/runtime/trajectory.h"
#include "haptics/device.h"

namespace incise {

class ScriptedDevice : public HapticDevice {
 public:
  // jaw: used when the trajectory has no jaw column.
  ScriptedDevice(Trajectory trajectory, std::string path, double max_force, double jaw = 0.0);
  std::string describe() const override { return "scripted (" + path_ + ")"; }
  double max_force() const override { return max_force_; }
  bool read(double t, DeviceSample& out) override;
  void write_force(double, const std::array<double, 3>& f) override { last_force_ = f; }
  const std::array<double, 3>& last_force() const { return last_force_; }

 private:
  Trajectory trajectory_;
  std::string path_;
  double max_force_, jaw_;
  std::array<double, 3> last_force_{};
};

}  // namespace incise
