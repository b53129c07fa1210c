#pragma once
// The solver Workspace a simulation owns beside its State: work arrays sized
// once, the factorization(s) and their threads (SolverWork), the tangent
// cache, the Newton loop's progress and the last frame's timings. Nothing in
// it is physical state: a copied State stepped with a fresh Workspace gives
// the same frames under a deterministic solver (`exact`); under the
// iterative policies the lagged factor, CG's start and the carried contact
// multipliers are history that shapes a frame within the CG tolerance
// (docs/architecture.md). A cut carries it over to
// the next Model in carry_workspace_over_cut (engine/solve/workspace_carry.h).
#include <cstdint>
#include <vector>

#include "engine/dynamics/contact_rows.h"
#include "engine/fem/assemble_parallel.h"
#include "engine/runtime/timing.h"
#include "engine/scene/scene.h"
#include "engine/solve/cholmod_solver.h"
#include "engine/solve/solver_work.h"

namespace incise {

struct Model;

struct Workspace {
  // Work arrays (ndof or nnz), reused every frame.
  std::vector<double> f_int;             // (ndof) internal force at the current iterate
  std::vector<double> K;                 // (nnz) tangent stiffness
  std::vector<double> A;                 // (nnz) dynamic matrix cM M + cK K, projected
  // solver.matrix_precision "single": A rounded to float for CG's products
  // (nnz), made from the A of stamp A_single_stamp (none yet: the largest
  // value, never a stamp); A_stamp counts the times form_matrix_once formed
  // A, A_products the products with it so far.
  std::vector<float> A_single;
  std::uint64_t A_stamp = 0, A_single_stamp = ~std::uint64_t{0};
  int A_products = 0;
  // What A was formed from, so an unchanged K (tangent_reuse keeping every
  // element, or the linear model's K0) is not formed again: K_generation
  // grows whenever ws.K may change (an assembly that recomputed a block, a
  // new or carried model), A_generation is K_generation when A was formed
  // from A_source (0: A holds something else, e.g. the static solve's K).
  std::uint64_t K_generation = 1, A_generation = 0;
  const double* A_source = nullptr;
  std::vector<double> rhs, du;           // (ndof) Newton residual and increment
  std::vector<double> delta;             // (ndof) step increment Delta = u(t + dt) - u(t)
  std::vector<double> tmp, tmp2;         // (ndof) scratch
  std::vector<double> f_damp;            // (ndof) R K0 R^T v1 of the iterate (the Rayleigh stiffness force / b)
  TangentCache tangent_cache;   // integrator.tangent_reuse: element blocks kept in K between frames
  CholmodSolver solver;
  bool factor_current = false;  // the factor in `solver` is valid for the policy (linear: never changes)
  SolverWork work;              // policies, worker pool, assembly plan (engine/solve/linear_solve.h)
  RuntimeSettings runtime;      // threads, CPUs, priorities (the scene's; set before init_state)

  // The Newton loop of the step in progress (engine/dynamics/step.cpp).
  int newton_iterations_done = 0;  // linearised solves done so far in this step (all of them after it)
  bool newton_done = false;      // set by the solve stage: no further iteration
  // This step takes the recovery coefficients (State::recovery at its start;
  // newmark_coefficients(m, true)); A_recovery: the coefficients ws.A holds.
  bool recovery = false, A_recovery = false;
  bool rescue_pending = false;   // lagged: the solve stage asks the factorization stage for a rescue factor

