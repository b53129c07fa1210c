#pragma once
// incise study: what accuracy costs in time. A study is the cartesian
// product of knob values (--sweep KNOB=V1,V2,...); each point is the scene
// run with those values (one independent `incise study --point K` process
// writing DIR/points/point_K.json), and the collection compares every
// point with a reference (the point with each knob at its finest value, or
// a given result file) at stated frames: relative L2 displacement error
// over the body (sampled at the base mesh's corner nodes, located in each
// point's own mesh), probe errors, energy drift, against ms per frame
// (median, p99), with the Pareto front marked. The logic here has no
// engine dependencies (tests/tools/test_study.cpp).
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace incise {

struct Sweep {
  std::string knob;                 // as given ("order", "solver.tolerance")
  std::string key;                  // the scene key it sets ("mesh.order")
  std::vector<std::string> values;  // as given, in order
};

// "KNOB=V1,V2,..." -> a Sweep. Knob aliases: order (mesh.order), mesh
// (mesh.file), rotation (material.rotation), preset (solver.preset), policy
// (solver.policy), tolerance (solver.tolerance), newton
// (integrator.newton_iterations), mass, dt (integrator.dt); any other
// dotted scene key as is. Throws incise::Error naming the argument.
Sweep parse_sweep(const std::string& text);

// The value of a sweep that is its finest (most accurate) setting: order,
// newton: the largest; tolerance, dt: the smallest; rotation: per_point;
// policy: exact; preset: reference; mass: consistent; otherwise (mesh files
// too: list them coarse to fine) the last listed.
int finest_value(const Sweep& sweep);

// The points: every combination, the last sweep varying fastest.
// points[k][s] = index into sweeps[s].values.
std::vector<std::vector<int>> study_points(const std::vector<Sweep>& sweeps);
// The point with every knob at its finest value.
int reference_point(const std::vector<Sweep>& sweeps);

// Indices of the points on the Pareto front of (cost, error), both
// minimised: no other point is at most as costly and as wrong and strictly
// better in one. Points with a non-finite cost or error are never on it.
// Ascending by cost.
std::vector<int> pareto_front(const std::vector<double>& cost, const std::vector<double>& error);

// Relative L2 difference of two sampled fields (n, 3) over the samples
// finite in both: sqrt(sum |a - b|^2 / sum |b|^2); NaN when none is.
double relative_l2(const std::vector<double>& a, const std::vector<double>& b);

// The table of a collected study (collect_study): one row per point.
struct StudyRow {
  int point = 0;
  std::vector<std::string> values;  // per sweep
  bool ok = false;
  std::string failure;              // why the point did not finish
  int dof = 0;
  double median_ms = 0, p99_ms = 0;
  std::vector<double> error;        // per stated frame (relative L2 over the body)
  double probe_error = -1;          // relative L2 over the probe points at the last frame (-1: no probe file)
  double energy_drift = 0;          // (E_last - E_0) / max |E| (start, stated frames, end), total energy
  bool pareto = false;
};

// The rows from the plan (DIR/study.json) and the point results (json per
// point; null for a point not run yet), against `reference` (a point
// result). Error, probe error and Pareto front use the last stated frame.
std::vector<StudyRow> collect_rows(const nlohmann::json& plan, const std::vector<nlohmann::json>& results,
                                   const nlohmann::json& reference);
std::string study_csv(const nlohmann::json& plan, const std::vector<StudyRow>& rows);
std::string study_markdown(const nlohmann::json& plan, const std::vector<StudyRow>& rows);

}  // namespace incise
