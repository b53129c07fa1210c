#pragma once
// What a haptic run measured, from its tick records (haptics/haptic_loop.h):
// the figures `incise run --haptics` prints and writes to haptics.json.
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

// Percentiles by nearest rank. force_limit: for counting clamped ticks.
TickStats summarize_ticks(const std::vector<TickRecord>& records, double force_limit);
std::string format_tick_stats(const TickStats& s);

// Writes the force log "t,fx,fy,fz,tick_us,late_us" (one row per tick) and
// the device stream (haptics/replay_device.h's format, fresh readings only),
// each through a temporary file renamed into place. Throws incise::Error.
void write_force_log(const std::string& path, const std::vector<TickRecord>& records);
void write_device_stream(const std::string& path, const std::vector<TickRecord>& records);
// One event in words: "t = 0.302 s: rejected a reading 10 m away from the workspace centre ...".
std::string format_event(const HapticEvent& e);
// "t,event,x,y,z".
void write_event_log(const std::string& path, const std::vector<HapticEvent>& events);

}  // namespace incise
