#pragma once
// lagged, solver.condense_below: the DOFs of mesh nodes next to a tiny cut
// piece are condensed out exactly every Newton iteration, and CG runs on the
// Schur complement of the rest.
//
// Why: CG stops at |r| <= tol |b| over the whole body, and a region of a
// node's support holding 1e-4 of its volume carries 1e-4 of the energy, so
// CG may leave its DOFs far off while the body converges. With the
// consistent tangent that error grew from frame to frame until the piece ran
// away (the issue-24 soak with the grasper; docs/benchmarks.md). A tiny
// region at node a moves with u_a (its home region) or u_a + q_r, so the
// weak direction lies in the span of node a's DOF nodes; all of them go
// into the condensed set S.
//
// The solve is deflated CG with W = the identity columns on S (Tang, Nabben,
// Vuik, Erlangga 2009, "A-DEF2"), which is CG on the Schur complement
// A_RR - A_RS A_SS^-1 A_SR: with Q v = A_SS^-1 v_S (on S, 0 elsewhere) and
// P^T = I - Q A,
//   x = Q b + y,  A y = b - A Q b by CG with preconditioner P^T M^-1 and a
//   start P^T y0:
// every residual is then zero on S, i.e. the condensed DOFs are in exact
// equilibrium with the rest at every CG iteration.
#include <cstddef>
#include <vector>

#include "engine/model/model.h"
#include "engine/solve/cholmod_solver.h"
#include "engine/solve/sparse_rows.h"

namespace incise {

struct CondensedDofs {
  std::vector<int> dof;         // (ns) the condensed DOFs, ascending
  std::vector<int> src;         // (nnz of A_SS) position in the model's A of each entry
  SparseRows rows;              // A's rows at S (every column)
  std::vector<double> A, v;     // A_SS values; work (ns, k columns)
  CholmodSolver factor;
  bool factored = false;
  bool empty() const { return dof.empty(); }
};

// The condensed set of m: every DOF node of each mesh node with a region of
// its support (the home region, or an enriched DOF node's) below `fraction`
// of the support's volume; none with fraction 0 or without cuts. Analyzes A_SS.
void build_condensed_dofs(const Model& m, double fraction, CondensedDofs& s);

// Factors A_SS from the model's A (every Newton iteration: S is small). A
// NumericalError names the global DOF.
void factor_condensed_dofs(CondensedDofs& s, const double* A);

// q = A_SS^-1 b_S (ns entries) and y -= A Q b, through S's rows only (y
// changes on S and its neighbours): the sparse part of the split below.
void condensed_q_subtract(CondensedDofs& s, const double* A, const double* b, double* q, double* y);

// x = Q b and y = b - A Q b (n entries each, overwritten; zero on S).
void condensed_split_rhs(CondensedDofs& s, int n, const double* A, const double* b, double* y, double* x);

// z = P^T z = z - Q A z (z: n entries): A z's rows at S only.
void condensed_project(CondensedDofs& s, const double* A, double* z);

// x += Q r (on S only).
void condensed_add_q(CondensedDofs& s, const double* r, double* x);

}  // namespace incise
