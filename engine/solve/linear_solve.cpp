#include "engine/solve/linear_solve.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/Core>

#include "engine/dynamics/step.h"
#include "engine/fem/assemble.h"
#include "engine/solve/carried_ordering.h"
#include "engine/util/error.h"
#include "engine/util/headroom.h"
#include "engine/fem/polar.h"
#include "engine/runtime/thread_affinity.h"

namespace incise {

namespace {

using Mat3 = Eigen::Matrix3d;

// A = cK K + cM M with the constrained rows and columns projected out
// (Algorithm 1); a recovery step's coefficients with `recovery`.
void form_matrix(const Model& m, const double* K, double* A, bool recovery = false) {
  const NewmarkCoefficients c = newmark_coefficients(m, recovery);
  const double cM = c.cM, cK = c.cK;
  for (int k = 0; k < m.nnz(); ++k) A[k] = cK * K[k];
  if (m.mass_kind == MassKind::Consistent) {
    for (int k = 0; k < m.nnz(); ++k) A[k] += cM * m.mass_csc[k];
  } else {  // lumped: the diagonal and, with X-FEM, the u-q couplings (Model::mass_coupling)
    for (int d = 0; d < m.ndof(); ++d) A[m.diag[d]] += cM * m.mass_lumped[d];
    for (int k : m.mass_coupling) A[k] += cM * m.mass_csc[k];
  }
  project_constraints(m, A);
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0.0;
  for (size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}

// One forward + back substitution, counted and timed (from the float copy
// when the factor has one: lagged with solver.factor_copy float or half).
void substitute(Workspace& ws, CholmodSolver& f, const double* b, double* x) {
  Stopwatch w;
  const int takeovers = f.stats().takeovers;
  if (f.has_factor_copy()) f.solve_copy(b, x);
  else f.solve(b, x);
  ws.timing.solves += 1;
  ws.timing.solve_kernel_ms += w.ms();
  ws.timing.takeovers += f.stats().takeovers - takeovers;
}

// x = Rn A0^-1 Rn^T b with the rest factor in ws.solver.
void warped_apply(const Model& m, Workspace& ws, const double* b, double* x) {
  auto& w = ws.work;
  double* t = w.t.data();
  for (int node = 0; node < m.ndofnode; ++node) {
    const Eigen::Map<const Mat3> R(&w.Rn[9 * node]);
    Eigen::Map<Eigen::Vector3d>(t + 3 * node) = R.transpose() * Eigen::Map<const Eigen::Vector3d>(b + 3 * node);
  }
  substitute(ws, ws.solver, t, t);
  for (int node = 0; node < m.ndofnode; ++node) {
    const Eigen::Map<const Mat3> R(&w.Rn[9 * node]);
    Eigen::Map<Eigen::Vector3d>(x + 3 * node) = R * Eigen::Map<const Eigen::Vector3d>(t + 3 * node);
  }
}

// y = A v for CG. Under solver.matrix_precision "single" (docs/numerics.md,
// "CG's matrix in single precision") from A's float copy, made at the third
// product with a newly formed A: the copy reads 8 and writes 4 bytes an
// entry, each product from it reads 4 fewer, so the first two products of
// an A read it in double (a frame of one CG iteration makes two).
// static_solve and init_state write ws.A themselves and set A_generation to
// 0: no copy is taken of that.
void cg_matvec(const Model& m, Workspace& ws, const double* A, const double* v, double* y) {
  auto& w = ws.work;
  const bool single = m.solver.single_matrix && A == ws.A.data() && ws.A_generation != 0;
  if (single && ws.A_single_stamp != ws.A_stamp && ++ws.A_products > 2) {
    resize_with_headroom(ws.A_single, m.nnz());
    for (int k = 0; k < m.nnz(); ++k) ws.A_single[k] = static_cast<float>(A[k]);
    ws.A_single_stamp = ws.A_stamp;
  }
  if (single && ws.A_single_stamp == ws.A_stamp) sym_matvec_parallel(m, w.plan, *w.pool, ws.A_single.data(), v, y);
  else sym_matvec_parallel(m, w.plan, *w.pool, A, v, y);
}

// Preconditioned CG on A x = b to |r| <= tol |b|, from x = 0 or, with x0
// (solver.initial_guess "previous"), from x = alpha x0 with the alpha that
// minimises |b - alpha A x0| (one product more; never a larger residual than
// x = 0). Records iterations, the starting and final residual and
// convergence in ws.timing.
template <class Precond>
void pcg(const Model& m, Workspace& ws, const double* A, const double* b, double* x, const Precond& precond,
         int max_iterations, const double* x0 = nullptr) {
  auto& w = ws.work;
  const auto matvec = [&](const double* v, double* y) { cg_matvec(m, ws, A, v, y); };
  const int n = m.ndof();
  std::vector<double>& r = w.r;
  std::vector<double>& z = w.z;
  std::vector<double>& p = w.p;
  std::vector<double>& q = w.q;
  std::copy(b, b + n, r.begin());
  std::fill(x, x + n, 0.0);
  const double bnorm = std::sqrt(dot(r, r));
  ws.timing.residual = 0.0;
  ws.timing.converged = true;
  if (bnorm == 0.0) return;
  if (x0) {
    // min over alpha of |b - alpha q|^2, q = A x0: alpha = (b.q)/(q.q), |r|^2 = |b|^2 - alpha (b.q).
    matvec(x0, q.data());
    double bq = 0.0, qq = 0.0;
    for (int i = 0; i < n; ++i) bq += b[i] * q[i], qq += q[i] * q[i];
    const double alpha = qq > 0.0 && std::isfinite(bq / qq) ? bq / qq : 0.0;
    if (alpha != 0.0) {
      double rr = 0.0;
      for (int i = 0; i < n; ++i) {
        r[i] = b[i] - alpha * q[i];
        rr += r[i] * r[i];
      }
      if (std::sqrt(rr) < bnorm) {
        for (int i = 0; i < n; ++i) x[i] = alpha * x0[i];
        ws.timing.start_residual = std::sqrt(rr) / bnorm;
        if (ws.timing.start_residual <= m.solver.tolerance) {
          ws.timing.residual = ws.timing.start_residual;
          return;
        }
      } else {
        std::copy(b, b + n, r.begin());  // roundoff made it no better: from 0
      }
    }
  }
  const double tol = m.solver.tolerance;
  precond(r.data(), z.data());
  p = z;
  double rz = dot(r, z), rel = 1.0;
  int it = 0;
  while (it < max_iterations) {
    matvec(p.data(), q.data());
    ++it;
    const double pq = dot(p, q);
    if (!(pq > 0.0)) break;  // breakdown (should not happen: A is SPD); reported as not converged
    const double alpha = rz / pq;
    for (int i = 0; i < n; ++i) {
      x[i] += alpha * p[i];
      r[i] -= alpha * q[i];
    }
    rel = std::sqrt(dot(r, r)) / bnorm;
    if (rel <= tol) break;
    if (it == max_iterations) break;
    precond(r.data(), z.data());
    const double rz_new = dot(r, z);
    const double beta = rz_new / rz;
    rz = rz_new;
    for (int i = 0; i < n; ++i) p[i] = z[i] + beta * p[i];
  }
  ws.timing.iterations += it;
  ws.timing.residual = rel;
  ws.timing.converged = ws.timing.converged && rel <= tol;
}

// Synchronous factorization of the current A into slot k (analysis first when
// the slot holds another pattern).
void factor_now(const Model& m, Workspace& ws, int k) {
  auto& w = ws.work;
  CholmodSolver& f = ws.slot(k);
  if (w.slot_pattern[k] != w.pattern) {
    f.analyze(m.ndof(), m.Ap, m.Ai);
    w.slot_carried[k] = false;
    w.slot_pattern[k] = w.pattern;
    w.slot_n[k] = m.ndof();
  }
  f.factorize(ws.A.data());
  w.slot_map[k].clear();
  if (m.solver.warp) w.slot_Rn[k] = w.Rn;
  ++ws.refactorizations;
}

void take_job(Workspace& ws) {
  auto& w = ws.work;
  w.wait_job();
  w.job_running = false;
  if (w.job_error) {
    auto e = w.job_error;
    w.job_error = nullptr;
    std::rethrow_exception(e);
  }
  ++ws.refactorizations;
  // A rescue since the launch factored a newer matrix into another slot: this one is older, dropped.
  if (w.job_frame >= w.front_frame) {
    w.front = w.job_slot;
    w.front_frame = w.job_frame;
  }
  w.job_slot = -1;
}

// Starts the background factorization of the current A (and the analysis of
// its pattern when the chosen slot has not seen it) in a slot other than the front.
void launch_job(const Model& m, Workspace& ws, int frame) {
  auto& w = ws.work;
  const int k = w.front == 0 ? 1 : 0;  // slot 0 or 1 but the front (none is running); 2 is the rescue's
  assign_range_with_headroom(w.A_back, ws.A.begin(), ws.A.end());
  // While an incision goes on (a new pattern this frame or the last), a slot
  // analyzing the new pattern carries the front factor's ordering over
  // (solver.cut_ordering "carried"): no METIS in the job (39-44 ms at 10k DOF,
  // the factorization 53 ms), for 10-20% more flops in the factorization. Once
  // cutting pauses, a slot with a carried analysis is analyzed again with a search.
  const bool cutting = frame - w.pattern_frame <= 1;
  w.job_analyze = w.slot_pattern[k] != w.pattern || (w.slot_carried[k] && !cutting);
  w.job_old_perm.clear();
  if (w.job_analyze) {
    w.job_Ap = m.Ap;
    w.job_Ai = m.Ai;
    w.slot_pattern[k] = w.pattern;
    w.slot_n[k] = m.ndof();
    const CholmodSolver& front = ws.slot(w.front);
    // Inputs checked here, so a mismatch falls back to a search instead of
    // failing the job.
    w.slot_carried[k] = m.solver.carry_ordering && cutting && m.has_cuts() && !w.slot_map[w.front].empty() &&
                        front.analyzed() && front.size() == w.slot_n[w.front] &&
                        static_cast<int>(m.cuts.enr_node.size()) == m.ndofnode - m.nnode;
    if (w.slot_carried[k]) {
      w.job_map = w.slot_map[w.front];
      w.job_old_perm = front.permutation();
      w.job_enr_node = m.cuts.enr_node;
      w.job_nnode = m.nnode;
    }
  }
  w.slot_map[k].clear();
  if (m.solver.warp) w.slot_Rn[k] = w.Rn;
  CholmodSolver* f = &ws.slot(k);
  SolverWork* wp = &w;
  const int n = m.ndof();
  w.job_done = false;
  // solver.background_priority "idle" with late_factor "skip": the job only
  // takes CPU time nothing else wants, so the stepping thread, the cut-ahead
  // helper and a haptic thread always come first (measured on the 10k
  // incision: the cutting stage's p99, mostly the wait for the helper, 11-13
  // -> 6.5-7.2 ms). Not with "wait": the step then blocks on the job, and an
  // idle-priority thread gets next to no CPU while every core is busy (an
  // unprivileged thread cannot raise it back for the wait).
  const auto priority = ws.runtime.idle_background && m.solver.skip_late_factor ? HelperThread::Priority::Idle
                                                                               : HelperThread::Priority::Normal;
  const bool helper_cpus = ws.runtime.split_affinity;
  if (!w.job_thread || w.job_thread->priority() != priority || w.job_thread->helper_cpus() != helper_cpus) {
    w.job_thread.reset();  // (no job runs: launch_job is called with none)
    w.job_thread = std::make_unique<HelperThread>(helper_cpus, priority);
  }
  w.job_thread->run([f, wp, n] {
    wp->job_policy = wp->job_thread->policy();
    try {
      if (wp->job_analyze && !wp->job_old_perm.empty()) {
        const std::vector<int> perm = carried_ordering(wp->job_nnode, wp->job_enr_node, wp->job_map, wp->job_old_perm);
        f->analyze(n, wp->job_Ap, wp->job_Ai, &perm);
      } else if (wp->job_analyze) {
        f->analyze(n, wp->job_Ap, wp->job_Ai);
      }
      f->factorize(wp->A_back.data());
    } catch (...) {
      wp->job_error = std::current_exception();
    }
    wp->job_done = true;
  });
  w.job_running = true;
  w.job_slot = k;
  w.job_frame = w.last_launch = frame;
}

// A now, synchronously (a rescue, or a patch too large to pay). With a job
// running, into the slot neither holds and without waiting for it
// (take_job drops it when it ends); otherwise into the front slot. Before,
// a rescue waited for the job and then factored: up to two factorizations.
// Two factorizations at once need a BLAS that allows it
// (blas_concurrency_safe); with a serial one the job is waited for and
// dropped, as before.
void factor_synchronously(const Model& m, Workspace& ws, int f) {
  auto& w = ws.work;
  int slot = w.front;
  if (w.job_running && blas_concurrency_safe()) {
    slot = 0;
    while (slot == w.front || slot == w.job_slot) ++slot;
  } else if (w.job_running) {
    w.wait_job();
    w.job_running = false;
    w.job_error = nullptr;
    w.job_slot = -1;
  }
  factor_now(m, ws, slot);
  w.front = slot;
  w.front_frame = f;
  if (!w.job_running) w.last_launch = f;
}

// Lagged: make the front factor current for this frame (refresh policy).
void lagged_refresh(const Model& m, Workspace& ws, int frame) {
  auto& w = ws.work;
  const int f = frame, k = m.solver.refresh_every;
  const int call = ws.refresh_frame == f ? ++ws.refresh_calls : (ws.refresh_calls = 0);
  ws.refresh_frame = f;
  if (ws.rescue_pending && ws.factor_current) {
    factor_synchronously(m, ws, f);
    return;
  }
  if (!ws.factor_current) {  // first frame, or the factor was invalidated
    w.wait_job();
    w.job_running = false;
    w.job_error = nullptr;
    w.front = 0;
    factor_now(m, ws, 0);
    ws.factor_current = true;
    w.front_frame = w.last_launch = f;
  } else if (!m.solver.background) {
    if (f - w.front_frame >= k) {
      factor_now(m, ws, w.front);
      w.front_frame = w.last_launch = f;
    }
  } else {
    // late_factor "wait" (deterministic): a job started k frames ago is taken
    // now, waiting if it is late, so replays give the same states. "skip":
    // a late job is taken in the first frame it has finished in; no stall,
    // but the trajectory then depends on the machine's speed, so the choice
    // is reported (timing.late_factor_call) and a replay imposes it.
    if (w.job_running && f - w.job_frame >= k) {
      bool take = true;
      if (m.solver.skip_late_factor) {
        const int imposed = ws.imposed_late_factor_call;
        take = imposed == Workspace::kClockDecides ? w.job_done.load() : imposed == call;
        if (take) ws.timing.late_factor_call = call;
      }
      if (take) take_job(ws);
    }
    if (!w.job_running && f - w.last_launch >= k) launch_job(m, ws, f);
    // The job shares the helpers' CPUs with the assembly workers; at idle
    // priority (skip) it gets none while they work, and back to back (incise
    // compare, 2 workers) drag15mm-20k's factor was 23-30 frames old, its
    // error at frame 30 0.55. So while a job is late (still running k frames
    // after its start) the workers stand down: this frame's CG products and
    // the next frame's assembly run on the stepping thread alone, with the
    // same bits (ThreadPool::active). Under "wait" the job's take is on
    // schedule and the workers stay. They stand down too while the cutting
    // stage's cut-ahead runs on a helper (helper_busy; it set that for this
    // frame's assembly already).
    w.job_late = m.solver.skip_late_factor && w.job_running && f - w.job_frame >= k;
    w.apply_stand_down();
  }
}

// warp: Q_n = Rn_n * (the front slot's Rn of the same node)^T for every DOF
// node whose three DOFs the slot knows as one node; identity elsewhere.
void lagged_warp_rotations(const Model& m, Workspace& ws) {
  auto& w = ws.work;
  const int k = w.front;
  const std::vector<int>& map = w.slot_map[k];
  const std::vector<double>& Rl = w.slot_Rn[k];
  w.Q.assign(9 * static_cast<size_t>(m.ndofnode), 0.0);
  for (int n = 0; n < m.ndofnode; ++n) {
    Eigen::Map<Mat3> Q(&w.Q[9 * n]);
    int fn = n;
    if (!map.empty()) {
      const int d = map[3 * n];
      fn = (d >= 0 && d % 3 == 0 && map[3 * n + 1] == d + 1 && map[3 * n + 2] == d + 2) ? d / 3 : -1;
    }
    if (fn < 0 || 9 * static_cast<size_t>(fn) >= Rl.size()) {
      Q.setIdentity();
      continue;
    }
    Q = Eigen::Map<const Mat3>(&w.Rn[9 * n]) * Eigen::Map<const Mat3>(&Rl[9 * fn]).transpose();
  }
}

// z = Q F^-1 Q^T r with the lagged front factor F (through its DOF map after
// cuts; 0 on the DOFs it does not know). With warp, Q = the node rotations
// since the factor's frame: if the body turned rigidly by Q, A = Q A_lag Q^T
// (lumped, isotropic mass) and this is exact.
void factor_apply(const Model& m, Workspace& ws, const double* r, double* z) {
  auto& w = ws.work;
  CholmodSolver& f = ws.slot(w.front);
  const std::vector<int>& map = w.slot_map[w.front];
  const bool warp = m.solver.warp;
  const double* rin = r;
  if (warp) {  // r <- Q^T r (into the factor's frame), in z as scratch
    for (int n = 0; n < m.ndofnode; ++n)
      Eigen::Map<Eigen::Vector3d>(z + 3 * n) =
          Eigen::Map<const Mat3>(&w.Q[9 * n]).transpose() * Eigen::Map<const Eigen::Vector3d>(r + 3 * n);
    rin = z;
  }
  if (map.empty()) {
    substitute(ws, f, rin, z);
  } else {
    w.t_slot.assign(f.size(), 0.0);  // capacity kept: no allocation after the first use
    for (int d = 0; d < m.ndof(); ++d)
      if (map[d] >= 0) w.t_slot[map[d]] = rin[d];
    substitute(ws, f, w.t_slot.data(), w.t_slot.data());
    for (int d = 0; d < m.ndof(); ++d) z[d] = map[d] >= 0 ? w.t_slot[map[d]] : 0.0;
  }
  if (warp)
    for (int n = 0; n < m.ndofnode; ++n) {
      const Eigen::Vector3d t = Eigen::Map<const Eigen::Vector3d>(z + 3 * n);
      Eigen::Map<Eigen::Vector3d>(z + 3 * n) = Eigen::Map<const Mat3>(&w.Q[9 * n]) * t;
    }
}

// z_p (+)= A_p^-1 r_p on the patch DOFs (r, z global).
void patch_apply(Workspace& ws, const double* r, double* z, bool add) {
  auto& w = ws.work;
  const int np = static_cast<int>(w.patch_dof.size());
  for (int j = 0; j < np; ++j) w.patch_r[j] = r[w.patch_dof[j]];
  Stopwatch clock;
  w.patch.solve(w.patch_r.data(), w.patch_r.data());
  ws.timing.solve_kernel_ms += clock.ms();
  for (int j = 0; j < np; ++j) z[w.patch_dof[j]] = (add ? z[w.patch_dof[j]] : 0.0) + w.patch_r[j];
}

// The multiplicative combination's patch steps around the substitution
// (lagged_apply, lagged_apply_multi): before, z1 = E A_p^-1 E^T r and
// r1 = r - A z1 (z1 lives on the patch, so A z1 sums over the patch rows: A
// symmetric); after (z = F^-1 r1), z += z1 and the last step
// (patch_last_step; r1 its scratch).
void patch_before(const Model& m, Workspace& ws, const double* A, const double* r, double* z1, double* r1) {
  auto& w = ws.work;
  patch_apply(ws, r, z1, /*add=*/false);
  std::copy(r, r + m.ndof(), r1);
  for (size_t i = 0; i < w.patch_dof.size(); ++i) {
    const double zi = z1[w.patch_dof[i]];
    for (int t = w.patch_rows.ptr[i]; t < w.patch_rows.ptr[i + 1]; ++t) r1[w.patch_rows.col[t]] -= A[w.patch_rows.k[t]] * zi;
  }
}

// The multiplicative combination's last step, z += E A_p^-1 E^T (r - A z)
// on the patch rows (r null: zero there; r1 their scratch).
void patch_last_step(Workspace& ws, const double* A, const double* r, double* r1, double* z) {
  auto& w = ws.work;
  for (size_t i = 0; i < w.patch_dof.size(); ++i) {
    double acc = r ? r[w.patch_dof[i]] : 0.0;
    for (int t = w.patch_rows.ptr[i]; t < w.patch_rows.ptr[i + 1]; ++t) acc -= A[w.patch_rows.k[t]] * z[w.patch_rows.col[t]];
    r1[w.patch_dof[i]] = acc;
  }
  patch_apply(ws, r1, z, /*add=*/true);
}

void patch_after(Workspace& ws, const double* A, const double* r, const double* z1, double* r1, double* z) {
  auto& w = ws.work;
  for (int d : w.patch_dof) z[d] += z1[d];
  patch_last_step(ws, A, r, r1, z);
}

// z = P r: the front factor (factor_apply); after cuts, with the patch of the
// DOFs it does not know (Jacobi on them if there is no patch). Additive:
// P = F^-1 + E A_p^-1 E^T. Multiplicative (symmetric, patch - factor -
// patch; Saad, Iterative Methods, sec. 14.3): z1 = E A_p^-1 E^T r, z2 = z1 +
// F^-1 (r - A z1), z = z2 + E A_p^-1 E^T (r - A z2): one substitution and two
// patch solves, and the residual products need A's patch rows only.
void lagged_apply(const Model& m, Workspace& ws, const double* A, const double* r, double* z) {
  auto& w = ws.work;
  const std::vector<int>& map = w.slot_map[w.front];
  if (w.patch_dof.empty()) {
    factor_apply(m, ws, r, z);
    if (!map.empty())
      for (int d = 0; d < m.ndof(); ++d)
        if (map[d] < 0) z[d] = r[d] / A[m.diag[d]];
  } else if (!m.solver.multiplicative_patch) {
    factor_apply(m, ws, r, z);
    patch_apply(ws, r, z, /*add=*/true);
  } else {
    double* z1 = w.ms_z.data();  // patch-supported
    double* r1 = w.ms_r.data();
    patch_before(m, ws, A, r, z1, r1);
    factor_apply(m, ws, r1, z);
    patch_after(ws, A, r, z1, r1, z);
  }
}

// solver.coarse "corners": the balancing two-level preconditioner
// z = Q r + (I - Q A) M (I - A Q) r with M = lagged_apply and Q = P A_c^-1 P^T
// (engine/solve/coarse_space.h): two products with A and two coarse solves
// more than M alone.
void two_level_apply(const Model& m, Workspace& ws, const double* A, const double* r, double* z) {
  auto& w = ws.work;
  const int n = m.ndof();
  double* q = w.bnn_q.data();
  double* t = w.bnn_t.data();
  double* s = w.bnn_s.data();
  apply_coarse_space(m, w.coarse, r, q);
  sym_matvec_parallel(m, w.plan, *w.pool, A, q, t);
  for (int i = 0; i < n; ++i) t[i] = r[i] - t[i];
  lagged_apply(m, ws, A, t, z);
  sym_matvec_parallel(m, w.plan, *w.pool, A, z, t);
  apply_coarse_space(m, w.coarse, t, s);
  for (int i = 0; i < n; ++i) z[i] += q[i] - s[i];
}

// solver.frame_iterations: the CG iterations left to the frame (at least one
// per solve, so every Newton iteration moves); no cap without a budget.
int budget_left(const Model& m, const Workspace& ws) {
  const int b = m.solver.frame_iterations;
  return b > 0 ? std::max(1, b - ws.timing.iterations) : std::numeric_limits<int>::max();
}

// After a CG solve capped at min(cap, left): whether it stopped short of the
// tolerance because the budget ran out (recorded in the frame's timing: no
// rescue and no further Newton iteration follow).
bool budget_ran_out(const Model& m, Workspace& ws, int left, int cap) {
  const bool out = ws.timing.residual > m.solver.tolerance && left <= cap;
  if (out) ws.timing.budget_spent = true;
  return out;
}

// The patch's DOF nodes: unknown = a DOF node with a DOF the front map does
// not carry, node_in = a node of an element touching an unknown one; and
// (solver.contact_patch) the DOF nodes of the grasp rows, grown by that
// many element rings (contact_nodes: those seeds, sorted).
void patch_nodes(const Model& m, const std::vector<int>& map, const std::vector<int>& contact_nodes,
                 std::vector<char>& node_in, std::vector<char>& unknown) {
  const auto grow = [&](std::vector<char>& from, std::vector<char>& to) {
    for (int e = 0; e < m.nelem; ++e) {
      bool touch = false;
      for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1] && !touch; ++k) touch = from[m.elem_dof_node[k]];
      if (touch)
        for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k) to[m.elem_dof_node[k]] = 1;
    }
  };
  if (!map.empty()) {
    for (int d = 0; d < m.ndof(); ++d)
      if (map[d] < 0) unknown[d / 3] = 1;
    grow(unknown, node_in);
  }
  if (contact_nodes.empty()) return;
  std::vector<char> ring(m.ndofnode, 0), next;
  for (int i : contact_nodes) ring[i] = 1;
  for (int k = 0; k < m.solver.contact_patch; ++k) {
    next = ring;
    grow(ring, next);
    ring.swap(next);
  }
  for (int i = 0; i < m.ndofnode; ++i) node_in[i] = node_in[i] || ring[i];
}

