#pragma once
// What a haptic run measured, from its tick records (haptics/haptic_loop.h):
// the figures `incise run --haptics` prints and writes to haptics.json.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "haptics/haptic_loop.h"

namespace incise {

struct TickStats {
  long ticks = 0;
  double period_median_ms = 0, period_p99_ms = 0, period_max_ms = 0;  // between consecutive wake-ups
  double late_median_us = 0, late_p99_us = 0, late_max_us = 0;        // wake-up after the deadline
  long late_over_half_ms = 0;                                         // ticks that woke > 0.5 ms late
  double compute_median_us = 0, compute_p99_us = 0, compute_max_us = 0;
  unsigned long long allocations = 0;  // in all ticks together
  unsigned max_allocations = 0;        // in one tick
  double force_max = 0;                // N
  double jump_max = 0;                 // largest change of the force between consecutive ticks (N)
  long clamped = 0;                    // ticks at the force limit
  long readings = 0;                   // fresh device readings
};

// The figures of a run's ticks, kept in constant memory as the records come
// (a run of hours at 1 kHz must not hold its records: issue 24's soak saw a
// kept log grow 8 MB a minute). Percentiles by nearest rank from histograms
// whose bins are 0.1% wide (from 1e-3 us or ms up), so within 0.05% of the
// exact order statistic; maxima exact.
class TickSummary {
 public:
  explicit TickSummary(double force_limit) : force_limit_(force_limit) {}
  void add(const TickRecord& r);
  TickStats stats() const;

 private:
  struct Histogram {
    std::vector<std::uint32_t> bins;  // bin 0: v < kLow; bin b >= 1: [kLow r^(b-1), kLow r^b)
    double min = 0.0, max = 0.0;
    long n = 0;
    void add(double v);
    double percentile(double p) const;  // 0 when empty
  };
  double force_limit_;
  TickStats s_;
  Histogram period_, late_, compute_;
  bool have_prev_ = false;
  double prev_t_ = 0.0;
  std::array<double, 3> prev_force_{};
};

// The same over records in memory. force_limit: for counting clamped ticks.
TickStats summarize_ticks(const std::vector<TickRecord>& records, double force_limit);
std::string format_tick_stats(const TickStats& s);

// Writes the force log "t,fx,fy,fz,tick_us,late_us" (one row per tick) or
// the device stream (haptics/replay_device.h's format, fresh readings only)
// of records in memory (haptics/tick_log.h streams them during a run).
void write_force_log(const std::string& path, const std::vector<TickRecord>& records);
void write_device_stream(const std::string& path, const std::vector<TickRecord>& records);
// One event in words: "t = 0.302 s: rejected a reading 10 m away from the workspace centre ...".
std::string format_event(const HapticEvent& e);
// "t,event,x,y,z".
void write_event_log(const std::string& path, const std::vector<HapticEvent>& events);

}  // namespace incise
