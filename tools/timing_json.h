#pragma once
// The JSON timing report shared by `incise run` and `incise bench`.
#include <string>
#include <vector>

#include "engine/runtime/simulation.h"
#include "engine/runtime/timing_stats.h"

namespace incise {

// {frame: {median_ms, p95_ms, p99_ms, max_ms, over_budget}, stages: {name: {...}},
//  dof, factor: {nnz_L, flops, ordering}, ...}; written atomically.
// With `frames`, also the solver report (solver.*, factor.gflops, solve.gbs, frame.bandwidth_multiple).
// pace_hz: the rate frames were started at (`bench --pace`; 0 = back to back).
void write_timing_json(const std::string& path, const Simulation& sim, const TimingSummary& s,
                       const std::vector<FrameTiming>* frames = nullptr, double bandwidth_gbs = 11.0,
                       double pace_hz = 0.0);

}  // namespace incise
