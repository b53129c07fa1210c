#include "haptics/input_guard.h"

#include <algorithm>
#include <cmath>

namespace incise {

const char* event_name(HapticEventKind k) {
  switch (k) {
    case HapticEventKind::NotFinite: return "not_finite";
    case HapticEventKind::NotRotation: return "not_rotation";
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
}  // namespace

const ToolPose& InputGuard::filter(double t, const ToolPose& r, bool fresh, HapticEvent* event, bool* has_event) {
  *has_event = false;
  const double dt = std::max(0.0, t - t_last_);
  t_last_ = t;
  // Half again the step max_speed allows, for jitter in when a reading was taken.
  const double step = 1.5 * s_.max_speed * dt + 1e-9 * s_.radius;
  auto report = [&](HapticEventKind k) {
    *has_event = true;
    event->t = t;
    event->kind = k;
    event->value = r.p;
  };
  // A reading that fails a check is reported and treated as no reading.
  bool valid = fresh;
  double qn = 1.0;
  if (valid) {
    bool finite = std::isfinite(r.jaw);
    for (double x : r.p) finite = finite && std::isfinite(x);
    for (double x : r.q) finite = finite && std::isfinite(x);
    if (finite) qn = std::sqrt(r.q[0] * r.q[0] + r.q[1] * r.q[1] + r.q[2] * r.q[2] + r.q[3] * r.q[3]);
    if (!finite) report(HapticEventKind::NotFinite);
    else if (!(std::abs(qn - 1.0) <= 1e-3)) report(HapticEventKind::NotRotation);
    else if (!(distance(r.p, s_.center) <= s_.radius)) report(HapticEventKind::Workspace);
    valid = !*has_event;
  }
  if (gliding_) {  // toward the reacquired reading, max_speed per second
    if (valid) {
      target_ = r;
      for (double& x : target_.q) x /= qn;
    }
    const double d = distance(good_.p, target_.p), lim = s_.max_speed * dt;
    if (d <= lim) {
      good_ = target_;
      gliding_ = false;
    } else {
      for (int k = 0; k < 3; ++k) good_.p[k] += (target_.p[k] - good_.p[k]) * (lim / d);
    }
    good_.q = target_.q;
    good_.jaw = target_.jaw;
    return good_;
  }
  if (!valid) return good_;
  if (jumped_ && distance(r.p, good_.p) <= step) jumped_ = false;  // back where it held: a glitch
  if (jumped_) {
    // Readings that move on like a hand from where the jump landed count
    // toward reacquiring; one that jumps again starts the count over.
    if (distance(r.p, candidate_) > step) candidate_since_ = t;
    candidate_ = r.p;
    if (t - candidate_since_ >= s_.reacquire) {
      jumped_ = false;
      gliding_ = true;
      target_ = r;
      for (double& x : target_.q) x /= qn;
      report(HapticEventKind::Reacquired);
    }
    return good_;
  }
  if (distance(r.p, good_.p) > step) {
    jumped_ = true;
    candidate_ = r.p;
    candidate_since_ = t;
    report(HapticEventKind::Jump);
    return good_;
  }
  good_ = r;
  for (double& x : good_.q) x /= qn;
  return good_;
}

}  // namespace incise
