#pragma once
// The coarse level of the lagged policy's two-level preconditioner
// (solver.coarse "corners", issue 20). Coarse space: the tet10 mesh's corner
// nodes with the linear (tet4) interpolation P, fine node -> corners (a
// corner: itself; a mid-edge node: half of each end of its edge; enriched
// and constrained DOFs: none). A_c = P^T A P (Galerkin) is formed from the
// frame's first A and factored (single precision where supernodal), so the
// smooth modes the lagged factor gets wrong after large non-rigid motion (a
// buckling beam, a soft organ stretching) are solved with this frame's
// matrix. The lagged factor M and Q = P A_c^-1 P^T combine as the balancing
// preconditioner z = Q r + (I - Q A) M (I - A Q) r ("BNN" in Tang, Nabben,
// Vuik, Erlangga, "Comparison of two-level preconditioners derived from
// deflation, domain decomposition and multigrid methods", J. Sci. Comput.
// 39 (2009)): symmetric positive definite for any SPD M.
// Cost at 20k DOF (organ_20k, 3,060 coarse DOFs, nnz(L) 4.4e5, this 2-core
// VM): 5-6 ms to form A_c, 5.7 ms to factor it, two products with A per CG
// iteration (docs/benchmarks.md, "Issue 20").
#include <vector>

#include "engine/solve/cholmod_solver.h"

namespace incise {

struct Model;

struct CoarseSpace {
  int nnode = 0;    // mesh nodes it was built for (0: not built)
  int ncoarse = 0;  // coarse nodes (the corners)
  std::vector<int> std_Ap;  // (3 nnode + 1) the fine pattern's standard columns it was built for (a cut keeps them)
  // P by fine mesh node: (nnode + 1) into p_node / p_w.
  std::vector<int> p_ptr, p_node;
  std::vector<double> p_w;
  // Fine node blocks (ni <= nj, both mesh nodes): for each, the position in
  // Ai of row 3 ni in the columns 3 nj, 3 nj + 1, 3 nj + 2 (nblk, 3), and the
  // coarse blocks it adds to: tgt_* over (tgt_ptr[b], tgt_ptr[b + 1]).
  std::vector<int> blk_ni, blk_nj, blk_k;
  std::vector<int> tgt_ptr, tgt_blk;
  std::vector<double> tgt_w;
  std::vector<unsigned char> tgt_mode;  // 0: w B, 1: w B^T, 2: w (B + B^T)
  // Coarse matrix: upper node blocks (I <= J) dense 3x3 column-major (ncblk, 9),
  // and the CSC upper triangle CHOLMOD factors (3 ncoarse columns).
  std::vector<int> cblk_I, cblk_J;
  std::vector<double> cblk;
  std::vector<int> cAp, cAi, cblk_k;  // cblk_k: (ncblk, 3) position of row 3 I in columns 3 J + c
  std::vector<double> cA;
  std::vector<char> cfixed;  // (3 ncoarse) coarse DOFs whose corner DOF is constrained
  CholmodSolver factor;
  std::vector<double> rc;  // (3 ncoarse) work
};

// Builds the space for the model, or keeps it when only enriched DOFs
// changed (a cut leaves the standard columns of the pattern as they were).
// A tet4 model has no coarser level: ncoarse stays 0 and apply is a no-op.
void build_coarse_space(const Model& m, CoarseSpace& c);
// A_c = P^T A P from the model-pattern matrix A (projected), factored.
void factor_coarse_space(const Model& m, const double* A, CoarseSpace& c);
// z = P A_c^-1 P^T r (ndof): 0 on enriched and constrained DOFs.
void apply_coarse_space(const Model& m, CoarseSpace& c, const double* r, double* z);

}  // namespace incise