// solver.contact_patch: the DOF nodes the grasp rows act on, sorted (empty:
// none). Grasps only: with a probe's contact rows in it (they change every
// frame) the combination stalled CG into rescues (docs/benchmarks.md).
void contact_patch_seeds(const Model& m, const Workspace& ws, std::vector<int>& out) {
  out.clear();
  if (m.solver.contact_patch <= 0) return;
  const ContactRows& c = ws.contacts;
  for (int i = 0; i < c.nrow(); ++i)
    if (c.kind[i] == RowKind::Grasp)
      for (int k = c.ptr[i]; k < c.ptr[i + 1]; ++k)
        if (!m.constrained[c.dof[k]]) out.push_back(c.dof[k] / 3);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

// patch_dof (the patch nodes' DOFs in order) and g2l, its inverse (-1 off the patch).
void patch_dofs(const Model& m, const std::vector<char>& node_in, const std::vector<char>& unknown, SolverWork& w,
                std::vector<int>& g2l) {
  w.patch_dof.clear();
  for (int n = 0; n < m.ndofnode; ++n)
    if (node_in[n] || unknown[n])
      for (int c = 0; c < 3; ++c) {
        g2l[3 * n + c] = static_cast<int>(w.patch_dof.size());
        w.patch_dof.push_back(3 * n + c);
      }
}

// A new patch (the front slot or the pattern changed): its DOFs, pattern,
// rows and analysis. False, with none of them, where a cut's patch would
// hold more than a quarter of the DOFs (see lagged_patch).
bool build_patch(const Model& m, const std::vector<int>& map, SolverWork& w) {
  std::vector<char> node_in(m.ndofnode, 0), unknown(m.ndofnode, 0);
  patch_nodes(m, map, w.patch_contact_nodes, node_in, unknown);
  std::vector<int> g2l(m.ndof(), -1);
  patch_dofs(m, node_in, unknown, w, g2l);
  if (!map.empty() && 4 * w.patch_dof.size() > static_cast<size_t>(m.ndof())) return false;
  std::vector<int> Pp(1, 0), Pi;
  w.patch_src.clear();
  submatrix_pattern(m, w.patch_dof, g2l, Pp, Pi, w.patch_src);
  rows_at(m, g2l, static_cast<int>(w.patch_dof.size()), w.patch_rows);
  // Supernodal (BLAS) only where BLAS may run beside the background job
  // (blas_concurrency_safe); otherwise BLAS-free simplicial.
  const int np = static_cast<int>(w.patch_dof.size());
  w.patch.configure(blas_concurrency_safe() ? FactorMethod::Supernodal : FactorMethod::Simplicial,
                    OrderingMethod::Amd);
  w.patch.analyze(np, Pp, Pi);
  w.patch_A.assign(Pi.size(), 0.0);
  w.patch_r.assign(np, 0.0);
  return true;
}

// The patch of the mapped front factor (see SolverWork::patch): built when
// the front slot or the pattern changed, refactored with the current A.
// A cut's patch over more than a quarter of the DOFs costs more than the
// whole factor, and every solve and contact column would go through it: A
// is factored now instead (a scalpel stroke's front enriched on organ_10k:
// a 9,006-DOF patch of 10,557, 94-144 ms of patch factorization and 260 ms
// of contact in each of three frames), and the patch is then the grasps'
// alone, if any.
void lagged_patch(const Model& m, Workspace& ws, const double* A, int frame) {
  auto& w = ws.work;
  const std::vector<int>& map = w.slot_map[w.front];
  std::vector<int>& seeds = w.patch_seeds;
  contact_patch_seeds(m, ws, seeds);
  if (map.empty() && seeds.empty()) {
    w.patch_dof.clear();
    w.patch_contact_nodes.clear();
    w.patch_pattern = -1;
    return;
  }
  if (!w.patch_current() || seeds != w.patch_contact_nodes) {
    w.mark_patch_current();
    w.patch_contact_nodes = seeds;
    if (!build_patch(m, map, w)) {
      factor_synchronously(m, ws, frame);  // (the front slot's map is empty now)
      if (m.solver.warp) lagged_warp_rotations(m, ws);
      w.patch_pattern = -1;
      lagged_patch(m, ws, A, frame);
      return;
    }
  }
  if (w.patch_dof.empty()) return;  // the mapped factor knows every node: nothing to solve exactly
  for (size_t t = 0; t < w.patch_src.size(); ++t) w.patch_A[t] = A[w.patch_src[t]];
  try {
    w.patch.factorize(w.patch_A.data());
  } catch (const NumericalError& e) {  // the patch's own numbering: its global DOF
    const bool known = e.dof >= 0 && e.dof < static_cast<long>(w.patch_dof.size());
    throw NumericalError(std::string(e.what()) + " (the lagged policy's patch matrix)",
                         known ? w.patch_dof[static_cast<size_t>(e.dof)] : -1);
  }
}

// The warped policies' factor of the rest matrix A0, once per model (its own
// buffer: the assembly stage has already formed this iteration's A).
void rest_factor(const Model& m, Workspace& ws) {
  if (ws.factor_current) return;
  std::vector<double> A0(m.nnz());
  form_matrix(m, m.K0_csc.data(), A0.data());
  ws.solver.factorize(A0.data());
  ++ws.refactorizations;
  ws.factor_current = true;
}

}  // namespace

