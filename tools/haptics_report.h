#pragma once
// The end of a run's haptic loop (`incise run --haptics`, `incise bench
// --haptics`): stopped, drained, its tick statistics and events printed, and
// the figures as JSON (haptics.json; the "haptics" key of bench's JSON).
#include <vector>

#include <nlohmann/json.hpp>

#include "haptics/haptic_loop.h"

namespace incise {

nlohmann::json finish_haptic_loop(HapticLoop& loop, std::vector<TickRecord>& records, std::vector<HapticEvent>& events);

}  // namespace incise
