#include "haptics/tick_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "engine/util/file_io.h"

namespace incise {
namespace {

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(std::ceil(p * static_cast<double>(v.size()))) - (p > 0 ? 1 : 0));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

double norm3(const std::array<double, 3>& f) { return std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]); }

}  // namespace

TickStats summarize_ticks(const std::vector<TickRecord>& r, double force_limit) {
  TickStats s;
  s.ticks = static_cast<long>(r.size());
  std::vector<double> period, late, compute;
  for (size_t i = 0; i < r.size(); ++i) {
    if (i > 0) period.push_back(1e3 * (r[i].t - r[i - 1].t));
    const double l = 1e6 * (r[i].t - r[i].deadline);
    late.push_back(l);
    if (l > 500.0) ++s.late_over_half_ms;
    compute.push_back(r[i].compute_us);
    s.allocations += r[i].allocations;
    s.max_allocations = std::max(s.max_allocations, r[i].allocations);
    const double f = norm3(r[i].force);
    s.force_max = std::max(s.force_max, f);
    if (f >= force_limit * (1.0 - 1e-9)) ++s.clamped;
    if (i > 0) {
      const std::array<double, 3> d{r[i].force[0] - r[i - 1].force[0], r[i].force[1] - r[i - 1].force[1],
                                    r[i].force[2] - r[i - 1].force[2]};
      s.jump_max = std::max(s.jump_max, norm3(d));
    }
    if (r[i].have_reading && r[i].raw.fresh) ++s.readings;
  }
  s.period_median_ms = percentile(period, 0.5);
  s.period_p99_ms = percentile(period, 0.99);
  s.period_max_ms = percentile(period, 1.0);
  s.late_median_us = percentile(late, 0.5);
  s.late_p99_us = percentile(late, 0.99);
  s.late_max_us = percentile(late, 1.0);
  s.compute_median_us = percentile(compute, 0.5);
  s.compute_p99_us = percentile(compute, 0.99);
  s.compute_max_us = percentile(compute, 1.0);
  return s;
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
  std::string out = "t,fx,fy,fz,tick_us,late_us\n";
  out.reserve(64 * records.size() + 32);
  char line[192];
  for (const TickRecord& r : records) {
    std::snprintf(line, sizeof line, "%.6f,%.9g,%.9g,%.9g,%.2f,%.2f\n", r.t, r.force[0], r.force[1], r.force[2],
                  static_cast<double>(r.compute_us), 1e6 * (r.t - r.deadline));
    out += line;
  }
  write_file_atomic(path, out);
}

void write_device_stream(const std::string& path, const std::vector<TickRecord>& records) {
  std::string out = "# device readings as received (haptics/replay_device.h)\nt,x,y,z,qw,qx,qy,qz,jaw,buttons\n";
  char line[320];
  for (const TickRecord& r : records) {
    if (!r.have_reading || !r.raw.fresh) continue;
    const ToolPose& p = r.raw.pose;
    std::snprintf(line, sizeof line, "%.9f,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%u\n", r.t, p.p[0], p.p[1],
                  p.p[2], p.q[0], p.q[1], p.q[2], p.q[3], p.jaw, r.raw.buttons);
    out += line;
  }
  write_file_atomic(path, out);
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
