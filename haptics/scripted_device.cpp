#include "haptics/scripted_device.h"

#include <utility>

namespace incise {

ScriptedDevice::ScriptedDevice(Trajectory trajectory, std::string path, double max_force, double jaw)
    : trajectory_(std::move(trajectory)), path_(std::move(path)), max_force_(max_force), jaw_(jaw) {}

bool ScriptedDevice::read(double t, DeviceSample& out) {
  out.pose = trajectory_.sample(t);
  if (!trajectory_.has_jaw()) out.pose.jaw = jaw_;
  out.buttons = 0;
  out.fresh = true;
  return true;
}

}  // namespace incise