bool policy_needs_tangent(const Model& m) { return m.solver.policy != SolverPolicy::Warped; }

bool solver_carries_over_cuts(const Model& m, const Workspace& ws) {
  return m.solver.policy == SolverPolicy::Lagged && ws.factor_current;
}

namespace {

// The assembly workers, the substitution worker and the stepping thread's
// CPU (solver.threads, substitution_threads, affinity); the assembly plan.
void prepare_workers(const Model& m, Workspace& ws, AssemblyPlan* plan) {
  auto& w = ws.work;
  const RuntimeSettings& rt = ws.runtime;
  const int threads = std::max(1, rt.threads);
  if (!w.pool || w.pool->size() != threads) w.pool = std::make_unique<ThreadPool>(threads);
  if (rt.substitution_threads > 1 && !w.substitution_worker)
    w.substitution_worker = std::make_unique<SubstitutionWorker>();
  if (rt.substitution_threads <= 1 && w.substitution_worker) {
    for (int k = 0; k < SolverWork::kSlots; ++k)  // before the worker goes (a bin given up on may still run)
      ws.slot(k).set_substitution_worker(nullptr);
    w.substitution_worker.reset();
  }
  for (int k = 0; k < SolverWork::kSlots; ++k) ws.slot(k).set_substitution_worker(w.substitution_worker.get());
  // After the workers above exist (they keep the whole CPU set; ones started
  // later unpin themselves: unpin_if_split).
  if (rt.split_affinity) set_thread_role(ThreadRole::Stepping);
  if (plan && plan->nthreads == threads) w.plan = std::move(*plan);
  else w.plan = make_assembly_plan(m, threads);
}

// A cut: keep the factors; each maps the new DOFs onto its own (composed
// over successive cuts). A DOF node the old model did not have (-1), or a
// second new one on the same old one, is left to the patch (lagged_patch).
void map_factors_over_cut(const Model& m, Workspace& ws, int frame, const std::vector<int>& dofnode_map) {
  auto& w = ws.work;
  const int n = m.ndof();
  for (int k = 0; k < SolverWork::kSlots; ++k) {
    if (k != w.front && k != w.job_slot) {
      w.slot_map[k].clear();
      w.slot_pattern[k] = -1;  // free: holds nothing usable
      continue;
    }
    const std::vector<int> old = std::move(w.slot_map[k]);
    std::vector<int>& nm = w.slot_map[k];
    nm.assign(n, -1);
    std::vector<char> taken(w.slot_n[k], 0);
    for (int node = 0; node < m.ndofnode; ++node) {
      const int o = dofnode_map[node];
      if (o < 0) continue;
      for (int c = 0; c < 3; ++c) {
        const int od = 3 * o + c;
        const int fd = old.empty() ? od : (od < static_cast<int>(old.size()) ? old[od] : -1);
        if (fd < 0 || fd >= static_cast<int>(taken.size()) || taken[fd]) continue;
        taken[fd] = 1;
        nm[3 * node + c] = fd;
      }
    }
  }
  ++w.pattern;
  w.pattern_frame = frame;
  w.last_launch = std::min(w.last_launch, frame - 1000000);  // the next frame starts a job on the new pattern
}

// No factor survives: configure both slots for the policy and analyze the pattern.
void reset_factors(const Model& m, Workspace& ws) {
  auto& w = ws.work;
  const int n = m.ndof();
  w.wait_job();
  w.job_running = false;
  w.job_error = nullptr;
  w.job_slot = -1;
  const bool lagged = m.solver.policy == SolverPolicy::Lagged;
  const FactorCopy copy = lagged ? m.solver.factor_copy : FactorCopy::None;
  for (int k = 0; k < SolverWork::kSlots; ++k) {
    CholmodSolver& f = ws.slot(k);
    f.configure(m.solver.factor, m.solver.ordering);
    f.set_single_factorization(false);  // single needs a copy: off first, on last
    f.set_factor_copy(copy);
    f.set_single_factorization(lagged && m.solver.single_factorization);
  }
  ++w.pattern;
  ws.solver.analyze(n, m.Ap, m.Ai);
  w.pattern_frame = -1000000;
  for (int k = 0; k < SolverWork::kSlots; ++k) {
    w.slot_carried[k] = false;
    w.slot_pattern[k] = k == 0 ? w.pattern : -1;
    w.slot_n[k] = k == 0 ? n : 0;
    w.slot_map[k].clear();
  }
  w.front = 0;
  w.front_frame = w.last_launch = w.job_frame = -1;
  w.job_late = false;
  w.apply_stand_down();
  ws.factor_current = false;
}

// CG work vectors, and CG's start: mapped through a cut (0 on new DOFs),
// dropped otherwise.
void prepare_cg(const Model& m, Workspace& ws, const std::vector<int>* dofnode_map) {
  auto& w = ws.work;
  const int n = m.ndof();
  for (auto* v : {&w.r, &w.z, &w.p, &w.q, &w.t, &w.ms_r, &w.ms_z}) v->assign(n, 0.0);
  if (dofnode_map && !w.guess.empty()) {  // a cut: the start follows its DOF nodes, 0 on new ones
    std::vector<double> old = std::move(w.guess);
    w.guess.assign(n, 0.0);
    for (int node = 0; node < m.ndofnode; ++node) {
      const int o = (*dofnode_map)[node];
      if (o >= 0 && 3 * static_cast<size_t>(o) + 3 <= old.size())
        for (int c = 0; c < 3; ++c) w.guess[3 * node + c] = old[3 * o + c];
    }
  } else if (!dofnode_map) {
    w.guess.clear();
  }
}

// The warped policies' node rotations: warm starts (from the old node's
// across a cut that keeps the factors), the nodes held at R = I, and the
// node -> element adjacency.
void prepare_node_rotations(const Model& m, Workspace& ws, const std::vector<int>* carried_map) {
  auto& w = ws.work;
  std::vector<double> old_Rn = std::move(w.Rn);
  w.Rn = identity_rotations(m.ndofnode);
  if (carried_map)  // a cut: node rotations warm-start from the old node's
    for (int node = 0; node < m.ndofnode; ++node) {
      const int o = (*carried_map)[node];
      if (o >= 0 && 9 * static_cast<size_t>(o) + 9 <= old_Rn.size())
        std::copy_n(old_Rn.begin() + 9 * static_cast<size_t>(o), 9, w.Rn.begin() + 9 * static_cast<size_t>(node));
    }
  w.node_identity.assign(m.ndofnode, 0);
  // A node with some but not all components constrained keeps R = I so the
  // warped matrix stays projected; a fully constrained node may rotate (its
  // block is the identity either way).
  for (int node = 0; node < m.ndofnode; ++node) {
    const int c = m.constrained[3 * node] + m.constrained[3 * node + 1] + m.constrained[3 * node + 2];
    w.node_identity[node] = c > 0 && c < 3;
  }
  if (m.solver.policy == SolverPolicy::Warped || m.solver.policy == SolverPolicy::WarpedCG ||
      (m.solver.policy == SolverPolicy::Lagged && m.solver.warp)) {
    std::vector<int> count(m.ndofnode + 1, 0);
    for (int e = 0; e < m.nelem; ++e)
      for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k) ++count[m.elem_dof_node[k] + 1];
    for (int node = 0; node < m.ndofnode; ++node) count[node + 1] += count[node];
    w.node_elem_ptr = count;
    w.node_elem.assign(count.back(), 0);
    std::vector<int> next(count.begin(), count.end() - 1);
    for (int e = 0; e < m.nelem; ++e)
      for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k) w.node_elem[next[m.elem_dof_node[k]]++] = e;
    w.elem_S.assign(9 * static_cast<size_t>(m.nelem), 0.0);
  } else {
    w.node_elem_ptr.assign(m.ndofnode + 1, 0);
    w.node_elem.clear();
  }
}

}  // namespace

