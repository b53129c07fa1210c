#pragma once
// The end of a run's haptic loop (`incise run --haptics`, `incise bench
// --haptics`), once stopped and drained: its tick statistics and events
// printed, and the figures as JSON (haptics.json; the "haptics" key of
// bench's JSON).
#include <vector>

#include <nlohmann/json.hpp>

#include "haptics/haptic_loop.h"
#include "haptics/tick_stats.h"

namespace incise {

nlohmann::json report_haptic_loop(const HapticLoop& loop, const TickStats& st, const std::vector<HapticEvent>& events);

}  // namespace incise
