#pragma once
// A keyframe trajectory of an instrument, read from CSV:
//
//   # comment lines and blank lines are skipped
//   t,x,y,z,qw,qx,qy,qz[,jaw]
//   0, 0.0, 0.5, 0.6, 1, 0, 0, 0
//   1, 0.1, 0.5, 0.4, 0.7071067811865476, 0, 0, 0.7071067811865476
//
// t in seconds, strictly increasing; (x, y, z) the tool frame's origin and
// (qw, qx, qy, qz) its orientation, a unit quaternion (tool -> world); jaw in
// [0, 1] (grasper: 0 open .. 1 closed). Sampled between keyframes: position
// and jaw linear, orientation by slerp; clamped outside [t0, tn].
#include <string>
#include <vector>

#include "engine/runtime/tool_pose.h"

namespace incise {

class Trajectory {
 public:
  // Reads and checks a trajectory file. Throws incise::Error "PATH:LINE: what"
  // (a missing or unreadable file: "PATH: what").
  static Trajectory read(const std::string& path);
  // The same from text already read (`path` for messages).
  static Trajectory parse(const std::string& text, const std::string& path);

  // The pose at time t. Allocates nothing (the 1 kHz haptic thread calls it).
  ToolPose sample(double t) const;
  double start_time() const { return t_.front(); }
  double end_time() const { return t_.back(); }
  bool has_jaw() const { return !jaw_.empty(); }
  int keyframes() const { return static_cast<int>(t_.size()); }

 private:
  std::vector<double> t_;    // (nkey) strictly increasing
  std::vector<double> p_;    // (nkey, 3)
  std::vector<double> q_;    // (nkey, 4) unit, (w, x, y, z)
  std::vector<double> jaw_;  // (nkey), empty without the jaw column
};

// Slerp from a to b (unit quaternions) at u in [0, 1] along the shorter arc
// (Eigen's Quaternion::slerp; linear weights where they are nearly parallel).
std::array<double, 4> slerp(const std::array<double, 4>& a, const std::array<double, 4>& b, double u);

}  // namespace incise
