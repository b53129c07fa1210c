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
  int capped_frames = 0;    // Newton stopped with the rotations still moving (FrameTiming::newton_capped)
  int recovery_frames = 0;  // recovery steps (backward Euler after a severing cut or a capped frame, integrator.recovery)
  int budget_frames = 0;           // frames that spent solver.frame_iterations (FrameTiming::budget_spent)
  double max_budget_residual = 0;  // the largest CG residual such a frame accepted
  double max_residual = 0;         // largest final CG relative residual
};

SolverReport solver_report(const Simulation& sim, const std::vector<FrameTiming>& frames, const TimingSummary& s,
                           double bandwidth_gbs = 11.0);
std::string format_solver_report(const SolverReport& r);
nlohmann::json solver_report_json(const SolverReport& r);

}  // namespace incise

namespace CLI {
class App;
}

namespace incise {

// The resolved solver.* and integrator.* settings of a loaded scene, each
// marked with where it came from ([preset], [scene], [--set] for a patch;
// unmarked: the default): a short block printed by run, bench and compare.
std::string format_resolved_settings(const Scene& s);

// --set KEY=VALUE on a sub-command (repeatable): a patch of the scene's JSON
// before it is parsed (engine/scene/scene.h, ScenePatch).
void add_set_option(CLI::App& cmd, std::vector<ScenePatch>& patches);
// The solver flags of bench and compare as aliases of --set, each adding the
// patch it names: --policy P = --set solver.policy=P, --tolerance X =
// --set solver.tolerance=X, --background = --set solver.background=true,
// --tangent-reuse X = --set integrator.tangent_reuse=X, ... (docs/scene-format.md).
// Patches keep the command line's order. No value is checked here: the
// scene parser checks them all.
void add_solver_aliases(CLI::App& cmd, std::vector<ScenePatch>& patches, bool with_policy = true);

}  // namespace incise
