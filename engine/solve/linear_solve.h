#pragma once
// The linear solve of a Newton iteration, A du = rhs with A = 4/dt^2 M +
// 2/dt D + K (projected), under the scene's solver.policy:
//
//   exact      numeric refactorization of the current A every iteration (reference)
//   lagged     CG on the current A, preconditioned by the factor of an earlier
//              frame's A: refreshed every solver.refresh_every frames, either
//              in the step (synchronously) or, with solver.background, on a
//              second thread whose factor is taken refresh_every frames after
//              it was started (deterministic: replays give the same states);
//              a cut keeps the factors (mapped onto the grown DOF set) and
//              moves the new symbolic analysis into the next refresh
//   warped     the factor of the REST matrix A0 = 4/dt^2 M + 2/dt D0 + K0
//              with per-node rotations around the solve: du = Rn A0^-1 Rn^T rhs
//              (exact when the mass is lumped and every element has the same
//              rotation; no tangent is assembled)
//   warped_cg  CG on the current A preconditioned by the warped solve
//
// Iterations, substitutions, the final CG residual and convergence go into
// Workspace::timing, so no policy is silent about what it did.
#include <functional>
#include <vector>

#include "engine/dynamics/state.h"
#include "engine/model/model.h"
#include "engine/runtime/timing.h"
#include "engine/solve/workspace.h"

namespace incise {

// Worker pool, assembly plan, factor configuration and symbolic analysis, node
// rotation adjacency. Called by init_state; call again after the Model changes
// (a cut) before the next step; `frame` is the State's. Invalidates the
// factor, except where solver_carries_over_cuts() and the cut passes
// `dofnode_map` (new DOF node -> old DOF node, -1 for a new one): then no
// analysis or factorization runs in the cut frame; the lagged factors keep
// preconditioning through the map (an exact solve on a patch around the DOFs
// they do not know) and the next background job (or synchronous refresh)
// analyzes and factorizes the new pattern.
// `plan`: make_assembly_plan(model, ws.runtime.threads) made ahead (a cut's
// helper thread), taken instead of making one here.
void prepare_solver(const Model& model, Workspace& ws, int frame, const std::vector<int>* dofnode_map = nullptr,
                    AssemblyPlan* plan = nullptr);

// The lagged policy with a valid factor: a cut keeps it (see prepare_solver).
bool solver_carries_over_cuts(const Model& model, const Workspace& ws);

// Whether the policy needs the assembled corotated tangent K (warped does not).
bool policy_needs_tangent(const Model& model);

// The policy's three parts of a Newton iteration, one per stage of the step
// (engine/dynamics/step.cpp):
// assembly:      ws.A = cM M + cK K ([book] eq. (3.59) in general form), projected
//                (Algorithm 1), and the warped policies' node rotations; K is
//                the tangent in the pattern (K0 for the linear model; may be
//                null for warped);
// factorization: the factor the solve needs now (exact: of A; lagged: the
//                refresh policy, its warp and patch, or a rescue; warped: of
//                the rest matrix, once);
// solve:         ws.du = A^-1 ws.rhs (substitution or CG). Lagged may instead
//                set ws.rescue_pending: the factorization and solve stages
//                then run again.
// Iterations, substitutions, residuals and rescues go into ws.timing.
void form_dynamic_matrix(const Model& model, const State& state, Workspace& ws, const double* K);
// Whether the factorization stage has work this iteration: not when the
// factor in hand serves (the linear model's, factored once; the warped
// policies' rest factor). The step skips the stage then, so a linear scene
// shows one factorization run in all.
bool factorization_due(const Model& model, const Workspace& ws);
void factorize_for_policy(const Model& model, const State& state, Workspace& ws);
void solve_for_policy(const Model& model, Workspace& ws);

// x ~= A^-1 b through the factor the policy solved with this iteration: the
// exact factor of A; lagged: the preconditioner (the older factor, warped,
// with its patch); warped and warped_cg: the warped rest factor. The contact
// stage builds its compliance W = H A^-1 H^T with it (Courtecuisse et al.'s
// compliance from the preconditioner). Call after the solve stage.
void apply_factor_inverse(const Model& model, Workspace& ws, const double* b, double* x);
// The same for k columns at once (B, X: ndof x k column-major, may alias):
// one read of the factor for all of them where it applies whole (exact,
// warped, lagged before a cut maps it), column by column otherwise.
void apply_factor_inverse_multi(const Model& model, Workspace& ws, int k, const double* B, double* X);
// The compliance of k columns B (ndof x k, zero outside the DOFs nz, which
// hold every DOF of their nodes, node by node: 3a, 3a+1, 3a+2) without their
// solves: W = B^T P^-1 B (k x k) and Z (|rows| x k), from the forward half of
// the preconditioner's substitution over the factor's tree paths from the
// columns' DOFs (CholmodSolver::forward_half_multi). Under lagged, where
// the columns lie on DOFs the front factor maps and off a cut's patch
// (there P^-1's patch steps leave them alone): W = Z^T Z with Z the forward
// half of Q^T B. Columns on the condensed set S (condensed_dofs.h) enter
// the factor as B - A Q B, nonzero on S's neighbours, which must then be
// mapped and off the patch as well: W = B^T Q B + Z^T Z. False otherwise
// (other policies, a simplicial factor), Z and W untouched.
bool factor_compliance(const Model& model, Workspace& ws, int k, const double* B, const std::vector<int>& nz,
                       std::vector<int>& rows, std::vector<double>& Z, std::vector<double>& W);
// x = P^-1 B c from Z c (z: |rows|, on factor_compliance's rows) and c (k):
// its Z, B and factor. The backward half alone, one read of the factor
// where a solve of B c reads it twice; then the patch's last step and the
// condensed projection, which do move the patch's and S's DOFs, and Q B c
// for columns on S.
void factor_compliance_apply(const Model& model, Workspace& ws, const std::vector<int>& rows, const double* z,
                             const double* c, double* x);

// The projection onto the constraints H_A x = 0 of the contact stage's
// active rows (engine/dynamics/contact_solve.cpp). project(r, z,
// precondition) removes H_A^T mu from the residual r (mu = W^-1 Y^T r: the
// multipliers that make r - H_A^T mu smallest in P^-1's norm, W = H_A Y,
// Y = P^-1 H_A^T), adds mu to what it has removed so far, and sets z to
// Pi P^-1 of the projected r (Pi = I - Y W^-1 H_A: z in the null space),
// with precondition(y, out) applying P^-1. Y's columns kept from an earlier
// preconditioner (a frame's later Newton iterations) are used as they are:
// Y^T r from them, then P^-1, then z's projection along them. Y from the
// factor's halves, formed with the preconditioner as it is, takes P^-1 r
// first: Y^T r = H_A P^-1 r and P^-1 of the projected r is P^-1 r - Y mu,
// already in the null space (one P^-1 and one Y mu an iteration).
struct ConstraintProjection {
  virtual void project(double* r, double* z, const std::function<void(const double*, double*)>& precondition) = 0;

