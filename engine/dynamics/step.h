#pragma once
// One fixed time step of the dynamics, as stages (engine/runtime/timing.h):
//
//   do {                                   Newton iterations
//     assembly       forces, tangent, residual and A at x = u + Delta
//     do {
//       factorization  the factor the policy needs now (skipped when the
//                      one in hand serves: a linear model's, factored once)
//       solve          du = A^-1 r, Delta += du; whether Newton goes on
//     } while a lagged rescue asks for a fresh factor
//   } while the solve stage asks for another iteration
//   integration      Newmark update of u, v, a; constraints; time
//
// Newmark average acceleration ([book] eqs. (3.58)-(3.61)) with the projection
// constraints of [book] Algorithm 1. Each stage is one function of
// (const Model&, State&, Workspace&); step() runs them through run_stage,
// which times them (the pipeline, engine/runtime/pipeline.h, runs step_stages
// between its own stages).
#include <vector>

#include "engine/dynamics/state.h"
#include "engine/model/model.h"
#include "engine/solve/workspace.h"

namespace incise {

// Sizes the state and workspace, analyzes the pattern, sets time = frame = 0,
// u = v = 0, R = I and (when consistent_a0) the consistent initial
// acceleration a0 = M^-1 f_ext on the free DOFs; otherwise a = 0.
void init_state(const Model& model, State& state, Workspace& ws, bool consistent_a0 = true);

// A State made elsewhere (copied, restored from a file) on a Workspace:
// sizes the work arrays and prepares the solver for the model (checking the
// state's sizes against it; throws incise::Error naming the field). The next
// step factors afresh.
void attach_state(const Model& model, const State& state, Workspace& ws);

// One step: resets ws.timing, then step_stages. Advances state.time by
// model.dt. Throws incise::Error on a non-positive-definite system or a
// non-finite result (never lets NaN on).
void step(const Model& model, State& state, Workspace& ws);
// The stages of one step, booked into ws.timing (which it does not reset).
void step_stages(const Model& model, State& state, Workspace& ws);

// The stages (see the top of this file).
void assemble_system(const Model& model, State& state, Workspace& ws);
void factorize_system(const Model& model, State& state, Workspace& ws);
void solve_system(const Model& model, State& state, Workspace& ws);
void integrate(const Model& model, State& state, Workspace& ws);
// Motion that runs away without producing NaN is stopped as NaN is: no DOF
// may move faster than kDivergedSpeed body lengths (the diagonal of the mesh
// nodes' bounding box) a second. Throws NumericalError naming the DOF.
// integrate() calls it. The bound is far above anything physical because an
// enriched DOF of a sliver piece (mass ~1e-9 kg) legitimately jumps to
// hundreds of m/s while its cut opens (163 m/s measured on the 15 cm organ,
// 1000 lengths a second; its material points hardly move); a run-away one
// passes 1e4 m/s within a hundred frames and 1e20 later.
inline constexpr double kDivergedSpeed = 1e6;
void check_motion_bounded(const Model& model, const State& state);
// Whether the Newton loop goes on (ws.newton_done): the iteration count, and
// the rotation check on Delta (the solve stage calls it; with contact rows
// the contact stage does, on the corrected increment).
void decide_newton(const Model& model, State& state, Workspace& ws);

// ws.f_int = internal force at displacement x (rotations into state.R), and
// the tangent into ws.K when asked. With Kv (corotated model): Kv = R K0 R^T v
// with those rotations, in the same pass. Returns the tangent's values: the
// rest stiffness for the linear model, ws.K otherwise.
const double* internal_forces(const Model& model, State& state, Workspace& ws, const double* x, bool tangent,
                              bool reuse_tangent = false, const double* v = nullptr, double* Kv = nullptr);

// Sets state.a to the acceleration consistent with the current u and v:
// M a = f_ext - f_int(u) - D v on the free DOFs (0 on constrained ones), by
// Jacobi-preconditioned CG on M (well conditioned: lumped or consistent).
// Needed after a cut: the old acceleration does not satisfy the new
// model's equations, and Newmark's trapezoidal update would turn that
// mismatch into an energy jump.
// `contact_force` (ndof, or null): an external force held in the balance
// too (the instruments' force of the last frame, after a cut: without it a
// probe's region got the acceleration of tissue the probe let go).
void consistent_acceleration(const Model& model, State& state, Workspace& ws,
                             const std::vector<double>* contact_force = nullptr);

// consistent_acceleration where a cut rebuild changed the equations: on the
// DOF nodes of the `changed` elements, their mesh nodes' other enriched DOF
// nodes (the lumped (u, q) blocks couple them), and nothing else; elsewhere
// state.a keeps its value. Needs only the forces of the elements around those
// nodes. Lumped mass only: with a consistent mass it is the global version.
// Newmark's acceleration elsewhere carries the steps' Newton residual, which
// sums to ~0 over a body: right while the cut severs nothing (cut_apply.cpp
// resets the whole body's when it does).
void consistent_acceleration_near(const Model& model, State& state, Workspace& ws, const std::vector<int>& changed);

// Kinetic + elastic - gravity potential energy (for verification): for the
// linear model 1/2 v'Mv + 1/2 u'K0u - f'u.
double total_energy(const Model& model, const State& state);

// x = M^-1 r for a lumped mass (X-FEM couplings included, a direct solve per
// mesh node), 0 on constrained DOFs; returns false for a consistent mass.
bool lumped_mass_solve(const Model& model, const std::vector<double>& r, std::vector<double>& x);
// X = M^-1 B for k columns (ndof apart; X may not alias B), the same solve
// with the couplings found once for all of them (the contact kinematics'
// active rows); false for a consistent mass.
bool lumped_mass_solve_multi(const Model& model, int k, const double* B, double* X);

// y = M x with the model's mass (lumped or consistent).
void mass_matvec(const Model& model, const double* x, double* y);

// [book] Algorithm 1: zero the constrained rows and columns of A (nnz, in the
// model's pattern), unit diagonal. The pattern is unchanged and A stays SPD.
void project_constraints(const Model& model, double* A);

}  // namespace incise
