#include "haptics/input_guard.h"

#include "engine/runtime/trajectory.h"  // slerp

#include <algorithm>
#include <cmath>

namespace incise {

const char* event_name(HapticEventKind k) {
  switch (k) {
    case HapticEventKind::NotFinite: return "not_finite";
    case HapticEventKind::NotRotation: return "not_rotation";
    case HapticEventKind::JawRange: return "jaw_range";
    case HapticEventKind::Workspace: return "workspace";
    case HapticEventKind::Jump: return "jump";
    case HapticEventKind::Reacquired: return "reacquired";
    case HapticEventKind::ForceClamped: return "force_clamped";
    case HapticEventKind::ForceNotFinite: return "force_not_finite";
    case HapticEventKind::Overrun: return "overrun";
  }
  return "?";
}

namespace {
double distance(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}
double rotation_angle(const std::array<double, 4>& a, const std::array<double, 4>& b) {
  const double dot = std::abs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]);
  return 2.0 * std::acos(std::min(1.0, dot));
}

}  // namespace

const ToolPose& InputGuard::filter(double t, const ToolPose& r, bool fresh, HapticEvent* event, bool* has_event) {
  *has_event = false;
  const double tick_dt = std::max(0.0, t - t_last_);
  t_last_ = t;
  auto report = [&](HapticEventKind k, const std::array<double, 3>& value) {
    *has_event = true;
    event->t = t;
    event->kind = k;
    event->value = value;
  };
  // A reading that fails a check is reported and treated as no reading.
  bool valid = fresh;
  double qn = 1.0;
  if (valid) {
    bool finite = std::isfinite(r.jaw);
    for (double x : r.p) finite = finite && std::isfinite(x);
    for (double x : r.q) finite = finite && std::isfinite(x);
    if (finite) qn = std::sqrt(r.q[0] * r.q[0] + r.q[1] * r.q[1] + r.q[2] * r.q[2] + r.q[3] * r.q[3]);
    if (!finite) report(HapticEventKind::NotFinite, r.p);
    else if (!(std::abs(qn - 1.0) <= 1e-3)) report(HapticEventKind::NotRotation, {qn, 0.0, 0.0});
    else if (!(r.jaw >= 0.0 && r.jaw <= 1.0)) report(HapticEventKind::JawRange, {r.jaw, 0.0, 0.0});
    else if (!(distance(r.p, s_.center) <= s_.radius)) report(HapticEventKind::Workspace, r.p);
    valid = !*has_event;
  }
  ToolPose unit = r;
  for (double& x : unit.q) x /= qn;
  if (gliding_) {  // toward the reacquired reading, at glide_speed and max_turn
    if (valid) target_ = unit;
    const double d = distance(good_.p, target_.p), lim = s_.glide_speed * tick_dt;
    const double ang = rotation_angle(good_.q, target_.q), turn = s_.max_turn * tick_dt;
    if (d > lim)
      for (int k = 0; k < 3; ++k) good_.p[k] += (target_.p[k] - good_.p[k]) * (lim / d);
    else
      good_.p = target_.p;
    good_.q = ang > turn ? slerp(good_.q, target_.q, turn / ang) : target_.q;
    good_.jaw = target_.jaw;
    gliding_ = d > lim || ang > turn;
    if (valid) t_fresh_ = t;
    return good_;
  }
  if (!valid) return good_;
  // Speeds between fresh readings (capped, so that a device back after a
  // long silence is not allowed an arbitrary step); half again for jitter.
  const double dt = std::min(t - t_fresh_, 0.05);
  t_fresh_ = t;
  const double step = 1.5 * s_.max_speed * dt + 1e-9 * s_.radius, turn = 1.5 * s_.max_turn * dt + 1e-9;
  if (jumped_ && distance(unit.p, good_.p) <= step && rotation_angle(unit.q, good_.q) <= turn)
    jumped_ = false;  // back where it held: a glitch
  if (jumped_) {
    // Readings that move on like a hand from where the jump landed count
    // toward reacquiring; one that jumps again starts the count over.
    const double since = std::min(t - candidate_t_, 0.05);
    if (distance(unit.p, candidate_) > 1.5 * s_.max_speed * since + 1e-9 * s_.radius) candidate_since_ = t;
    candidate_ = unit.p;
    candidate_t_ = t;
    if (t - candidate_since_ >= s_.reacquire) {
      jumped_ = false;
      gliding_ = true;
      target_ = unit;
      report(HapticEventKind::Reacquired, unit.p);
    }
    return good_;
  }
  if (distance(unit.p, good_.p) > step || rotation_angle(unit.q, good_.q) > turn) {
    jumped_ = true;
    candidate_ = unit.p;
    candidate_since_ = candidate_t_ = t;
    report(HapticEventKind::Jump, unit.p);
    return good_;
  }
  good_ = unit;
  return good_;
}

}  // namespace incise
