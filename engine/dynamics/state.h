#pragma once
// The mutable State of a simulation: kinematics, current rotations, work
// arrays sized once, the factorization, and the last frame's timings.
#include <vector>

#include "engine/fem/assemble_parallel.h"
#include "engine/solve/cholmod_solver.h"
#include "engine/model/model.h"
#include "engine/solve/solver_work.h"
#include "engine/runtime/timing.h"

namespace incise {

struct State {
  double time = 0.0;
  int frame = 0;
  std::vector<double> u, v, a;  // (ndof) displacement, velocity, acceleration
  std::vector<double> R;        // (nrot, 9) rotation of each slot, column-major

  // Work arrays (ndof or nnz), allocated by init_state, reused every frame.
  std::vector<double> f_int, K, A, rhs, delta, du, tmp, tmp2;
  TangentCache tangent_cache;   // integrator.tangent_reuse: element blocks kept in K between frames
  CholmodSolver solver;
  bool factor_current = false;  // the factor in `solver` is valid for the policy (linear: never changes)
  SolverWork work;              // policies, worker pool, assembly plan (engine/solve/linear_solve.h)

  FrameTiming timing;           // last frame
  int refactorizations = 0;     // numeric factorizations so far
  int rotation_fallbacks = 0;   // SVD fallbacks in the last frame (inverted points)
  double last_residual = 0.0;      // relative residual of the last Newton iteration
  int newton_iterations_done = 0;  // linearised solves in the last step

  State() = default;
  State(const State&) = delete;
  State& operator=(const State&) = delete;
  // `work` goes first: its background job may be factorizing `solver`, and a
  // substitution bin given up on may still read it on work's worker.
  ~State() {
    work.wait_job();
    solver.set_substitution_worker(nullptr);
  }
};

// Sizes the arrays, analyzes the pattern, sets u = v = 0 and (when
// consistent_a0) the consistent initial acceleration a0 = M^-1 f_ext on the
// free DOFs; otherwise a = 0 (the caller sets the kinematics, e.g. after a cut).
void init_state(const Model& model, State& state, bool consistent_a0 = true);

// Sizes the kinematics, rotations and work arrays for the model (all zero,
// rotations identity); no solver set-up. Used by init_state and by a cut
// that carries the solver over (engine/solve/linear_solve.h). With zero = false
// the arrays are only sized (what they held stays, new entries are 0): for
// a cut, which then sets u, v, a and R, and whose step writes every work
// array and A before reading them (K: the tangent carry or a full assembly
// fills it); zeroing 8 MB at 10k DOF took 0.85 ms of each cut frame.
void size_state(const Model& model, State& state, bool zero = true);

}  // namespace incise
