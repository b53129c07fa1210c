#pragma once
// Summaries of per-frame stage timings: median, p95, p99, max.
#include <string>
#include <vector>

#include "engine/runtime/timing.h"

namespace incise {

struct Percentiles {
  double median_ms = 0, p95_ms = 0, p99_ms = 0, max_ms = 0;
  int count = 0;
};
// Nearest-rank percentiles of the samples.
Percentiles percentiles(std::vector<double> samples);

struct TimingSummary {
  Percentiles frame;
  Percentiles stages[kNumStages];
  long long runs[kNumStages] = {};  // times each stage ran over all the frames (0: absent from the pipeline)
  double over_budget = 0.0;  // share of frames with frame_ms > budget_ms
  Percentiles cut_frames;    // frames whose DOF set changed (a cut), frame_ms
  Percentiles plain_frames;  // the other frames
  Percentiles cut_parts[kNumCutParts];  // parts of the cutting stage, over the cut frames
  int cut_ahead = 0;         // cut frames whose layout and model were prepared during the previous frame
  int cut_early = 0;         // ... beside the frame's own collision stage (a scalpel's cut)
  double newton_mean = 0;    // linearised solves per frame
  int newton_max = 0;
  double budget_ms = 1000.0 / 30.0;
  // Instruments (frames where the collision stage ran).
  int contact_frames = 0;       // frames with contact or grasp rows
  double contacts_mean = 0;     // contact rows per frame (over all frames)
  int contacts_max = 0;
  int grasp_rows_max = 0;
  double contact_sweeps_mean = 0;  // PGS sweeps per frame with rows
  double max_depth = 0;         // deepest penetration collision found at a frame's start
  double contact_force_max = 0; // largest |total contact and grasp force| (N)
  // Mean change of that force between consecutive frames that both have
  // rows (N): a held tool's force chatters when this is a large share of it.
  double contact_force_change = 0;
  long long bvh_refits = 0, bvh_rebuilds = 0;
  int swept_frames = 0;         // frames with rows from a fast probe's sweep
  int speculative_frames = 0;   // frames with speculative rows (fast tissue near a probe)
};
TimingSummary summarize(const std::vector<FrameTiming>& frames, double budget_ms = 1000.0 / 30.0);
// A fixed-width table: stage, median, p95, p99, max (ms), runs.
std::string format_summary(const TimingSummary& s);

}  // namespace incise
