#pragma once
// Corotated element terms and their assembly into the global pattern.
//
// Per quadrature point q of weight w with gradients g_a and rotation R
// ([book] eqs. (3.64)-(3.66), (A.45)-(A.52); [preprint] eq. (66) for enriched DOF nodes):
//   F     = sum_a (X_a + u_a) (x) g_a
//   eps'  = sym(R^T F) - I,  sig' = 2 mu eps' + lambda tr(eps') I
//   f_a  += w R sig' g_a
//   K_ab += w (lambda h_a h_b^T + mu h_b h_a^T + mu (g_a . g_b) I),  h = R g
// The last line is R K0_ab R^T of the isotropic linear stiffness (eq. 3.42)
// written with rotated gradients, which is cheaper than rotating K0 blocks.
// Where R is the point's own polar factor, the tangent also gets the rotation
// (dR/dF) term, projected to be positive semi-definite (rotation_stiffness.h).
// The linear model is the same with R = I.
#include <vector>

#include "engine/model/model.h"

namespace incise {

// R (nrot, 9) column-major 3x3 per slot: warm start in, rotations out.
// Linear material: identity. Returns the number of SVD fallbacks (inversions
// or extreme deformations) so callers can report them.
int update_rotations(const Model& model, const double* u /* (ndof) */, double* R);
// The same for slots [r_begin, r_end) only (one worker's share).
int update_rotations(const Model& model, const double* u, double* R, int r_begin, int r_end);

// (nqp) 1 where a point's rotation slot serves that point alone, so its R is
// the polar factor of the point's own F and the tangent gets the rotation
// term of rotation_stiffness.h; per-element and per-piece slots keep the
// frozen-R tangent. All 0 for the linear model and unless the scene asks for
// integrator.tangent "consistent".
std::vector<char> point_rotation_flags(const Model& model);

// (nrot) total cubature weight of each rotation slot that several points
// share (per element or per cut piece), which gets the slot form of the
// rotation term (add_slot_rotation_stiffness); 0 for a point's own slot, and
// all 0 under the same conditions as point_rotation_flags.
std::vector<double> shared_slot_weights(const Model& model);
// The same with the rotation term asked for explicitly (the static solve
// always takes it, whatever integrator.tangent says).
std::vector<char> point_rotation_flags(const Model& model, bool consistent);
std::vector<double> shared_slot_weights(const Model& model, bool consistent);

// f_int (ndof) = internal elastic force at u with rotations R; K (nnz) = the
// corotated tangent in the pattern (skipped when K is null). Both are
// overwritten.
void assemble_internal(const Model& model, const double* u, const double* R, double* f_int, double* K);

// y = A x for a symmetric matrix stored as the pattern's upper triangle.
void sym_matvec(const Model& model, const double* A /* (nnz) */, const double* x, double* y);

// Von Mises stress of each element (nelem), the volume average of its points'
// corotated Cauchy stress.
void element_von_mises(const Model& model, const double* u, const double* R, double* vm);

}  // namespace incise

namespace incise {
// Elastic energy sum_q w (mu eps':eps' + lambda/2 tr(eps')^2) at u with rotations R.
double elastic_energy(const Model& model, const double* u, const double* R);
}  // namespace incise
