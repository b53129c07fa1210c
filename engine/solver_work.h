#pragma once
// Run-time resources of the linear-solver policies and of parallel assembly,
// held by State: the worker pool, the assembly plan, the second (background)
// factor of the lagged policy, node rotations of the warped policies, and CG
// vectors. Built by prepare_solver (engine/linear_solve.h).
#include <exception>
#include <memory>
#include <thread>
#include <vector>

#include "engine/assemble_parallel.h"
#include "engine/cholmod_solver.h"
#include "engine/thread_pool.h"

namespace incise {

struct SolverWork {
  std::unique_ptr<ThreadPool> pool;
  AssemblyPlan plan;

  // lagged: the factor in State::solver ("front") holds the matrix of frame
  // front_frame; the background job factorizes A_back of frame job_frame into
  // `back`, swapped in when joined.
  int front = 0;          // 0: State::solver is the front factor, 1: `back` is
  int front_frame = -1;
  int last_launch = -1;   // frame the last background job started (or the first factorization)
  CholmodSolver back;
  std::vector<double> A_back;  // (nnz)
  std::thread job;
  bool job_running = false;
  int job_frame = -1;
  std::exception_ptr job_error;

  // warped: DOF node -> rotation slots (weights: the slot's share of element volume).
  std::vector<int> node_rot_ptr, node_rot;  // (ndofnode + 1), slots
  std::vector<double> node_rot_weight;
  std::vector<double> Rn;            // (ndofnode, 9) node rotations, column-major
  std::vector<char> node_identity;   // (ndofnode) 1 where 1 or 2 components are constrained: R = I keeps the projection

  std::vector<double> r, z, p, q, t;  // (ndof) CG work

  SolverWork() = default;
  SolverWork(const SolverWork&) = delete;
  SolverWork& operator=(const SolverWork&) = delete;
  ~SolverWork() { wait_job(); }
  void wait_job() {
    if (job.joinable()) job.join();
  }
};

}  // namespace incise