 protected:
  ~ConstraintProjection() = default;
};

// x = argmin of 1/2 x^T A x - b^T x over x0 + null(H_A), from the feasible x0
// given in x, for the iterative policies (lagged, warped_cg): projected
// preconditioned CG (Gould, Hribar & Nocedal, SIAM J. Sci. Comput. 23(4),
// 2001; the residual re-projected every iteration, as their residual
// update strategy does) with the constraint preconditioner
// z = Pi P^-1 Pi^T r, Pi = I - Y W^-1 H_A:
// every iterate meets the rows exactly, and at convergence b - A x =
// H_A^T mu (the multipliers project() removed). Stops when |Pi^T r| <= tol |b|,
// or after solver.max_iterations (and what is left of
// solver.frame_iterations); iterations count in ws.timing.iterations, the
// Newton solve's residual and convergence in ws.timing are kept. False
// (x untouched) for the direct policies or with no iteration left.
//
// k_extra: unknowns appended after the ndof DOFs, each with its own diagonal
// stiffness (no coupling to the DOFs but through the constraints): the
// contact stage's spring-coupled tools (their displacement along the
// spring). b and x then have ndof + k_extra.size() entries; their block of
// the preconditioner is 1 / k.
bool constrained_refine(const Model& model, Workspace& ws, const double* b, double* x, ConstraintProjection& proj,
                        const std::vector<double>& k_extra = {});

// Whether the policy solves by CG on the current A (lagged, warped_cg).
bool iterative_policy(const Model& model);

// Node rotations of the warped policies from the slot rotations R (nrot, 9):
// the polar rotation of the volume-weighted sum of the incident slots' R;
// identity on nodes with some but not all components constrained.
void update_node_rotations(const Model& model, const double* R, Workspace& ws);

}  // namespace incise
