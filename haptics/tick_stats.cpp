#include "haptics/tick_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "engine/util/file_io.h"
#include "haptics/tick_log.h"

namespace incise {
namespace {

double norm3(const std::array<double, 3>& f) { return std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]); }

constexpr double kLow = 1e-3;       // below: bin 0
constexpr double kRatio = 1.001;    // bin width
constexpr int kBins = 27632;        // up to kLow * kRatio^(kBins-1) ~ 1e9: larger values go to the last bin

}  // namespace

void TickSummary::Histogram::add(double v) {
  if (bins.empty()) bins.assign(kBins, 0);
  int b = 0;
  if (v >= kLow) b = std::min(kBins - 1, 1 + static_cast<int>(std::log(v / kLow) / std::log(kRatio)));
  ++bins[static_cast<size_t>(b)];
  min = n == 0 ? v : std::min(min, v);
  max = n == 0 ? v : std::max(max, v);
  ++n;
}

double TickSummary::Histogram::percentile(double p) const {
  if (n == 0) return 0.0;
  if (p >= 1.0) return max;
  // nearest rank: the k-th smallest, k = ceil(p n) (at least 1)
  const long k = std::max(1L, static_cast<long>(std::ceil(p * static_cast<double>(n))));
  long seen = 0;
  for (int b = 0; b < kBins; ++b) {
    seen += bins[static_cast<size_t>(b)];
    if (seen < k) continue;
    const double mid = b == 0 ? 0.0 : kLow * std::pow(kRatio, b - 0.5);
    return std::clamp(mid, min, max);
  }
  return max;
}

void TickSummary::add(const TickRecord& r) {
  ++s_.ticks;
  if (have_prev_) period_.add(1e3 * (r.t - prev_t_));
  const double l = 1e6 * (r.t - r.deadline);
  late_.add(l);
  if (l > 500.0) ++s_.late_over_half_ms;
  compute_.add(r.compute_us);
  s_.allocations += r.allocations;
  s_.max_allocations = std::max(s_.max_allocations, r.allocations);
  const double f = norm3(r.force);
  s_.force_max = std::max(s_.force_max, f);
  if (f >= force_limit_ * (1.0 - 1e-9)) ++s_.clamped;
  if (have_prev_) {
    const std::array<double, 3> d{r.force[0] - prev_force_[0], r.force[1] - prev_force_[1], r.force[2] - prev_force_[2]};
    s_.jump_max = std::max(s_.jump_max, norm3(d));
  }
  if (r.have_reading && r.raw.fresh) ++s_.readings;
  have_prev_ = true;
  prev_t_ = r.t;
  prev_force_ = r.force;
}

TickStats TickSummary::stats() const {
  TickStats s = s_;
  s.period_median_ms = period_.percentile(0.5);
  s.period_p99_ms = period_.percentile(0.99);
  s.period_max_ms = period_.percentile(1.0);
  s.late_median_us = late_.percentile(0.5);
  s.late_p99_us = late_.percentile(0.99);
  s.late_max_us = late_.percentile(1.0);
  s.compute_median_us = compute_.percentile(0.5);
  s.compute_p99_us = compute_.percentile(0.99);
  s.compute_max_us = compute_.percentile(1.0);
  return s;
}

TickStats summarize_ticks(const std::vector<TickRecord>& r, double force_limit) {
  TickSummary sum(force_limit);
  for (const TickRecord& x : r) sum.add(x);
  return sum.stats();
}

std::string format_tick_stats(const TickStats& s) {
  char buf[1024];
  std::snprintf(buf, sizeof buf,
                "haptics: %ld ticks, period median %.3f / p99 %.3f / max %.3f ms; late > 0.5 ms: %ld (%.3f%%), late "
                "p99 %.0f us, max %.0f us\n"
                "haptics: tick compute median %.1f / p99 %.1f / max %.1f us; allocations %llu (%.2g per tick, at most "
                "%u in one)\n"
                "haptics: force max %.3f N, largest change between ticks %.4f N, %ld ticks at the limit; %ld device "
                "readings\n",
                s.ticks, s.period_median_ms, s.period_p99_ms, s.period_max_ms, s.late_over_half_ms,
                s.ticks ? 100.0 * static_cast<double>(s.late_over_half_ms) / static_cast<double>(s.ticks) : 0.0,
                s.late_p99_us, s.late_max_us, s.compute_median_us, s.compute_p99_us, s.compute_max_us, s.allocations,
                s.ticks ? static_cast<double>(s.allocations) / static_cast<double>(s.ticks) : 0.0, s.max_allocations,
                s.force_max, s.jump_max, s.clamped, s.readings);
  return buf;
}

void write_force_log(const std::string& path, const std::vector<TickRecord>& records) {
  TickLogWriter w(path, "");
  w.append(records);
  w.finish();
}

void write_device_stream(const std::string& path, const std::vector<TickRecord>& records) {
  TickLogWriter w("", path);
  w.append(records);
  w.finish();
}

std::string format_event(const HapticEvent& e) {
  char buf[256];
  const double* v = e.value.data();
  const double f = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  switch (e.kind) {
    case HapticEventKind::NotFinite:
      std::snprintf(buf, sizeof buf, "rejected a reading that is not finite; the last good pose holds");
      break;
    case HapticEventKind::NotRotation:
      std::snprintf(buf, sizeof buf, "rejected a reading whose quaternion has length %.6g (not 1); the last good pose holds",
                    v[0]);
      break;
    case HapticEventKind::JawRange:
      std::snprintf(buf, sizeof buf, "rejected a reading with jaw %.6g (allowed: [0, 1]); the last good pose holds", v[0]);
      break;
    case HapticEventKind::Workspace:
      std::snprintf(buf, sizeof buf, "rejected a reading at (%.4g, %.4g, %.4g), outside the workspace (guard.workspace_radius)",
                    v[0], v[1], v[2]);
      break;
    case HapticEventKind::Jump:
      std::snprintf(buf, sizeof buf, "rejected a jump to (%.4g, %.4g, %.4g), faster than guard.max_speed", v[0], v[1], v[2]);
      break;
    case HapticEventKind::Reacquired:
      std::snprintf(buf, sizeof buf, "readings at (%.4g, %.4g, %.4g) agreed for guard.reacquire: gliding there at "
                    "guard.glide_speed", v[0], v[1], v[2]);
      break;
    case HapticEventKind::ForceClamped:
      std::snprintf(buf, sizeof buf, "force %.3g N clamped to the device's limit", f);
      break;
    case HapticEventKind::ForceNotFinite:
      std::snprintf(buf, sizeof buf, "the coupling solve gave a non-finite force: zero sent");
      break;
    case HapticEventKind::Overrun:
      std::snprintf(buf, sizeof buf, "woke %.3g ms late: %.0f tick(s) skipped", v[0], v[1]);
      break;
  }
  char head[48];
  std::snprintf(head, sizeof head, "t = %.3f s: ", e.t);
  return head + std::string(buf);
}

void write_event_log(const std::string& path, const std::vector<HapticEvent>& events) {
  std::string out = "t,event,x,y,z\n";
  char line[256];
  for (const HapticEvent& e : events) {
    std::snprintf(line, sizeof line, "%.6f,%s,%.9g,%.9g,%.9g\n", e.t, event_name(e.kind), e.value[0], e.value[1],
                  e.value[2]);
    out += line;
  }
  write_file_atomic(path, out);
}

}  // namespace incise