void prepare_solver(const Model& m, Workspace& ws, int frame, const std::vector<int>* dofnode_map, AssemblyPlan* plan) {
  prepare_workers(m, ws, plan);
  const bool carried = dofnode_map && solver_carries_over_cuts(m, ws);
  if (carried) map_factors_over_cut(m, ws, frame, *dofnode_map);
  else reset_factors(m, ws);
  prepare_cg(m, ws, dofnode_map);
  prepare_node_rotations(m, ws, carried ? dofnode_map : nullptr);
  auto& w = ws.work;
  build_condensed_dofs(m, m.solver.policy == SolverPolicy::Lagged ? m.solver.condense_below : 0.0, w.condensed);
  for (auto* v : {&w.rhs_cg, &w.x_s}) v->assign(w.condensed.empty() ? 0 : m.ndof(), 0.0);
  if (m.solver.policy == SolverPolicy::Lagged && m.solver.coarse) {
    build_coarse_space(m, w.coarse);  // kept over a cut: the standard DOFs' pattern stays
    for (auto* v : {&w.bnn_q, &w.bnn_t, &w.bnn_s}) v->assign(m.ndof(), 0.0);
  }
}

void update_node_rotations(const Model& m, const double* R, Workspace& ws) {
  auto& w = ws.work;
  const auto& ep = w.plan.elem_rot_ptr;
  w.pool->run([&](int tid) {
    int b, e;
    // S_e = vol_e / nslot_e sum of the element's slot rotations, then per
    // node the sum over its elements: the volume-weighted sum of the
    // incident slots' R, with the slot sums shared by the element's nodes
    // (a tet10 per_point corner node sees ~80 slots through ~20 elements).
    ThreadPool::split(m.nelem, w.pool->active(), tid, b, e);
    for (int el = b; el < e; ++el) {
      Eigen::Map<Mat3> Se(&w.elem_S[9 * static_cast<size_t>(el)]);
      Se.setZero();
      for (int k = ep[el]; k < ep[el + 1]; ++k) Se += Eigen::Map<const Mat3>(&R[9 * static_cast<size_t>(w.plan.elem_rot[k])]);
      if (ep[el + 1] > ep[el]) Se *= m.elem_volume[el] / (ep[el + 1] - ep[el]);
    }
    w.pool->barrier();
    ThreadPool::split(m.ndofnode, w.pool->active(), tid, b, e);
    // Four nodes at a time (extract_rotations' lanes): S (4, 9), R (4, 9).
    double S[36], Rb[36];
    int nodes[4], count = 0;
    const auto extract = [&] {
      extract_rotations(count, S, Rb);
      for (int j = 0; j < count; ++j) std::copy(Rb + 9 * j, Rb + 9 * j + 9, &w.Rn[9 * static_cast<size_t>(nodes[j])]);
      count = 0;
    };
    for (int node = b; node < e; ++node) {
      if (w.node_identity[node] || w.node_elem_ptr[node] == w.node_elem_ptr[node + 1]) {
        Eigen::Map<Mat3>(&w.Rn[9 * node]).setIdentity();
        continue;
      }
      Eigen::Map<Mat3> Sn(S + 9 * count);
      Sn.setZero();
      for (int k = w.node_elem_ptr[node]; k < w.node_elem_ptr[node + 1]; ++k)
        Sn += Eigen::Map<const Mat3>(&w.elem_S[9 * static_cast<size_t>(w.node_elem[k])]);
      std::copy(&w.Rn[9 * node], &w.Rn[9 * node] + 9, Rb + 9 * count);
      nodes[count++] = node;
      if (count == 4) extract();
    }
    if (count > 0) extract();
  });
}

