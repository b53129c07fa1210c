#pragma once
// The frozen, precomputed Model: everything that does not change between
// frames. A cut (later) builds the next Model version between frames; every
// stage is a function of (const Model&, State&).
//
// DOF layout: "DOF nodes" carry 3 DOFs each (dof = 3 * dofnode + component).
// The first nnode DOF nodes are the mesh nodes; enriched DOF nodes (X-FEM) are
// appended after them, so the DOF map can grow without renumbering.
//
// Element terms are integrated per quadrature point over an element's list of
// DOF nodes; each quadrature point uses one rotation slot. tet4: 1 point, 1
// rotation; tet10: 4 points, 4 rotations (per_point) or 1 rotation from the
// corner nodes (single, "tet10SR"). An X-FEM element will list standard and
// enriched DOF nodes, integrate over sub-element points, and give each side
// its own rotation slot, with no change to assembly.
#include <string>
#include <vector>

#include "engine/model/cut_layout.h"
#include "engine/mesh/mesh.h"
#include "engine/scene/scene.h"

namespace incise {

struct Model {
  Mesh mesh;                    // the element mesh (tet4 or tet10) the model was built from
  Material material;
  double mu = 0, lambda = 0;    // Lame parameters
  MassKind mass_kind = MassKind::Lumped;
  double dt = 1.0 / 30.0;
  int newton_iterations = 1;
  int max_newton_iterations = 4;    // adaptive cap (scene integrator.max_newton_iterations)
  double rotation_tolerance = 0.1;  // radians; 0 = fixed iteration count
  double rotation_fraction = 1e-4;  // integrator.rotation_fraction: volume fraction allowed past rotation_tolerance
  double rotation_rms = 0.02;       // integrator.rotation_rms: radians, volume-weighted RMS; 0 = off
  bool line_search = false;         // integrator.line_search: halve an iteration that raised the residual
  double residual_tolerance = 0.0;  // integrator.residual_tolerance: also iterate while the relative residual is above it
  double newmark_gamma = 0.5, newmark_beta = 0.25;  // 1/2, 1/4: trapezoidal rule
  bool recovery_steps = true;       // integrator.recovery "backward_euler" (true) or "none": State::recovery's steps
  bool consistent_tangent = false;  // integrator.tangent: add the rotation term (engine/fem/rotation_stiffness.h)
  bool increment_predictor = false;  // integrator.predictor "increment": Newton starts from State::du, not dt v
  double tangent_reuse = 0.0;       // integrator.tangent_reuse: F change below which element tangents are kept
  double cut_stabilization = 0.1;   // scene cut_stabilization: weight of a small piece's extension points (qp_extension)
  SolverSettings solver;        // solver.* of the scene: policy, CG tolerance, threads

  // DOF nodes
  int nnode = 0;                // standard DOF nodes (= mesh nodes)
  int ndofnode = 0;             // all DOF nodes (standard + enriched)
  // Newton iterates past newton_iterations while rotations move more than
  // rotation_tolerance over more than rotation_fraction of the body, or by
  // more than rotation_rms in the mean (decide_newton, engine/dynamics/step.cpp).
  bool adaptive_newton() const {
    return material.model == MaterialModel::Corotated && (rotation_tolerance > 0 || residual_tolerance > 0) &&
           max_newton_iterations > newton_iterations;
  }
  int ndof() const { return 3 * ndofnode; }
  std::vector<double> X;        // (ndofnode, 3) reference positions; 0 for enriched DOF nodes
  double body_length = 0.0;     // diagonal of the mesh nodes' bounding box (the run-away stop's scale, step.h)

  // Elements (assembly units)
  int nelem = 0;
  std::vector<int> elem_dof_ptr;   // (nelem + 1) into elem_dof_node
  std::vector<int> elem_dof_node;  // DOF nodes of each element
  std::vector<int> elem_qp_ptr;    // (nelem + 1) quadrature points of each element
  std::vector<double> elem_volume; // (nelem) reference volume
  std::vector<unsigned char> tet_face_boundary;  // (nelem, 4) face opposite corner k is on the mesh boundary
  // Mesh topology (cuts never change it; a rebuild copies it): the interior
  // faces as pairs (e, k, f, l), face k of element e is face l of f, in the
  // order of their sorted corners; and each mesh node's elements.
  std::vector<int> tet_face_pair;  // (npairs, 4)
  std::vector<int> node_elem_ptr;  // (nnode + 1) into node_elem
  std::vector<int> node_elem;      // elements of each mesh node, ascending

