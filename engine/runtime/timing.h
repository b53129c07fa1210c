#pragma once
// Stage timers: each frame records milliseconds per stage, so a scene shows
// exactly what it spends where (and that stages it does not need cost 0).
#include <array>
#include <chrono>

namespace incise {

// The stages of a frame in loop order (../shared/DESIGN.md, "The frame as
// stages"; engine/runtime/pipeline.h runs them). assembly, factorization and
// solve run once per Newton iteration (solve decides whether another
// follows; a lagged rescue runs factorization and solve again); the others
// once per frame, or never when the scene does not call for them (no tool:
// no tool poses, collision or contact publish; no cut: no cutting; render
// and record only when asked).
enum Stage {
  kStageToolPoses,
  kStageCollision,
  kStageCutting,
  kStageAssembly,
  kStageFactorization,
  kStageSolve,
  kStageContact,
  kStageIntegration,
  kStageContactPublish,
  kStageRender,
  kStageRecord,
  kNumStages
};
inline constexpr std::array<const char*, kNumStages> kStageNames = {
    "tool_poses", "collision", "cutting", "assembly", "factorization", "solve", "contact", "integration", "contact_publish",
    "render", "record"};

// Parts of the cutting stage in a cut frame (they sum to its ms[kStageCutting]
// up to the surface set-up): the X-FEM layout, the Model rebuild, the transfer
// of u, v, a and rotations, the solver's set-up for the new pattern, and the
// consistent acceleration.
enum CutPart { kCutLayout, kCutModel, kCutTransfer, kCutSolverSetup, kCutAcceleration, kNumCutParts };
inline constexpr std::array<const char*, kNumCutParts> kCutPartNames = {"  layout", "  model", "  transfer",
                                                                       "  solver setup", "  acceleration"};

struct FrameTiming {
  std::array<double, kNumStages> ms{};  // per stage (all its runs this frame)
  std::array<int, kNumStages> runs{};   // times each stage ran this frame (0: absent)
  std::array<double, kNumCutParts> cut_ms{};  // parts of ms[kStageCutting] (cut frames)
  double frame_ms = 0.0;                // whole frame, wall clock
  double cpu_ms = 0.0;                  // CPU time of the stepping thread in the frame (frame_ms - cpu_ms: time it waited or was preempted)
  bool cut_frame = false;               // the DOF set changed this frame (new symbolic analysis)
  bool cut_ahead = false;               // its layout and model were prepared during the previous frame
  bool cut_early = false;               // ... beside this frame's collision stage (a scalpel's cut)
  int newton = 0;                       // linearised solves (Newton iterations) this frame
  // Linear solver of the frame (all Newton iterations together).
  int iterations = 0;         // CG iterations (lagged, warped_cg); 0 for direct policies
  int solves = 0;             // forward+back substitutions with a Cholesky factor
  double solve_kernel_ms = 0; // time inside those substitutions
  int takeovers = 0;          // their worker's bins the stepping thread did itself (CholmodSolver::set_substitution_worker)
  int assembly_workers = 0;   // workers of the frame's last assembly: solver.threads, 1 while they stood down (SolverWork::apply_stand_down)
  double residual = 0;        // last relative residual |A du - b| / |b| of CG (0 when direct)
  double start_residual = 1;  // CG's relative residual at its start (< 1: solver.initial_guess "previous" helped)
  bool converged = true;      // CG reached solver.tolerance within solver.max_iterations
  int rescues = 0;            // lagged: synchronous refactorizations after solver.rescue_after CG iterations
  bool budget_spent = false;  // solver.frame_iterations ran out: the frame took CG's last residual (`residual`) as it was
  int factor_age = 0;         // lagged: frames since the matrix of the preconditioning factor (last Newton iteration)
  int late_factor_call = -1;  // late_factor "skip": the lagged refresh call (0, 1, ...) that took a finished background factor; -1 none (Workspace::imposed_late_factor_call)
  int patch_dofs = 0;         // lagged after cuts: DOFs of the exactly solved patch (0: none)
  int condensed_dofs = 0;     // lagged after cuts: DOFs condensed out next to tiny pieces (solver.condense_below)
  int tangent_updates = 0;    // elements whose tangent blocks were (re)computed (all but the kept ones: integrator.tangent_reuse)
  int inverted_points = 0;    // cubature points the frame's last assembly found inverted or degenerate (SVD fallback of the rotation)
  double rotation_change = 0; // adaptive Newton: largest rotation change (rad) at the last check (integrator.rotation_tolerance)
  double rotation_rms = 0;    // adaptive Newton: the volume-weighted RMS of every slot's change (rad) at the last check, largest over the bodies
  double rotation_above = 0;  // adaptive Newton: the volume fraction that changed more than rotation_tolerance, largest over the bodies
  int line_search_halvings = 0;  // Newton iterations taken back halfway (integrator.line_search), each an extra assembly
  bool recovery = false;      // the step was a recovery step (State::recovery: backward Euler, integrator.recovery)
  bool newton_capped = false; // Newton stopped with rotations still moving, at its cap (or solver.frame_iterations) or in a severed piece under rotation_fraction of the tissue: the next step recovers
  // Instruments (collision/, engine/dynamics/contact_solve.h).
  int contacts = 0;           // contact rows of the frame (after reduction to contact.max_rows)
  int grasp_rows = 0;         // bilateral grasp rows
  int contact_sweeps = 0;     // projected Gauss-Seidel sweeps (all Newton iterations)
  int compliance_columns = 0; // columns of Y = A^-1 H^T substituted (0 where an earlier Newton iteration's or frame's Y served)
  double contact_force = 0;   // |sum of lambda dir| over the contact and grasp rows (N)
  double max_depth = 0;       // deepest penetration collision found at the frame's start (before the response)
  int swept_rows = 0;         // contact rows from a fast probe's sweep (faces it went through: collision_stage.h)
  int speculative_rows = 0;   // speculative rows for tissue that may reach a probe within the frame (collision_stage.h)
  int held_rows_dropped = 0;  // contact rows left out on tissue a grasp holds (collision_stage.cpp)
  int bvh_refits = 0;         // tissue collision model refitted this frame
  int bvh_rebuilds = 0;       // rebuilt (after a topology change)
};

class Stopwatch {
 public:
  Stopwatch() : t0_(std::chrono::steady_clock::now()) {}
  double ms() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0_).count();
  }
  // Milliseconds since construction or the last lap.
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double d = std::chrono::duration<double, std::milli>(now - t0_).count();
    t0_ = now;
    return d;
  }

 private:
  std::chrono::steady_clock::time_point t0_;
};

// Runs one stage and books its time and run: the only place a stage is
// timed (the pipeline and the step's Newton loop call it; stages never time
// themselves).
template <class F>
void run_stage(FrameTiming& timing, Stage stage, F&& fn) {
  Stopwatch clock;
  fn();
  timing.ms[stage] += clock.ms();
  ++timing.runs[stage];
}

}  // namespace incise