namespace {
// ws.A = cM M + cK K unless it already holds that for this K: a streaming
// pass over nnz values (about 1 ms at 20k DOF) saved in every Newton
// iteration whose assembly kept every element's blocks (tangent_reuse on a
// calm body) and for the linear model's constant K0.
void form_matrix_once(const Model& m, Workspace& ws, const double* K) {
  if (ws.A_generation == ws.K_generation && ws.A_source == K && ws.A_recovery == ws.recovery) return;
  form_matrix(m, K, ws.A.data(), ws.recovery);
  ++ws.A_stamp;
  ws.A_products = 0;
  ws.A_generation = ws.K_generation;
  ws.A_source = K;
  ws.A_recovery = ws.recovery;
}
}  // namespace

void form_dynamic_matrix(const Model& m, const State& s, Workspace& ws, const double* K) {
  const bool linear = m.material.model == MaterialModel::Linear;
  switch (m.solver.policy) {
    case SolverPolicy::Exact:
      if (!(linear && ws.factor_current)) form_matrix_once(m, ws, K);
      break;
    case SolverPolicy::Lagged:
      form_matrix_once(m, ws, K);
      if (m.solver.warp) update_node_rotations(m, s.R.data(), ws);
      break;
    case SolverPolicy::Warped:
      update_node_rotations(m, s.R.data(), ws);
      break;
    case SolverPolicy::WarpedCG:
      form_matrix_once(m, ws, K);
      update_node_rotations(m, s.R.data(), ws);
      break;
  }
}

