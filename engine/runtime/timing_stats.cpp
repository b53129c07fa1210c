#include "engine/runtime/timing_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace incise {

Percentiles percentiles(std::vector<double> x) {
  Percentiles p;
  p.count = static_cast<int>(x.size());
  if (x.empty()) return p;
  std::sort(x.begin(), x.end());
  auto rank = [&](double q) {
    const size_t k = static_cast<size_t>(std::ceil(q * x.size()));
    return x[std::min(x.size() - 1, k == 0 ? 0 : k - 1)];
  };
  p.median_ms = x.size() % 2 ? x[x.size() / 2] : 0.5 * (x[x.size() / 2 - 1] + x[x.size() / 2]);
  p.p95_ms = rank(0.95);
  p.p99_ms = rank(0.99);
  p.max_ms = x.back();
  return p;
}

TimingSummary summarize(const std::vector<FrameTiming>& frames, double budget_ms) {
  TimingSummary s;
  s.budget_ms = budget_ms;
  std::vector<double> f, cut, plain;
  std::vector<double> st[kNumStages], parts[kNumCutParts];
  int over = 0;
  for (const auto& t : frames) {
    f.push_back(t.frame_ms);
    (t.cut_frame ? cut : plain).push_back(t.frame_ms);
    over += t.frame_ms > budget_ms;
    for (int k = 0; k < kNumStages; ++k) {
      st[k].push_back(t.ms[k]);
      s.runs[k] += t.runs[k];
    }
    for (int k = 0; t.cut_frame && k < kNumCutParts; ++k) parts[k].push_back(t.cut_ms[k]);
    s.cut_ahead += t.cut_frame && t.cut_ahead;
    s.cut_early += t.cut_frame && t.cut_early;
  }
  for (const auto& t : frames) {
    s.newton_mean += t.newton;
    s.newton_max = std::max(s.newton_max, t.newton);
  }
  if (!frames.empty()) s.newton_mean /= frames.size();
  for (const auto& t : frames) {
    const bool rows = t.contacts + t.grasp_rows > 0;
    s.contact_frames += rows;
    s.contacts_mean += t.contacts;
    s.contacts_max = std::max(s.contacts_max, t.contacts);
    s.grasp_rows_max = std::max(s.grasp_rows_max, t.grasp_rows);
    s.contact_sweeps_mean += rows ? t.contact_sweeps : 0;
    s.max_depth = std::max(s.max_depth, t.max_depth);
    s.contact_force_max = std::max(s.contact_force_max, t.contact_force);
    s.bvh_refits += t.bvh_refits;
    s.bvh_rebuilds += t.bvh_rebuilds;
    s.swept_frames += t.swept_rows > 0;
    s.speculative_frames += t.speculative_rows > 0;
  }
  if (!frames.empty()) s.contacts_mean /= frames.size();
  if (s.contact_frames > 0) s.contact_sweeps_mean /= s.contact_frames;
  int pairs = 0;
  for (size_t k = 1; k < frames.size(); ++k) {
    const FrameTiming &a = frames[k - 1], &b = frames[k];
    if (a.contacts + a.grasp_rows == 0 || b.contacts + b.grasp_rows == 0) continue;
    s.contact_force_change += std::abs(b.contact_force - a.contact_force);
    ++pairs;
  }
  if (pairs > 0) s.contact_force_change /= pairs;
  s.frame = percentiles(f);
  s.cut_frames = percentiles(cut);
  s.plain_frames = percentiles(plain);
  for (int k = 0; k < kNumStages; ++k) s.stages[k] = percentiles(st[k]);
  for (int k = 0; k < kNumCutParts; ++k) s.cut_parts[k] = percentiles(parts[k]);
  s.over_budget = frames.empty() ? 0.0 : static_cast<double>(over) / frames.size();
  return s;
}

std::string format_summary(const TimingSummary& s) {
  std::string out;
  char line[768];
  std::snprintf(line, sizeof line, "%-16s %10s %10s %10s %10s %8s\n", "stage (ms)", "median", "p95", "p99", "max", "runs");
  out += line;
  auto row = [&](const char* name, const Percentiles& p, long long runs = -1) {
    std::snprintf(line, sizeof line, "%-16s %10.3f %10.3f %10.3f %10.3f", name, p.median_ms, p.p95_ms, p.p99_ms,
                  p.max_ms);
    out += line;
    if (runs >= 0) {
      std::snprintf(line, sizeof line, " %8lld", runs);
      out += line;
    }
    out += "\n";
  };
  for (int k = 0; k < kNumStages; ++k) {
    row(kStageNames[k], s.stages[k], s.runs[k]);
    // The cutting stage's parts, over the cut frames only.
    for (int j = 0; k == kStageCutting && s.cut_frames.count > 0 && j < kNumCutParts; ++j)
      row(kCutPartNames[j], s.cut_parts[j]);
  }
  row("frame", s.frame);
  if (s.cut_frames.count > 0) {
    row("cut frame", s.cut_frames);
    row("other frames", s.plain_frames);
  }
  std::snprintf(line, sizeof line, "Newton iterations per frame: mean %.2f, max %d\n", s.newton_mean, s.newton_max);
  out += line;
  std::snprintf(line, sizeof line, "frames over the %.1f ms budget: %.1f%% of %d (%d cut frames)\n", s.budget_ms,
                100.0 * s.over_budget, s.frame.count, s.cut_frames.count);
  out += line;
  if (s.runs[kStageCollision] > 0) {
    std::snprintf(line, sizeof line,
                  "instruments: %d frames with contacts or grasps; contact rows per frame mean %.1f, max %d; grasp rows "
                  "max %d;\n  PGS sweeps per such frame %.0f; deepest penetration found at a frame's start %.3g; "
                  "largest total force %.3g N, its change between frames mean %.3g N;\n  collision tree refitted %lld "
                  "times, rebuilt %lld (topology changes); %d frames with rows from a fast probe's sweep (moving more "
                  "than half its radius a frame), %d with speculative rows (tissue moving faster than the margin)\n",
                  s.contact_frames, s.contacts_mean, s.contacts_max, s.grasp_rows_max, s.contact_sweeps_mean,
                  s.max_depth, s.contact_force_max, s.contact_force_change, s.bvh_refits, s.bvh_rebuilds,
                  s.swept_frames, s.speculative_frames);
    out += line;
  }
  if (s.cut_frames.count > 0) {
    std::snprintf(line, sizeof line,
                  "cut frames whose layout and model were built during the previous frame's step: %d of %d, "
                  "beside the frame's collision stage: %d\n",
                  s.cut_ahead, s.cut_frames.count, s.cut_early);
    out += line;
  }
  return out;
}

}  // namespace incise
