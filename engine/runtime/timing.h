#pragma once
// Stage timers: each frame records milliseconds per stage, so a scene shows
// exactly what it spends where (and that stages it does not need cost 0).
#include <array>
#include <chrono>

namespace incise {

// render: offscreen drawing and read-back of the frame, only when asked
// (`run --render`, `bench --render`); step() itself never renders.
enum Stage { kStageCutting, kStageAssembly, kStageFactorization, kStageSolve, kStageRender, kStageOther, kNumStages };
inline constexpr std::array<const char*, kNumStages> kStageNames = {"cutting", "assembly", "factorization", "solve", "render",
                                                                    "other"};

// Parts of the cutting stage in a cut frame (they sum to its ms[kStageCutting]
// up to the surface set-up): the X-FEM layout, the Model rebuild, the transfer
// of u, v, a and rotations, the solver's set-up for the new pattern, and the
// consistent acceleration.
enum CutPart { kCutLayout, kCutModel, kCutTransfer, kCutSolverSetup, kCutAcceleration, kNumCutParts };
inline constexpr std::array<const char*, kNumCutParts> kCutPartNames = {"  layout", "  model", "  transfer",
                                                                       "  solver setup", "  acceleration"};

struct FrameTiming {
  std::array<double, kNumStages> ms{};  // per stage
  std::array<double, kNumCutParts> cut_ms{};  // parts of ms[kStageCutting] (cut frames)
  double frame_ms = 0.0;                // whole frame, wall clock
  double cpu_ms = 0.0;                  // CPU time of the stepping thread in the frame (frame_ms - cpu_ms: time it waited or was preempted)
  bool cut_frame = false;               // the DOF set changed this frame (new symbolic analysis)
  bool cut_ahead = false;               // its layout and model were prepared during the previous frame
  int newton = 0;                       // linearised solves (Newton iterations) this frame
  // Linear solver of the frame (all Newton iterations together).
  int iterations = 0;         // CG iterations (lagged, warped_cg); 0 for direct policies
  int solves = 0;             // forward+back substitutions with a Cholesky factor
  double solve_kernel_ms = 0; // time inside those substitutions
  int takeovers = 0;          // their worker's bins the stepping thread did itself (CholmodSolver::set_substitution_worker)
  double residual = 0;        // last relative residual |A du - b| / |b| of CG (0 when direct)
  double start_residual = 1;  // CG's relative residual at its start (< 1: solver.initial_guess "previous" helped)
  bool converged = true;      // CG reached solver.tolerance within solver.max_iterations
  int rescues = 0;            // lagged: synchronous refactorizations after solver.rescue_after CG iterations
  int factor_age = 0;         // lagged: frames since the matrix of the preconditioning factor (last Newton iteration)
  int patch_dofs = 0;         // lagged after cuts: DOFs of the exactly solved patch (0: none)
  int tangent_updates = 0;    // elements whose tangent blocks were (re)computed (all but the kept ones: integrator.tangent_reuse)
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

}  // namespace incise