bool factorization_due(const Model& m, const Workspace& ws) {
  switch (m.solver.policy) {
    case SolverPolicy::Exact:
      return !(m.material.model == MaterialModel::Linear && ws.factor_current);
    case SolverPolicy::Lagged:
      return true;  // the refresh policy, the warp and the patch decide per iteration
    case SolverPolicy::Warped:
    case SolverPolicy::WarpedCG:
      return !ws.factor_current;
  }
  return true;
}

void factorize_for_policy(const Model& m, const State& s, Workspace& ws) {
  const bool linear = m.material.model == MaterialModel::Linear;
  switch (m.solver.policy) {
    case SolverPolicy::Exact:
      if (!(linear && ws.factor_current)) {
        ws.solver.factorize(ws.A.data());
        ++ws.refactorizations;
        ws.factor_current = true;
      }
      break;
    case SolverPolicy::Lagged: {
      // A rescue (solve_for_policy gave up on CG) factors A now,
      // synchronously, beside a running background job (lagged_refresh).
      const bool rescue = ws.rescue_pending;
      if (rescue || ws.newton_iterations_done == 0 || !ws.factor_current) lagged_refresh(m, ws, s.frame);
      if (m.solver.warp) lagged_warp_rotations(m, ws);
      if (rescue || ws.newton_iterations_done == 0 || ws.work.patch_pattern < 0)
        lagged_patch(m, ws, ws.A.data(), s.frame);
      if (!rescue) factor_condensed_dofs(ws.work.condensed, ws.A.data());  // this iteration's A (a rescue keeps it)
      // The coarse level: from this frame's first matrix (measured at 20k DOF
      // here: 5-6 ms to form A_c, 5.7 ms to factor it; later Newton
      // iterations of the frame keep it).
      if (m.solver.coarse && ws.newton_iterations_done == 0 && !rescue) factor_coarse_space(m, ws.A.data(), ws.work.coarse);
      ws.timing.factor_age = s.frame - ws.work.front_frame;
      ws.timing.patch_dofs = static_cast<int>(ws.work.patch_dof.size());
      ws.timing.condensed_dofs = static_cast<int>(ws.work.condensed.dof.size());
      break;
    }
    case SolverPolicy::Warped:
    case SolverPolicy::WarpedCG:
      rest_factor(m, ws);
      break;
  }
}

void solve_for_policy(const Model& m, Workspace& ws) {
  double* du = ws.du.data();
  const int iteration = ws.newton_iterations_done;
  switch (m.solver.policy) {
    case SolverPolicy::Exact:
      substitute(ws, ws.solver, ws.rhs.data(), du);
      break;
    case SolverPolicy::Lagged: {
      // DOFs next to tiny cut pieces (solver.condense_below) are condensed
      // out: du = Q rhs + y, CG on A y = rhs - A Q rhs with the
      // preconditioner and start projected by P^T (engine/solve/condensed_dofs.h).
      CondensedDofs& cd = ws.work.condensed;
      const double* rhs = ws.rhs.data();
      if (!cd.empty()) {
        condensed_split_rhs(cd, m.ndof(), ws.A.data(), ws.rhs.data(), ws.work.rhs_cg.data(), ws.work.x_s.data());
        rhs = ws.work.rhs_cg.data();
      }
      const auto precond = [&](const double* r, double* z) {
        if (m.solver.coarse) two_level_apply(m, ws, ws.A.data(), r, z);
        else lagged_apply(m, ws, ws.A.data(), r, z);
        if (!cd.empty()) condensed_project(cd, ws.A.data(), z);
      };
      const int rescue = m.solver.rescue_after;
      const int left = budget_left(m, ws);
      auto& guess = ws.work.guess;
      if (ws.rescue_pending) {  // the rescue factor is in place: CG again from 0
        ws.rescue_pending = false;
        pcg(m, ws, ws.A.data(), rhs, du, precond, std::min(m.solver.max_iterations, left));
        budget_ran_out(m, ws, left, m.solver.max_iterations);
      } else {
        // The first Newton iteration's increment alternates in sign between
        // frames (the trapezoidal rule's undamped sawtooth about the
        // constant-velocity predictor): the last one, scaled, starts CG close.
        const bool use_guess = m.solver.previous_guess && iteration == 0 && guess.size() == static_cast<size_t>(m.ndof());
        if (use_guess && !cd.empty()) condensed_project(cd, ws.A.data(), guess.data());
        const int cap = rescue > 0 ? std::min(rescue, m.solver.max_iterations) : m.solver.max_iterations;
        pcg(m, ws, ws.A.data(), rhs, du, precond, std::min(cap, left), use_guess ? guess.data() : nullptr);
        // With solver.frame_iterations spent the frame takes this increment
        // as it is (no rescue, no further Newton iteration: decide_newton).
        if (!budget_ran_out(m, ws, left, cap) && rescue > 0 && ws.timing.residual > m.solver.tolerance &&
            rescue < m.solver.max_iterations) {
          // The lagged factor is too far from A (fast large rotations): the
          // factorization stage factors A now and CG runs again with it,
          // instead of hundreds of CG iterations.
          ws.rescue_pending = true;
          ++ws.timing.rescues;
          return;
        }
      }
      if (!cd.empty())
        for (int d = 0; d < m.ndof(); ++d) du[d] += ws.work.x_s[d];
      if (iteration == 0 && m.solver.previous_guess) guess.assign(du, du + m.ndof());
      break;
    }
    case SolverPolicy::Warped:
      warped_apply(m, ws, ws.rhs.data(), du);
      break;
    case SolverPolicy::WarpedCG: {
      auto& guess = ws.work.guess;
      const bool use_guess = m.solver.previous_guess && iteration == 0 && guess.size() == static_cast<size_t>(m.ndof());
      const int left = budget_left(m, ws);
      pcg(m, ws, ws.A.data(), ws.rhs.data(), du, [&](const double* r, double* z) { warped_apply(m, ws, r, z); },
          std::min(m.solver.max_iterations, left), use_guess ? guess.data() : nullptr);
      budget_ran_out(m, ws, left, m.solver.max_iterations);
      if (iteration == 0 && m.solver.previous_guess) guess.assign(du, du + m.ndof());
      break;
    }
  }
}

