#pragma once
// Run-time resources of the linear-solver policies and of parallel assembly,
// held by the Workspace (engine/solve/workspace.h): the worker pool, the assembly plan, the second (background)
// factor of the lagged policy, node rotations of the warped policies, and CG
// vectors. Built by prepare_solver (engine/solve/linear_solve.h).
#include <atomic>
#include <exception>
#include <memory>
#include <thread>
#include <vector>

#include "engine/fem/assemble_parallel.h"
#include "engine/solve/cholmod_solver.h"
#include "engine/solve/coarse_space.h"
#include "engine/solve/condensed_dofs.h"
#include "engine/solve/sparse_rows.h"
#include "engine/runtime/helper_thread.h"
#include "engine/runtime/thread_pool.h"

namespace incise {

struct SolverWork {
  std::unique_ptr<ThreadPool> pool;
  // The pool's workers stand down (ThreadPool::set_active: the stepping
  // thread alone, the same bits) while the helpers' CPUs are needed more:
  // a background factorization still running k frames after its start under
  // late_factor "skip" (job_late, lagged_refresh), or a helper job this frame
  // (helper_busy: the cutting stage's cut-ahead).
  bool job_late = false;
  bool helper_busy = false;
  void apply_stand_down() {
    if (pool) pool->set_active(job_late || helper_busy ? 1 : pool->size());
  }
  AssemblyPlan plan;
  // solver.substitution_threads 2: the second thread of every substitution
  // (set on every factor slot; engine/solve/split_substitution.h). Null with 1.
  // Declared before `back` so that it outlives it; the Workspace destructor takes
  // it from Workspace::solver (CholmodSolver::set_substitution_worker).
  std::unique_ptr<SubstitutionWorker> substitution_worker;

