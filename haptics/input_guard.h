#pragma once
// Device readings are checked before they move the tool: a reading that is
// not finite, not a rotation, outside the workspace or a jump no hand makes
// is rejected, the last good pose holds, and the event is reported. A device
// that really did move far (re-homed, tracker re-registered) is taken back
// after its readings agree for `reacquire` seconds, and the tool then glides
// to it at glide_speed (and max_turn) instead of teleporting into the
// tissue. Speeds are judged between fresh readings, so a 30 Hz tracker is
// held to the same max_speed as a 1 kHz device.
#include <array>

#include "engine/runtime/tool_pose.h"

namespace incise {

enum class HapticEventKind : char {
  NotFinite,     // a reading with NaN or infinity: rejected
  NotRotation,   // its quaternion is not of unit length (|1 - |q|| > 1e-3): rejected
  JawRange,      // its jaw is outside [0, 1]: rejected
  Workspace,     // farther than workspace_radius from the workspace centre: rejected
  Jump,          // moved faster than max_speed (or turned faster than max_turn) since the last reading: rejected
  Reacquired,    // after a jump, readings agreed for `reacquire` s: the tool glides to them
  ForceClamped,  // the force reached the device's limit (logged when it starts)
  ForceNotFinite,// the coupling solve gave a non-finite force: zero sent instead
  Overrun,       // a tick woke after its successor's deadline: ticks skipped
};
const char* event_name(HapticEventKind k);

struct HapticEvent {
  double t = 0.0;                  // device time (s)
  HapticEventKind kind = HapticEventKind::NotFinite;
  std::array<double, 3> value{};   // the rejected position ({|q|, 0, 0}, {jaw, 0, 0}), the unclamped force, or {late ms, skipped, 0}
};

struct GuardSettings {
  std::array<double, 3> center{};  // workspace centre (scene units)
  double radius = 1.0;             // workspace radius
  double max_speed = 2.0;          // per second
  double max_turn = 20.0;          // rad/s
  double reacquire = 0.2;          // s
  double glide_speed = 0.05;       // per second, toward a reacquired reading
};

class InputGuard {
 public:
  InputGuard() = default;
  InputGuard(const GuardSettings& s, const ToolPose& start) : s_(s), good_(start) {}
  // One tick at time t with the device's reading (fresh: a new one; else
  // only a glide advances). Returns the pose to use; `*event` is filled and
  // `*has_event` set when the reading was rejected or reacquired.
  // Allocates nothing.
  const ToolPose& filter(double t, const ToolPose& reading, bool fresh, HapticEvent* event, bool* has_event);
  const ToolPose& pose() const { return good_; }

 private:
  GuardSettings s_;
  ToolPose good_;              // last accepted pose (what the tool follows)
  double t_last_ = 0.0;        // previous tick (the loop's clock starts at 0)
  double t_fresh_ = 0.0;       // previous fresh reading that passed the checks
  bool jumped_ = false;        // rejecting since a jump
  bool gliding_ = false;       // reacquired: moving toward the device at max_speed
  std::array<double, 3> candidate_{};  // jumped: where the device now seems to be
  double candidate_since_ = 0.0, candidate_t_ = 0.0;
  ToolPose target_;            // gliding: the reading moved toward
};

}  // namespace incise