namespace {

// X = Rn F^-1 Rn^T B per column with the factor f (Rn: per-node rotations of
// (ndofnode, 9), or none), all columns in one substitution (X may alias B).
// map (null or empty: f knows every DOF): the lagged front factor's DOF map
// after cuts, factor_apply's; X is 0 on the DOFs it does not know.
void rotated_multi(const Model& m, Workspace& ws, CholmodSolver& f, const std::vector<double>* Rn,
                   const std::vector<int>* map, int k, const double* B, double* X) {
  const size_t n = static_cast<size_t>(m.ndof());
  const auto rotate = [&](double* V, bool transpose) {
    for (int c = 0; c < k; ++c)
      for (int node = 0; node < m.ndofnode; ++node) {
        const Eigen::Map<const Mat3> R(&(*Rn)[9 * static_cast<size_t>(node)]);
        Eigen::Map<Eigen::Vector3d> v(V + c * n + 3 * node);
        const Eigen::Vector3d t = v;
        if (transpose) v = R.transpose() * t;
        else v = R * t;
      }
  };
  if (X != B) std::copy(B, B + n * k, X);
  if (Rn) rotate(X, true);
  Stopwatch w;
  if (!map || map->empty()) {
    f.solve_copy_multi(k, X, X);
  } else {
    std::vector<double>& t = ws.work.multi_t;
    const size_t nf = static_cast<size_t>(f.size());
    t.assign(nf * k, 0.0);
    for (int c = 0; c < k; ++c)
      for (size_t d = 0; d < n; ++d)
        if ((*map)[d] >= 0) t[c * nf + (*map)[d]] = X[c * n + d];
    f.solve_copy_multi(k, t.data(), t.data());
    for (int c = 0; c < k; ++c)
      for (size_t d = 0; d < n; ++d) X[c * n + d] = (*map)[d] >= 0 ? t[c * nf + (*map)[d]] : 0.0;
  }
  ws.timing.solves += k;
  ws.timing.solve_kernel_ms += w.ms();
  if (Rn) rotate(X, false);
}

// factor_apply for k columns (ndof apart; Z may alias R): the front factor read once for all of them.
void factor_apply_multi(const Model& m, Workspace& ws, int k, const double* R, double* Z) {
  auto& w = ws.work;
  rotated_multi(m, ws, ws.slot(w.front), m.solver.warp ? &w.Q : nullptr, &w.slot_map[w.front], k, R, Z);
}

// lagged_apply for k columns (ndof apart; Z must not alias R unless the
// front factor knows every DOF and there is no patch), with one
// multi-column substitution where lagged_apply does k: after cuts the
// contact stage's compliance (one column per contact row) went column by
// column through the patch's combination, a substitution each, and with a
// probe's 23-27 rows that was most of a cut frame's contact stage.
void lagged_apply_multi(const Model& m, Workspace& ws, const double* A, int k, const double* R, double* Z) {
  auto& w = ws.work;
  const std::vector<int>& map = w.slot_map[w.front];
  const size_t n = static_cast<size_t>(m.ndof());
  if (w.patch_dof.empty()) {
    factor_apply_multi(m, ws, k, R, Z);
    if (!map.empty())
      for (int c = 0; c < k; ++c)
        for (size_t d = 0; d < n; ++d)
          if (map[d] < 0) Z[c * n + d] = R[c * n + d] / A[m.diag[d]];
    return;
  }
  if (!m.solver.multiplicative_patch) {
    factor_apply_multi(m, ws, k, R, Z);
    for (int c = 0; c < k; ++c) patch_apply(ws, R + c * n, Z + c * n, /*add=*/true);
    return;
  }
  // lagged_apply's multiplicative combination, its substitution batched.
  w.multi_r.resize(n * k);
  w.multi_z.resize(n * k);
  for (int c = 0; c < k; ++c) patch_before(m, ws, A, R + c * n, &w.multi_z[c * n], &w.multi_r[c * n]);
  factor_apply_multi(m, ws, k, w.multi_r.data(), Z);
  for (int c = 0; c < k; ++c) patch_after(ws, A, R + c * n, &w.multi_z[c * n], &w.multi_r[c * n], Z + c * n);
}

// X = Q B + P^T M^-1 (B - A Q B) for k columns (ndof apart; X may alias B):
// the lagged preconditioner made exact on the condensed DOFs
// (engine/solve/condensed_dofs.h); apply_m(Y, Z) applies M^-1 to all k
// columns of Y at once.
template <class ApplyM>
void condensed_inverse(const Model& m, Workspace& ws, int k, const double* B, double* X, const ApplyM& apply_m) {
  auto& w = ws.work;
  const size_t n = static_cast<size_t>(m.ndof());
  w.multi_y.resize(n * k);  // grows to the most columns asked, then stays
  w.multi_x.resize(n * k);
  for (int c = 0; c < k; ++c)
    condensed_split_rhs(w.condensed, m.ndof(), ws.A.data(), B + c * n, &w.multi_y[c * n], &w.multi_x[c * n]);
  apply_m(w.multi_y.data(), X);
  for (int c = 0; c < k; ++c) {
    condensed_project(w.condensed, ws.A.data(), X + c * n);
    for (size_t d = 0; d < n; ++d) X[c * n + d] += w.multi_x[c * n + d];
  }
}

}  // namespace

void apply_factor_inverse_multi(const Model& m, Workspace& ws, int k, const double* B, double* X) {
  const size_t n = static_cast<size_t>(m.ndof());
  auto& w = ws.work;
  switch (m.solver.policy) {
    case SolverPolicy::Exact:
      rotated_multi(m, ws, ws.solver, nullptr, nullptr, k, B, X);
      return;
    case SolverPolicy::Lagged:
      // lagged_apply's preconditioner (warp: Q F^-1 Q^T, Q the rotations since
      // the factor's frame; after cuts its DOF map and patch), one
      // substitution for all columns.
      if (w.condensed.factored) {
        condensed_inverse(m, ws, k, B, X, [&](const double* Y, double* Z) { lagged_apply_multi(m, ws, ws.A.data(), k, Y, Z); });
      } else if (w.slot_map[w.front].empty() && w.patch_dof.empty()) {
        factor_apply_multi(m, ws, k, B, X);  // (X may alias B)
      } else {
        w.multi_y.assign(B, B + n * k);  // (X may alias B)
        lagged_apply_multi(m, ws, ws.A.data(), k, w.multi_y.data(), X);
      }
      return;
    case SolverPolicy::Warped:
    case SolverPolicy::WarpedCG:
      rotated_multi(m, ws, ws.solver, &w.Rn, nullptr, k, B, X);
      return;
  }
}

// After cuts the lagged preconditioner is P^-1 = Q + P_S^T M^-1 P_S
// (condensed_inverse: Q = A_SS^-1 on the condensed set S, P_S = I - A Q)
// around M^-1 = the patch steps around the mapped factor (lagged_apply).
// For columns zero on the DOFs the factor does not map and on the patch,
// the patch steps change only the patch's DOFs and leave the columns as
// they are (C B = 0): B^T M^-1 B = B^T F B with F the mapped, warped factor
// alone, whose forward half gives Z. Columns on S enter M^-1 as
// B - A Q B (zero on S, nonzero on S's neighbours: those must be mapped and
// off the patch too), so W = B^T Q B + Z^T Z with Z the forward half of
// B - A Q B. The correction (factor_compliance_apply) adds the steps back.
namespace {
// The condensed part of factor_compliance for columns with DOFs on S: Q B
// into w.compliance_q, the DOFs of B - A Q B off S into w.compliance_nz
// (every DOF of their nodes, node by node) and its values there into
// w.compliance_yc.
void condensed_columns(const Model& m, Workspace& ws, int k, const double* B, const std::vector<int>& nz) {
  auto& w = ws.work;
  CondensedDofs& S = w.condensed;
  const size_t n = static_cast<size_t>(m.ndof()), ns = S.dof.size();
  const auto on_S = [&](int d) { return std::binary_search(S.dof.begin(), S.dof.end(), d); };
  std::vector<char>& mark = w.compliance_mark;
  mark.assign(m.ndofnode, 0);
  for (int d : nz)
    if (!on_S(d)) mark[d / 3] = 1;
  for (size_t i = 0; i < ns; ++i)
    for (int t = S.rows.ptr[i]; t < S.rows.ptr[i + 1]; ++t)
      if (!on_S(S.rows.col[t])) mark[S.rows.col[t] / 3] = 1;
  std::vector<int>& cols = w.compliance_nz;
  cols.clear();
  for (int node = 0; node < m.ndofnode; ++node)
    if (mark[node])
      for (int c = 0; c < 3; ++c) cols.push_back(3 * node + c);
  std::vector<double>& y = w.compliance_y;  // zero outside cols and S between the columns
  y.assign(n, 0.0);
  resize_with_headroom(w.compliance_q, ns * k);
  resize_with_headroom(w.compliance_yc, cols.size() * k);
  const double* A = ws.A.data();
  for (int c = 0; c < k; ++c) {
    const double* b = B + c * n;
    for (int d : cols) y[d] = b[d];
    condensed_q_subtract(S, A, b, w.compliance_q.data() + c * ns, y.data());
    double* yc = w.compliance_yc.data() + c * cols.size();
    for (size_t j = 0; j < cols.size(); ++j) {
      yc[j] = y[cols[j]];
      y[cols[j]] = 0.0;
    }
    for (int d : S.dof) y[d] = 0.0;  // (b_S - A_SS q: roundoff)
  }
}
}  // namespace

