#pragma once
// What the linear solver did over a run of frames: factor size and speed,
// substitution bandwidth, frame time against the memory-bandwidth limit of one
// substitution, CG iterations. Printed by `incise bench` and written into the
// timing JSON of bench and run.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/runtime/simulation.h"
#include "engine/runtime/timing.h"
#include "engine/runtime/timing_stats.h"

namespace incise {

struct SolverReport {
  std::string policy;
  int threads = 1;
  double nnz_L = 0, flops = 0;     // factor entries, flops of one numeric factorization
  int factorizations = 0;          // numeric factorizations in the run (all threads)
  double factor_ms_mean = 0;       // their mean wall time
  double gflops = 0;               // flops / factor_ms_mean
  bool single_precision = false;   // solver.factor_precision "single"
  int single_factorizations = 0;   // of `factorizations`: done in float
  int single_fallbacks = 0;        // of those: float pivots that failed, redone by CHOLMOD in double
  double substitutions_per_frame = 0;  // median
  double substitution_ms = 0;      // mean time of one forward+back substitution
  double solve_gbs = 0;            // 2 * 8 bytes * nnz_L / substitution_ms (L read twice)
  double bandwidth_gbs = 11.0;     // the constant the limit uses
  double bandwidth_limit_ms = 0;   // one substitution at bandwidth_gbs
  double frame_multiple = 0;       // median frame time / bandwidth_limit_ms
  Percentiles iterations;          // CG iterations per frame (as "ms" fields: median, p95, p99, max)
  int not_converged_frames = 0;    // frames whose CG stopped at max_iterations above tolerance
  int rescue_frames = 0;           // lagged: frames that factored the current matrix (solver.rescue_after)
  double max_residual = 0;         // largest final CG relative residual
};

SolverReport solver_report(const Simulation& sim, const std::vector<FrameTiming>& frames, const TimingSummary& s,
                           double bandwidth_gbs = 11.0);
std::string format_solver_report(const SolverReport& r);
nlohmann::json solver_report_json(const SolverReport& r);

}  // namespace incise

namespace incise {

// Command-line overrides of the scene's solver.* keys (bench, compare).
struct SolverOverrides {
  std::string policy;  // empty: the scene's
  double tolerance = 0;  // 0: the scene's
  int max_iterations = 0, refresh_every = 0, threads = 0, substitution_threads = 0;
  int rescue_after = -1;  // -1: the scene's
  double tangent_reuse = -1;  // integrator.tangent_reuse of the runs under test (-1: the scene's; not the exact reference)
  bool background = false;
  bool warp = false;
  std::string single_precision;  // "", "true" or "false"
  std::string factor_copy;       // "", "none", "float" or "half"
  std::string factor_precision;  // "", "double" or "single"
  std::string initial_guess;     // "", "zero" or "previous"
  std::string late_factor;       // "", "wait" or "skip"
  std::string patch;             // "", "additive" or "multiplicative"
  std::string cut_ordering;      // "", "search" or "carried"
  std::string background_priority;  // "", "idle" or "normal"
  std::string affinity;             // "", "none" or "split"
  std::string factorization, ordering;  // empty: the scene's
};
// Registers --policy, --tolerance, ... on a sub-command.
void add_solver_options(void* cli_app, SolverOverrides& o, bool with_policy = true);
// Applies the overrides to the model and re-initialises the state (t = 0).
void apply_solver_overrides(Simulation& sim, const SolverOverrides& o);

}  // namespace incise