  // lagged: three factor slots (0 = Workspace::solver, 1 = `back`, 2 =
  // `spare`). The front slot preconditions CG; the background job factorizes
  // a copy of an earlier frame's matrix into another slot, which becomes the
  // front when taken. A rescue while a job runs factors the current matrix
  // into the slot neither holds, without waiting for the job (which is then
  // dropped when it ends: its matrix is older); `spare` holds nothing until
  // the first such rescue. A cut does not discard them: each slot keeps a map
  // from the current DOFs to its own (slot_map, empty = identity), DOFs it
  // does not know are solved by the patch below, and the next job analyzes
  // the new pattern off the main thread (engine/solve/linear_solve.h).
  static constexpr int kSlots = 3;
  CholmodSolver back, spare;
  int front = 0;              // slot preconditioning now
  int front_frame = -1;       // frame whose matrix the front slot holds
  int last_launch = -1;       // frame the last job started (or the last synchronous refresh)
  int pattern = 0;            // epoch of the model's sparsity pattern (a carried-over cut bumps it)
  int slot_pattern[kSlots] = {-1, -1, -1};  // epoch each slot was analyzed for
  int slot_n[kSlots] = {0, 0, 0};           // size of that pattern (read here, never from a slot a job may be analyzing)
  std::vector<int> slot_map[kSlots];        // (ndof) slot DOF of each current DOF, -1 none; empty = identity
  std::vector<double> A_back;          // (nnz of the job's pattern) the job's matrix
  std::vector<int> job_Ap, job_Ai;     // the job's pattern when it must analyze it
  // solver.cut_ordering "carried": the job derives its ordering from the front
  // factor's (engine/solve/carried_ordering.h) instead of searching one; inputs copied
  // at launch (empty job_old_perm: search).
  std::vector<int> job_map, job_old_perm, job_enr_node;
  int job_nnode = 0;
  int pattern_frame = -1000000;        // frame a cut last changed the pattern (cutting goes on while it is this or the last frame)
  bool slot_carried[kSlots] = {false, false, false};  // that slot's analysis used a carried ordering: searched again once cutting pauses
  bool job_analyze = false;
  int job_slot = -1;
  std::unique_ptr<HelperThread> job_thread;  // runs the jobs (created at the first, again if its settings change)
  bool job_running = false;
  std::atomic<bool> job_done{false};   // set by the job when it has finished (late_factor "skip" polls it)
  int job_policy = -1;                 // the scheduling policy the last job ran at (SCHED_IDLE, SCHED_OTHER), set by it
  int job_frame = -1;
  std::exception_ptr job_error;
  std::vector<double> t_slot;          // gather buffer of a mapped slot
  std::vector<int> nz_slot;            // factor_compliance: the rows' DOFs in the front slot's numbering
  // factor_compliance with columns on the condensed set S: Q B = A_SS^-1 B_S
  // ((|S|, k); empty when the columns are off S), the DOFs off S where
  // B - A Q B can be nonzero, its values there ((|compliance_nz|, k)), an
  // (ndof) scratch and a node mark.
  std::vector<double> compliance_q, compliance_yc, compliance_y;
  std::vector<int> compliance_nz;
  std::vector<char> compliance_mark;
  std::vector<double> slot_Rn[kSlots];  // (slot's DOF nodes, 9) node rotations when its matrix was taken (warp)
  std::vector<double> Q;               // (ndofnode, 9) warp: Rn * slot_Rn^T of the front slot, this solve
  // lagged after a cut, until a factor of the new pattern is taken: the DOFs
  // the front factor does not know, with every DOF node of the elements that
  // touch them, form a patch solved exactly (CHOLMOD, supernodal where BLAS
  // may run beside the background job, else BLAS-free simplicial;
  // refactored each frame), combined with the factor additively or
  // multiplicatively (solver.patch_schwarz).
  CholmodSolver patch;
  std::vector<int> patch_dof;          // (np) global DOFs of the patch, sorted
  std::vector<int> patch_src;          // (patch nnz) position in the global A of each patch entry
  std::vector<double> patch_A, patch_r;
  // What the patch was built for: the pattern, the front slot and its frame
  // (patch_pattern -1: none). Kept apart: a packed key, (pattern * 2 +
  // front) * 1000003 + front_frame, gave pattern 26 with slot 2 and pattern
  // 27 with slot 0 the same value, and a patch of the old pattern's entries
  // was refactored with the new A (organ_instruments: "not positive
  // definite" at frame 46).
  int patch_pattern = -1, patch_front = -1, patch_front_frame = 0;
  bool patch_current() const {
    return patch_pattern == pattern && patch_front == front && patch_front_frame == front_frame;
  }
  void mark_patch_current() { patch_pattern = pattern, patch_front = front, patch_front_frame = front_frame; }
  std::vector<int> patch_contact_nodes;  // solver.contact_patch: the contact rows' DOF nodes it was built for
  std::vector<int> patch_seeds;          // (scratch) this iteration's
  // Rows of A at the patch DOFs (every column), for the multiplicative combination.
  SparseRows patch_rows;
  std::vector<double> ms_r, ms_z;      // (ndof) multiplicative Schwarz work
  // lagged, solver.condense_below: the DOFs condensed out next to tiny cut
  // pieces (engine/solve/condensed_dofs.h); rhs_cg, x_s: (ndof) the
  // right-hand side CG gets and the condensed part of the solution.
  CondensedDofs condensed;
  std::vector<double> rhs_cg, x_s;
  std::vector<double> multi_y, multi_x;  // (ndof, k) the same for apply_factor_inverse's k columns
  std::vector<double> multi_r, multi_z, multi_t;  // (ndof, k), (ndof, k), (front slot size, k): lagged_apply_multi

  // warped: DOF node -> its elements; each element's volume-weighted sum of
  // its slots' R (the slot's share of the element's volume) is summed once
  // per frame and then per node.
  std::vector<int> node_elem_ptr, node_elem;  // (ndofnode + 1), elements
  std::vector<double> elem_S;                 // (nelem, 9) sum over the element's slots of vol/nslot R
  std::vector<double> Rn;            // (ndofnode, 9) node rotations, column-major
  std::vector<char> node_identity;   // (ndofnode) 1 where 1 or 2 components are constrained: R = I keeps the projection

  std::vector<double> r, z, p, q, t;  // (ndof) CG work
  std::vector<double> cr, cz, cp, cq;  // (ndof + extra) constrained_refine's CG work (the contact stage's tools appended)
  // solver.coarse "corners": the two-level preconditioner's coarse level and
  // its work vectors (ndof each).
  CoarseSpace coarse;
  std::vector<double> bnn_q, bnn_t, bnn_s;
  // (ndof, or empty) CG's start for the next frame's first Newton iteration:
  // this frame's first increment du (mapped through a cut; 0 on new DOFs).
  std::vector<double> guess;

  SolverWork() = default;
  SolverWork(const SolverWork&) = delete;
  SolverWork& operator=(const SolverWork&) = delete;
  ~SolverWork() { wait_job(); }
  void wait_job() {
    if (job_thread) job_thread->wait();
  }
};

}  // namespace incise
