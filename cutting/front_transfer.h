#pragma once
// Carrying a state across a rebuild near cut fronts with branch functions
// (cut_front "enriched", engine/model/cut_layout.h node_branch): the part of
// transfer_kinematics (cut_apply.h) the nodal transfer cannot do exactly.
#include "cutting/cut_apply.h"
#include "engine/model/model.h"

namespace incise {

// Near enriched fronts, old or new, the new model's DOFs by a local
// projection of the old field (after the nodal transfer, which is exact
// elsewhere), over the elements S holding a branch DOF node in either model,
// for the DOF nodes (standard, enriched, branch) of the mesh nodes whose
// elements all lie in S; the nodes on S's boundary keep their nodal values,
// which the old field takes there exactly (its branch part vanishes outside
// S), so the field stays continuous:
//   u:         min 1/2 int_S eps(e) : C : eps(e) + beta (lambda + 2 mu) |e|^2,
//              e = u_new - u_old  (the energy norm: 3 x 3 blocks)
//   v, a, du:  min int_S |f_new - f_old|^2  (L2, one scalar system)
// beta = 1e-2 / h^2 (h: the cube root of S's mean element volume) makes the
// problem definite where S holds a whole free piece.
// Where S keeps its sub-tetrahedra and fronts (another cut's rebuild) the
// DOFs copy over one by one, exactly (same_fronts); face-snapped ->
// enriched at the same front is the nodal transfer with the branch DOFs at
// 0, exactly (fronts_only_added: the new space contains the old; the
// projection cost 1.4 s on organ_10k). The velocity's correction (and a's
// and du's with it) is scaled back where it would raise the kinetic energy
// (with the model's lumped mass) over the old model's: sliver DOFs near a
// node layer are near-null in L2 but not in the lumped mass. Otherwise the old sqrt(r) is not in the new space and this is
// its best fit: a second cut through an enriched slit's front elements
// (which takes that front to faces) changed the energy by 0.21 of the
// gravity work, against 2.6 before (branch DOFs dropped by node, 4-point
// rule; 1.7 by node with the 27-point rule; FrontEnrichment.ASecondCut...).
// Points: branch_cubature on every sub-tetrahedron of the new pieces; the
// old piece is looked up once per sub-tetrahedron (new pieces lie inside
// old ones: cuts only grow); the branch functions take the sign of phi at
// each point, as the model's gradients do (a sub-tetrahedron ahead of the
// front may straddle the plane: 18 of 861 in the slit of the tests).
// os: the old state; nf: the fields carried (u, v, a, and du when 4); ns
// holds the nodal transfer on entry and the projection on return.
void project_near_fronts(const Model& from, const State& os, const Model& to, int nf, Kinematics& ns);

}  // namespace incise