  // Quadrature points
  std::vector<double> qp_weight;   // (nqp) cubature weight * det J: the volume it stands for
  std::vector<int> qp_grad_ptr;    // (nqp + 1) into qp_grad, 3 * (element's DOF nodes) each
  std::vector<double> qp_grad;     // dN_a/dX of the element's DOF nodes at the point
  std::vector<int> qp_rot;         // (nqp) rotation slot used by the point
  // (nqp) 1: an extension point of a small piece (its field over the whole
  // element, a small weight; model_build.cpp add_piece_extension): in the
  // energy, forces and stiffness, not in the piece's volume.
  std::vector<unsigned char> qp_extension;

  // Rotation slots: F = sum_a (X_a + u_a) (x) rot_grad_a (computed as I + sum_a u_a (x) rot_grad_a), R its rotation
  int nrot = 0;
  std::vector<int> rot_elem;       // (nrot) element of the slot
  std::vector<int> rot_grad_ptr;   // (nrot + 1) into rot_grad
  std::vector<double> rot_grad;    // gradients giving the slot's deformation gradient
  // The body (connected piece of tissue, CutLayout::piece_body) of each slot,
  // so Newton's stop can judge a severed piece by its own volume
  // (decide_newton). Empty while the tissue is one body.
  int nbody = 1;
  std::vector<int> rot_body;       // (nrot) 0..nbody-1
  // Rest stiffness of the points of a shared slot (a piece of a split element):
  // with one rotation R for all of them, their force is R^ K0 (R^T x - X) and
  // their frozen-R tangent R^ K0 R^T (R^ = diag(R, ...)), so assembly rotates
  // this matrix instead of integrating the piece's many sub-element points.
  // Two forms. Over d: a piece displaces its mesh node a by d_a = u_a + q_a
  // (q_a: the piece's enriched DOF node at a, if any; [preprint] eq. (66)),
  // so K0 is kept over the npe mesh nodes in d and spread onto the element's
  // u and q at assembly (a quarter of the blocks of the same matrix over all
  // the DOF nodes); the partner list names q_a's local index. Over all the
  // element's n DOF nodes, in its order (partner list all -1): a piece of an
  // element with branch DOF nodes (front enrichment), whose N_a (F - F_a)
  // gradients do not fold onto d.
  std::vector<int> rot_K0_ptr;     // (nrot + 1) into rot_K0; an empty range: the slot's points are integrated
  std::vector<double> rot_K0;      // per condensed slot: blocks (a <= b) x 9, row-major, over its k nodes
  std::vector<int> rot_K0_partner_ptr;  // (nrot + 1) into rot_K0_partner: k entries per condensed slot
  std::vector<int> rot_K0_partner; // per condensed slot, (k): local DOF-node index of q_a, -1 where none
  const int* slot_partner(int r) const { return &rot_K0_partner[rot_K0_partner_ptr[r]]; }
  int slot_K0_nodes(int r) const { return rot_K0_partner_ptr[r + 1] - rot_K0_partner_ptr[r]; }  // k of slot r

  // Global sparse pattern: upper triangle, compressed columns, ndof x ndof
  std::vector<int> Ap;             // (ndof + 1) column starts
  std::vector<int> Ai;             // (nnz) row ids, sorted within a column
  std::vector<int> diag;           // (ndof) position of each diagonal entry
  std::vector<int> elem_scatter_ptr;  // (nelem + 1) into elem_scatter
  std::vector<int> elem_scatter;   // per element, blocks (a <= b) x 9: position in Ai, -1 = skip
  int nnz() const { return static_cast<int>(Ai.size()); }

  // X-FEM pieces (empty without cuts): see engine/model/cut_layout.h
  CutLayout cuts;
  bool has_cuts() const { return !cuts.elem_piece_ptr.empty(); }

  // Mass and loads
  std::vector<double> elem_mass;   // (nelem, npe, npe) rho int N_a N_b of each whole element: kept so a
                                   // cut rebuild integrates only the split elements
  std::vector<double> mass_lumped; // (ndof) lumped nodal masses (HRZ for tet10); the mass when mass_csc is empty
  std::vector<double> mass_csc;    // (nnz) the mass matrix in the pattern when not diagonal
                                   // (consistent, or lumped with enrichment)
  std::vector<int> mass_coupling;  // lumped with enrichment: positions in Ai of mass_csc's nonzeros off the
                                   // diagonal (the u-q couplings, all in enriched columns); with mass_lumped
                                   // as the diagonal they are the whole matrix (mass_matvec, form_matrix)
  std::vector<int> mass_coupling_col;  // the column of each
  std::vector<double> f_gravity;   // (ndof) M g: exact free fall for either mass
  double gravity[3] = {0.0, 0.0, 0.0};  // the scene's g (for failure messages)
  std::vector<double> K0_csc;      // (nnz) rest stiffness (R = I): filled for the linear model, the warped
                                   // policies and every model built without a base; a cut rebuild of
                                   // another corotated model leaves it empty (rest_stiffness() makes it)

