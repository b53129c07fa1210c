#pragma once
// The contact stage of the step: after each solve, the increment Delta is
// corrected so the frame ends with the constraints of ws.contacts met
// (engine/dynamics/contact_rows.h): contacts without penetration, grasped
// points on the jaws, Coulomb friction when asked.
//
// Constraint-based response with the compliance from the frame's factor
// (Courtecuisse et al., "Real-time simulation of contact and cutting of
// heterogeneous soft-tissues", Med. Image Anal. 18(2), 2014, sec. 3): with
// the free increment Delta_f (the solve's, which already includes the force
// H^T lambda of earlier Newton iterations of the step),
//   Delta = Delta_f + A^-1 H^T (lambda - lambda_old),
//   W = H A^-1 H^T  (the contact compliance, nrow x nrow),
// and lambda solves the mixed LCP
//   W lambda - b >= 0, lambda >= 0, complementary   (contacts)
//   W lambda - b  = 0                               (grasps)
//   |lambda_t| <= mu lambda_n, sticking or sliding   (friction)
// with b = target - H Delta_f + W lambda_old, by projected Gauss-Seidel. A^-1
// is the policy's own (apply_factor_inverse: the exact factor, or the lagged
// preconditioner): the correction then meets H Delta = target exactly, and
// equilibrium holds to the preconditioner's accuracy, which the next Newton
// iteration (lambda H^T stays in its residual) or frame corrects, or the
// refinement below removes.
#include "engine/dynamics/state.h"
#include "engine/model/model.h"
#include "engine/solve/workspace.h"

namespace incise {

// At the start of a step: lambda and the contact force for the frame's rows
// (none: contact_force emptied, so assembly adds nothing). Zero, except
// under the iterative policies for a row whose key (ContactRows::key: a
// grasp's held point and axis, a contact's tool, face and part) was one of
// the last frame's rows: it starts from that row's multiplier, and the force
// goes into the first Newton iteration's residual, so the contact correction
// through the preconditioner's compliance is only the frame's change.
// Measured on drag15mm-20k (realtime preset): the grasp frames' Newton
// iterations 3-4 -> 1-2, the error against `exact` at frame 20 1.0e-1 ->
// 1.9e-2 (docs/benchmarks.md).
void begin_contacts(const Model& model, const State& state, Workspace& ws);

// The stage: lambda, the corrected ws.delta and ws.contact_force = H^T lambda.
// Records rows, sweeps and the total force in ws.timing.
//
// contact.refine_rounds > 0 (the iterative policies): Y dlambda is the preconditioner's A^-1 H^T dlambda, so the rows
// hold but the contact force is out of equilibrium by the preconditioner's
// error. The LCP's active rows (contacts pushing, grasps, friction sticking)
// are then held exactly while a projected CG puts the rest into
// equilibrium: du minimises the iteration's quadratic model over
// H_A du = target_A (constrained_refine, the constraint preconditioner built
// from Y and W), and the multipliers come out of its residual, as exact's
// would. A result that leaves the LCP's feasible set (a contact pulling,
// friction off its cone, an inactive contact pressed in) goes through the
// LCP again (a round), at most refine_rounds times; the last LCP's Y dlambda
// stands. A tool held through a spring (the haptic probe: its rows yield by
// c_t d_i . d_j lambda_j) brings its displacement w_t as three more
// unknowns with stiffness 1/c_t, constrained with the tissue
// (H_i du + d_i . w_t = target_i), so W_c is the constraint preconditioner's
// compliance. Every Newton iteration, not only the last: the later iterations
// then linearise where exact's do (refining only the last one left the
// probe scene's error at frame 30 at 2.3e-1 against 1.2e-1, 1.8e-1 without;
// docs/benchmarks.md).
void solve_contacts(const Model& model, State& state, Workspace& ws);

// In the integration stage, after the Newmark update: the rows active at the
// end of the step (contacts pushing, grasps, friction sticking) get the
// velocity of the tool they touch and no acceleration along them, by the
// change of least kinetic energy: with Z = M^-1 H_A^T and G = H_A Z,
// v += Z G^-1 (v_tool - H_A v), a += Z G^-1 (-H_A a) (a lumped mass; for a
// consistent one, Z = the contact stage's A^-1 H_A^T stands in for M^-1).
// Without it the trapezoidal rule integrates the impulsive correction as
// v1 = 2/dt Delta - v, a sawtooth that never decays at a held contact (the
// prescribed DOFs get the same treatment in integrate()).
void project_contact_kinematics(const Model& model, State& state, Workspace& ws);

}  // namespace incise