bool factor_compliance(const Model& m, Workspace& ws, int k, const double* B, const std::vector<int>& nz,
                       std::vector<int>& rows, std::vector<double>& Z, std::vector<double>& W) {
  auto& w = ws.work;
  w.compliance_q.clear();
  if (m.solver.policy != SolverPolicy::Lagged) return false;
  const std::vector<int>& map = w.slot_map[w.front];
  const auto in = [](const std::vector<int>& sorted, int d) { return std::binary_search(sorted.begin(), sorted.end(), d); };
  const CondensedDofs& S = w.condensed;
  const bool on_S = S.factored && std::any_of(nz.begin(), nz.end(), [&](int d) { return in(S.dof, d); });
  // The DOFs the columns M^-1 sees live on: nz, or B - A Q B's.
  const std::vector<int>* cols = &nz;
  if (on_S) {
    condensed_columns(m, ws, k, B, nz);
    cols = &w.compliance_nz;
  }
  const auto fail = [&] {
    w.compliance_q.clear();
    return false;
  };
  for (int d : *cols)  // (off S: nz was, or B - A Q B's DOFs are)
    if ((!map.empty() && map[d] < 0) || in(w.patch_dof, d)) return fail();
  CholmodSolver& f = ws.slot(w.front);
  const size_t n = static_cast<size_t>(m.ndof()), nf = static_cast<size_t>(f.size());
  const double* Bq = B;
  const std::vector<int>* nzf = cols;
  if (m.solver.warp || !map.empty() || on_S) {  // Q^T B on the columns' nodes, in the factor's numbering (the rest is zero)
    std::vector<double>& t = w.multi_t;
    resize_with_headroom(t, nf * k);
    std::fill(t.begin(), t.begin() + nf * k, 0.0);  // the paths read rows outside nz too
    const auto to_f = [&](int d) { return static_cast<size_t>(map.empty() ? d : map[d]); };
    for (int c = 0; c < k; ++c)
      for (size_t i = 0; i + 2 < cols->size(); i += 3) {
        const int node = (*cols)[i] / 3;
        Eigen::Vector3d b = on_S ? Eigen::Vector3d(Eigen::Map<const Eigen::Vector3d>(w.compliance_yc.data() + c * cols->size() + i))
                                 : Eigen::Vector3d(Eigen::Map<const Eigen::Vector3d>(B + c * n + 3 * node));
        if (m.solver.warp) b = Eigen::Map<const Mat3>(&w.Q[9 * static_cast<size_t>(node)]).transpose() * b;
        for (int j = 0; j < 3; ++j) t[c * nf + to_f(3 * node + j)] = b[j];
      }
    Bq = t.data();
    if (!map.empty()) {
      w.nz_slot.clear();
      for (int d : *cols) w.nz_slot.push_back(map[d]);
      nzf = &w.nz_slot;
    }
  }
  Stopwatch sw;
  if (!f.forward_half_multi(k, Bq, *nzf, rows, Z)) return fail();
  ws.timing.solve_kernel_ms += sw.ms();
  const Eigen::Map<const Eigen::MatrixXd> Zm(Z.data(), static_cast<Eigen::Index>(rows.size()), k);
  W.resize(static_cast<size_t>(k) * k);
  Eigen::Map<Eigen::MatrixXd> Wm(W.data(), k, k);
  Wm.noalias() = Zm.transpose() * Zm;
  if (on_S) {  // + B_S^T Q B (symmetric: B_S^T A_SS^-1 B_S), symmetrised
    const size_t ns = S.dof.size();
    Eigen::MatrixXd BtQB(k, k);
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < k; ++j) {
        double acc = 0.0;
        for (size_t s = 0; s < ns; ++s) acc += B[i * n + S.dof[s]] * w.compliance_q[j * ns + s];
        BtQB(i, j) = acc;
      }
    Wm += 0.5 * (BtQB + BtQB.transpose());
  }
  return true;
}

void factor_compliance_apply(const Model& m, Workspace& ws, const std::vector<int>& rows, const double* z,
                             const double* c, double* x) {
  auto& w = ws.work;
  CholmodSolver& f = ws.slot(w.front);
  const std::vector<int>& map = w.slot_map[w.front];
  const int n = m.ndof();
  Stopwatch sw;
  const int takeovers = f.stats().takeovers;
  if (map.empty()) {
    f.backward_half(rows, z, x);
  } else {  // in the factor's numbering, then back (an unmapped DOF: the columns are zero there, so is Jacobi's step)
    w.t_slot.resize(f.size());
    f.backward_half(rows, z, w.t_slot.data());
    for (int d = 0; d < n; ++d) x[d] = map[d] >= 0 ? w.t_slot[map[d]] : 0.0;
  }
  ws.timing.solve_kernel_ms += sw.ms();
  ws.timing.takeovers += f.stats().takeovers - takeovers;
  if (m.solver.warp)  // back out of the factor's frame: x <- Q x
    for (int node = 0; node < m.ndofnode; ++node) {
      const Eigen::Vector3d t = Eigen::Map<const Eigen::Vector3d>(x + 3 * node);
      Eigen::Map<Eigen::Vector3d>(x + 3 * node) = Eigen::Map<const Mat3>(&w.Q[9 * node]) * t;
    }
  // The steps the factor's half leaves out, for a right-hand side r zero on
  // the patch and on S (lagged_apply, condensed_inverse): the multiplicative
  // patch's last, x += E A_p^-1 E^T (0 - A x) on the patch rows (its first,
  // E A_p^-1 E^T r, is zero, as is the additive patch's term), then the
  // condensed projection.
  if (!w.patch_dof.empty() && m.solver.multiplicative_patch) {
    resize_with_headroom(w.ms_r, static_cast<size_t>(n));
    patch_last_step(ws, ws.A.data(), nullptr, w.ms_r.data(), x);
  }
  if (w.condensed.factored) condensed_project(w.condensed, ws.A.data(), x);
  if (!w.compliance_q.empty()) {  // + Q B c (columns on S)
    const size_t ns = w.condensed.dof.size(), k = w.compliance_q.size() / ns;
    for (size_t i = 0; i < ns; ++i) {
      double acc = 0.0;
      for (size_t j = 0; j < k; ++j) acc += w.compliance_q[j * ns + i] * c[j];
      x[w.condensed.dof[i]] += acc;
    }
  }
}

bool iterative_policy(const Model& m) {
  return m.solver.policy == SolverPolicy::Lagged || m.solver.policy == SolverPolicy::WarpedCG;
}

bool constrained_refine(const Model& m, Workspace& ws, const double* b, double* x, ConstraintProjection& proj,
                        const std::vector<double>& k_extra) {
  const int n = m.ndof(), ne = static_cast<int>(k_extra.size()), nt = n + ne;
  const int left = std::min(m.solver.max_iterations, budget_left(m, ws));
  const bool spent = m.solver.frame_iterations > 0 && ws.timing.iterations >= m.solver.frame_iterations;
  if (!iterative_policy(m) || spent || left <= 0) return false;
  auto& w = ws.work;
  for (auto* v : {&w.cr, &w.cz, &w.cp, &w.cq}) resize_with_headroom(*v, nt);
  double* r = w.cr.data();
  double* z = w.cz.data();
  double* p = w.cp.data();
  double* q = w.cq.data();
  const auto dot_t = [nt](const double* a, const double* c) {
    double sum = 0.0;
    for (int i = 0; i < nt; ++i) sum += a[i] * c[i];
    return sum;
  };
  // q = A~ y, z = P~^-1 y: the tissue's A and preconditioner, the extra block's diagonal.
  const auto matvec = [&](const double* y, double* out) {
    sym_matvec_parallel(m, w.plan, *w.pool, ws.A.data(), y, out);
    for (int e = 0; e < ne; ++e) out[n + e] = k_extra[e] * y[n + e];
  };
  const std::function<void(const double*, double*)> precondition = [&](const double* y, double* out) {
    apply_factor_inverse(m, ws, y, out);
    for (int e = 0; e < ne; ++e) out[n + e] = y[n + e] / k_extra[e];
  };
  // r projected (its H_A^T mu removed: A p leaves the range of the projected
  // residuals by roundoff and by P's asymmetry), z the preconditioned residual.
  const auto project = [&] { proj.project(r, z, precondition); };
  const double bnorm = std::sqrt(dot_t(b, b)), tol = m.solver.tolerance;
  if (bnorm == 0.0) return true;
  matvec(x, q);
  for (int i = 0; i < nt; ++i) r[i] = b[i] - q[i];
  project();
  double rel = std::sqrt(dot_t(r, r)) / bnorm;
  int it = 0;
  if (rel > tol) {
    std::copy(z, z + nt, p);
    double rz = dot_t(r, z);
    while (it < left && rz > 0.0) {
      matvec(p, q);
      ++it;
      const double pq = dot_t(p, q);
      if (!(pq > 0.0)) break;
      const double alpha = rz / pq;
      for (int i = 0; i < nt; ++i) {
        x[i] += alpha * p[i];
        r[i] -= alpha * q[i];
      }
      project();  // also on the last iteration: its mu is part of the multipliers
      rel = std::sqrt(dot_t(r, r)) / bnorm;
      if (rel <= tol || it == left) break;
      const double rz_new = dot_t(r, z);
      const double beta = rz_new / rz;
      rz = rz_new;
      for (int i = 0; i < nt; ++i) p[i] = z[i] + beta * p[i];
    }
  }
  ws.timing.iterations += it;
  return true;
}

void apply_factor_inverse(const Model& m, Workspace& ws, const double* b, double* x) {
  switch (m.solver.policy) {
    case SolverPolicy::Exact:
      substitute(ws, ws.solver, b, x);
      break;
    case SolverPolicy::Lagged:
      if (!ws.work.condensed.factored) lagged_apply(m, ws, ws.A.data(), b, x);
      else condensed_inverse(m, ws, 1, b, x, [&](const double* y, double* z) { lagged_apply(m, ws, ws.A.data(), y, z); });
      break;
    case SolverPolicy::Warped:
    case SolverPolicy::WarpedCG:
      warped_apply(m, ws, b, x);
      break;
  }
}

}  // namespace incise