  // Constraints ([book] Algorithm 1: projection keeps the pattern and SPD)
  std::vector<int> fixed_dofs;     // sorted, unique; constrained to 0
  struct PrescribedDof {
    int dof;
    double value;  // final displacement
    double ramp;   // seconds to reach it linearly, 0 = at once
  };
  std::vector<PrescribedDof> prescribed;
  std::vector<char> constrained;   // (ndof) 1 if fixed or prescribed
  std::vector<int> constrained_entries;  // positions in Ai of entries in a constrained row or column, diagonal excluded

  double prescribed_value(const PrescribedDof& p, double time) const {
    return (p.ramp > 0 && time < p.ramp) ? p.value * time / p.ramp : p.value;
  }
  // Its time derivative: the right limit at the end of the ramp, which a time
  // summed from steps (k dt) reaches within roundoff.
  double prescribed_velocity(const PrescribedDof& p, double time) const {
    return (p.ramp > 0 && time < p.ramp * (1.0 - 1e-9)) ? p.value / p.ramp : 0.0;
  }
};

// Newmark's update ([book] eq. (3.58) for beta = 1/4, gamma = 1/2, in general
// form) in terms of the step's increment Delta = u1 - u:
//   a1 = a_d Delta + a_v v + a_a a,   v1 = v_d Delta + v_v v + v_a a,
// and the dynamic matrix A = cM M + cK K with Rayleigh damping D = a M + b K
// ([book] eq. (3.59) in general form): cM = 1/(beta dt^2) + a gamma/(beta dt),
// cK = 1 + b gamma/(beta dt).
struct NewmarkCoefficients {
  double a_d, a_v, a_a, v_d, v_v, v_a, cM, cK;
};
// `recovery`: a recovery step's (State::recovery): backward Euler, written
// in the same form (a_a = v_a = 0: the carried acceleration is not used).
NewmarkCoefficients newmark_coefficients(const Model& model, bool recovery = false);

// Builds the Model from a mesh (tet4 or tet10, checked) and the scene's
// material, mass, constraints and loads. order 2 raises a tet4 mesh. With a
// cut layout (from cutting/, computed on the uncut model of the same mesh and
// scene) cut elements are integrated per piece with enriched DOF nodes.
// With `base` (a model of the same mesh and scene, e.g. the one before a cut)
// the tet10 mesh, boundary faces and per-element masses are copied from it, so
// a cut rebuild integrates only what the cut changed (docs/numerics.md).
// `spare`: a model no longer needed (the one the cut before last replaced),
// whose large arrays the new model takes, emptied, for their storage: their
// pages are in use already, where new ones would each fault on first touch.
Model build_model(const Mesh& mesh, const Scene& scene, const CutLayout* cuts = nullptr, const Model* base = nullptr,
                  Model* spare = nullptr);

// Whether element e has the same pieces in m as in base (a model of the same
// mesh; no cuts = one whole piece): enrichment up to renumbering, split flag
// and sub-tetrahedra. build_model copies such elements' integration data.
bool same_element_pieces(const Model& m, const Model& base, int e);
// Whether element e has as many pieces in m as in base (none = one whole
// piece) with the same (piece, node) pairs sharing an enriched DOF node (ids
// may differ): the same Heaviside space on it, whatever its sub-tetrahedra
// and branch DOFs.
bool same_piece_regions(const Model& m, const Model& base, int e);

std::vector<int> element_slot_ptr(const Model& m);  // (nelem + 1) first rotation slot of each element
// The cube root of the mean element volume (an element size for reaches and tolerances).
double mean_element_size(const Model& m);

// The gravity load of static solves (ndof): f_gravity, with the consistent
// load rho g int N_a on the Heaviside-enriched DOF nodes of a lumped-mass
// model where their node's function nearly vanishes in their region: rho
// int N_a^2 there below kSliverMass of frac * rho int_e N_a^2 (the
// definition explains why).
inline constexpr double kSliverMass = 1e-6;
std::vector<double> static_gravity_load(const Model& model);

// The rest stiffness K0 (R = I) in the model's pattern, (nnz).
std::vector<double> rest_stiffness(const Model& model);
// Whether stepping uses K0: the linear model and the warped policies.
bool model_needs_rest_stiffness(const Model& model);

// Nodes selected by a region (tolerance 1e-9 of the mesh's bounding-box
// diagonal). Throws naming the region's JSON path when it selects no node or a
// node id is out of range.
std::vector<int> select_nodes(const Mesh& mesh, const Region& region, const std::string& scene_path);

}  // namespace incise