  // Contact and grasp constraints of the coming frame (collision/ fills
  // them before the step; the contact stage solves them) and the force they
  // put on the DOFs, H^T lambda (ndof; empty while there are none).
  ContactRows contacts;
  std::vector<double> contact_force;
  std::vector<double> contact_work;  // (nrow, ndof) A^-1 H^T columns, reused
  std::vector<double> contact_W;     // (nrow, nrow) the compliance H A^-1 H^T of the last solve
  std::vector<double> contact_Wc;    // (nrow, nrow) the same plus the tools' coupling springs (ContactRows::compliance)
  int contact_frame = -1;            // State::frame contact_W and contact_work were computed in
  // The multipliers the last contact stage ended with and its rows' keys
  // (ContactRows::key): the next frame's rows of the same keys start there.
  std::vector<double> contact_last_lambda;
  std::vector<long long> contact_last_key;
  // The rows (H: ptr, dof, coef, keys) and the lagged factor
  // (contact_factor_key) contact_work's Y = P^-1 H^T was computed for: a
  // later frame with the same factor and the same rows, or rows within
  // contact.compliance_reuse of them, takes Y over (contact_solve.cpp).
  std::vector<int> contact_Y_ptr, contact_Y_dof;
  std::vector<double> contact_Y_coef;
  std::vector<long long> contact_Y_rowkey;
  bool contact_W_of_Y = false;       // contact_W is H Y for Y's own rows (symmetrised), not a later frame's H
  long long contact_Y_key = -1;
  // contact_W from the forward half of the preconditioner (factor_compliance):
  // no Y; each LCP round's correction (and the refinement's Y mu) is the
  // backward half of Z dlambda.
  bool contact_half = false;
  std::vector<int> contact_nz, contact_zrows;  // every DOF of the rows' nodes; Z's rows
  std::vector<char> contact_node_mark;         // (ndofnode) scratch for contact_nz
  std::vector<double> contact_zhalf;           // (|contact_zrows|, nrow) Z
  std::vector<double> contact_g, contact_gy;   // (|contact_zrows|) Z dlambda; (ndof) its backward half
  std::vector<double> contact_dl;              // (nrow) dlambda of that product
  std::vector<double> contact_Z;     // (nrow, ndof) project_contact_kinematics' columns (Y stays in contact_work)
  std::vector<double> contact_h;     // (ndof, active rows) the contact kinematics' H^T columns (project_contact_kinematics)
  // (ndof) the contact refinement's Delta before the iteration's solve, residual
  // without the contact force, right-hand side and increment.
  std::vector<double> contact_base, contact_rhs, contact_b, contact_x;
  double contact_scale = 0.0;        // the largest |b_i| of the iteration's first LCP (a displacement)

  FrameTiming timing;           // the last (or current) frame
  // late_factor "skip": whether a finished background factor is taken is the
  // clock's choice (engine/solve/linear_solve.cpp, lagged_refresh), recorded
  // in timing.late_factor_call. A replay (tools/cmd_replay.cpp) imposes the
  // recorded choice before each frame instead: the lagged refresh call of the
  // frame (0, 1, ...) that takes it, -1 none; kClockDecides: the clock.
  static constexpr int kClockDecides = -2;
  int imposed_late_factor_call = kClockDecides;
  int refresh_frame = -1, refresh_calls = 0;  // lagged refresh calls in frame refresh_frame
  int refactorizations = 0;     // numeric factorizations so far
  int rotation_fallbacks = 0;   // SVD fallbacks in the last frame (inverted points)
  double last_residual = 0.0;      // relative residual of the last Newton iteration
  // integrator.line_search: the last accepted iterate (Delta, the contact
  // multipliers and force) and its residual norm |r|, to take the next one
  // back halfway when its residual is larger.
  double accepted_rnorm = 0.0;
  std::vector<double> accepted_delta, accepted_lambda, accepted_contact_force;

  // Factor slot k of the lagged policy, 0 <= k < SolverWork::kSlots (0 is `solver`).
  CholmodSolver& slot(int k) { return k == 0 ? solver : k == 1 ? work.back : work.spare; }
  const CholmodSolver& slot(int k) const { return k == 0 ? solver : k == 1 ? work.back : work.spare; }

  Workspace() = default;
  Workspace(const Workspace&) = delete;
  Workspace& operator=(const Workspace&) = delete;
  // `work` goes first: its background job may be factorizing `solver`, and a
  // substitution bin given up on may still read it on work's worker.
  ~Workspace() {
    work.wait_job();
    solver.set_substitution_worker(nullptr);
  }
};

// Sizes the work arrays for the model. zero = false only sizes them (a cut,
// whose step writes every work array and A before reading them; K is filled
// by the tangent carry or a full assembly): zeroing 8 MB at 10k DOF took
// 0.85 ms of each cut frame.
void size_workspace(const Model& model, Workspace& ws, bool zero = true);

}  // namespace incise
