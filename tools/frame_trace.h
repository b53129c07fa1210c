#pragma once
// Per-frame timing trace (CSV) of `incise bench --trace`:
// one row per timed frame, every stage and cutting part in ms, so a slow
// frame can be explained after the fact (which stage, a cut, a rescue, CG).
#include <string>
#include <vector>

#include "engine/runtime/timing.h"

namespace incise {

// Columns: frame, frame_ms, cut_frame, <stage>_ms..., cut_<part>_ms...,
// newton, cg_iterations, substitutions, rescues, converged. `first_frame`
// numbers the first row (frames stepped before timing started). Written
// atomically; throws naming the file when it cannot be written.
void write_frame_trace(const std::string& path, const std::vector<FrameTiming>& frames, int first_frame);

}  // namespace incise
