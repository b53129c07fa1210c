#pragma once
// A device that plays back a recorded device stream: the readings a real
// device gave, as `incise run --haptics` writes them (haptics_device.csv):
//
//   # comment lines and blank lines are skipped
//   t,x,y,z,qw,qx,qy,qz,jaw,buttons
//   0.001,0.02,0.01,0.05,1,0,0,0,0,0
//
// t in seconds of device time, finite and strictly increasing; the pose in
// the device's coordinates, as read (nan and inf included: the recorded
// input, bad readings and all, goes through the loop's input checks again);
// buttons an integer bitmask in [0, 2^31). At time t the device reads the
// last sample with t_i <= t, fresh when it is a new one; before the first,
// nothing.
#include <string>
#include <vector>

#include "haptics/device.h"

namespace incise {

class ReplayDevice : public HapticDevice {
 public:
  // Reads and checks a stream. Throws incise::Error "PATH:LINE: what" (a
  // missing or unreadable file: "PATH: what").
  static ReplayDevice read_file(const std::string& path, double max_force);
  // The same from text already read (`path` for messages).
  static ReplayDevice parse(const std::string& text, const std::string& path, double max_force);

  std::string describe() const override;
  double max_force() const override { return max_force_; }
  void start() override { next_ = 0; }
  bool read(double t, DeviceSample& out) override;
  void write_force(double, const std::array<double, 3>&) override {}
  int samples() const { return static_cast<int>(t_.size()); }
  double end_time() const { return t_.empty() ? 0.0 : t_.back(); }

 private:
  std::string path_;
  double max_force_ = 0.0;
  std::vector<double> t_;        // (nsample) strictly increasing
  std::vector<DeviceSample> s_;  // (nsample)
  size_t next_ = 0;              // first sample not yet read
};

}  // namespace incise
