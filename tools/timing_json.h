#pragma once
// The JSON timing report shared by `incise run` and `incise bench`.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/runtime/simulation.h"
#include "engine/runtime/timing_stats.h"

namespace incise {

// {frame: {median_ms, p95_ms, p99_ms, max_ms, over_budget}, stages: {name: {...}},
//  dof, factor: {nnz_L, flops, ordering}, peak_rss_mb, ...}; written atomically.
// With `frames`, also the solver report (solver.*, factor.gflops, solve.gbs,
// frame.bandwidth_multiple) and per_frame: {frame_ms, cut, stages: {name: ms
// per frame}} for the stages that ran (tools/scripts/plot-budget.py draws it).
// pace_hz: the rate frames were started at (`bench --pace`; 0 = back to back).
// `extra`: keys added at the top level ("haptics" from bench --haptics).
void write_timing_json(const std::string& path, const Simulation& sim, const TimingSummary& s,
                       const std::vector<FrameTiming>* frames = nullptr, double bandwidth_gbs = 11.0,
                       double pace_hz = 0.0, const nlohmann::json& extra = nlohmann::json::object());

// The largest resident set of this process so far (MB; getrusage).
double peak_rss_mb();

}  // namespace incise
