#pragma once
// One fixed time step of the dynamics.
#include <vector>

#include "engine/model/model.h"
#include "engine/dynamics/state.h"

namespace incise {

// Newmark average acceleration (book eq. 3.58-3.61) with the projection
// constraints of Algorithm 1, newton_iterations linearised solves (1 by
// default). Advances state.time by model.dt. Throws incise::Error on a
// non-positive-definite system or a non-finite result (never lets NaN on).
void step(const Model& model, State& state);

// state.f_int = internal force at displacement x (rotations into state.R),
// and the tangent into state.K when asked. Returns the tangent's values: the
// rest stiffness for the linear model, state.K otherwise.
const double* internal_forces(const Model& model, State& state, const double* x, bool tangent,
                              bool reuse_tangent = false);

// Sets state.a to the acceleration consistent with the current u and v:
// M a = f_ext - f_int(u) - D v on the free DOFs (0 on constrained ones), by
// Jacobi-preconditioned CG on M (well conditioned: lumped or consistent).
// Needed after a cut: the old acceleration does not satisfy the new
// model's equations, and Newmark's trapezoidal update would turn that
// mismatch into an energy jump.
void consistent_acceleration(const Model& model, State& state);

// consistent_acceleration where a cut rebuild changed the equations: on the
// DOF nodes of the `changed` elements, their mesh nodes' other enriched DOF
// nodes (the lumped (u, q) blocks couple them), and nothing else; elsewhere
// state.a keeps its value. Needs only the forces of the elements around those
// nodes. Lumped mass only: with a consistent mass it is the global version.
void consistent_acceleration_near(const Model& model, State& state, const std::vector<int>& changed);

// Kinetic + elastic - gravity potential energy (for verification): for the
// linear model 1/2 v'Mv + 1/2 u'K0u - f'u.
double total_energy(const Model& model, const State& state);

// y = M x with the model's mass (lumped or consistent).
void mass_matvec(const Model& model, const double* x, double* y);

}  // namespace incise
