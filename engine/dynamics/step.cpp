#include "engine/dynamics/step.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "engine/dynamics/contact_solve.h"
#include "engine/fem/assemble.h"
#include "engine/fem/assemble_parallel.h"
#include "engine/util/error.h"
#include "engine/util/headroom.h"
#include "engine/solve/linear_solve.h"

namespace incise {

void mass_matvec(const Model& m, const double* x, double* y) {
  if (m.mass_kind == MassKind::Consistent) {
    sym_matvec(m, m.mass_csc.data(), x, y);
    return;
  }
  // lumped: the diagonal, and with enrichment the u-q couplings (Model::mass_coupling)
  for (int d = 0; d < m.ndof(); ++d) y[d] = m.mass_lumped[d] * x[d];
  for (size_t t = 0; t < m.mass_coupling.size(); ++t) {
    const int k = m.mass_coupling[t], r = m.Ai[k], c = m.mass_coupling_col[t];
    y[r] += m.mass_csc[k] * x[c];
    y[c] += m.mass_csc[k] * x[r];
  }
}

void project_constraints(const Model& m, double* A) {
  for (int k : m.constrained_entries) A[k] = 0.0;
  for (int d = 0; d < m.ndof(); ++d)
    if (m.constrained[d]) A[m.diag[d]] = 1.0;
}

namespace {

void check_finite(const std::vector<double>& x, const char* what, const State& s) {
  for (size_t d = 0; d < x.size(); ++d)
    if (!std::isfinite(x[d])) {
      std::ostringstream os;
      os << "step: non-finite " << what << " at frame " << s.frame << " (t = " << s.time << ") at DOF " << d
         << "; the simulation was stopped instead of propagating NaN";
      throw NumericalError(os.str(), static_cast<long>(d));
    }
}

// Lumped mass with enrichment: each enriched DOF q couples only to its own
// mesh node's standard DOF u with M_uq = M_qq = m_q (model_build.cpp,
// build_mass; [preprint] eqs. (81)-(82)), so
//   m_u a_u + sum_q m_q a_q = r_u,  m_q (a_u + a_q) = r_q
// gives a_u = (r_u - sum_q r_q) / (m_u - sum_q m_q) (the home piece's mass)
// and a_q = r_q / m_q - a_u: a direct solve (a branch DOF of the front
// enrichment has no coupling: a = r / m). On the DOF nodes with mark
// (every one when mark is null; a marked enriched node's mesh node must be
// marked too); a is left alone elsewhere, 0 on constrained DOFs.
struct XfemLumped {
  std::vector<int> home;     // (ndof - 3 nnode) enriched DOF -> its mesh node's DOF (the coupling's row), -1 without
  std::vector<double> msum;  // (3 nnode) the home piece's mass m_u - sum_q m_q
};

// The couplings on the DOF nodes with mark (every one when null): constant
// for a model, so found once for any number of right-hand sides.
XfemLumped xfem_lumped(const Model& m, const std::vector<char>* mark) {
  const int nstd = 3 * m.nnode, n = m.ndof();
  const auto marked = [&](int dof) { return !mark || (*mark)[dof / 3]; };
  XfemLumped L{std::vector<int>(n - nstd, -1), std::vector<double>(nstd, 0.0)};
  for (int c = 0; c < nstd; ++c)
    if (marked(c)) L.msum[c] = m.mass_csc[m.diag[c]];
  for (int c = nstd; c < n; ++c) {
    if (!marked(c)) continue;
    for (int k = m.Ap[c]; k < m.Ap[c + 1]; ++k)
      if (m.Ai[k] < nstd && m.mass_csc[k] != 0.0) {
        L.home[c - nstd] = m.Ai[k];
        L.msum[m.Ai[k]] -= m.mass_csc[k];
      }
  }
  return L;
}

// a = M^-1 r on the marked DOF nodes (rsum: (3 nnode) scratch).
void xfem_lumped_apply(const Model& m, const XfemLumped& L, const std::vector<char>* mark, const double* r,
                       std::vector<double>& rsum, double* a) {
  const int nstd = 3 * m.nnode, n = m.ndof();
  const auto marked = [&](int dof) { return !mark || (*mark)[dof / 3]; };
  rsum.assign(nstd, 0.0);
  for (int c = 0; c < nstd; ++c)
    if (marked(c)) rsum[c] = r[c];
  for (int c = nstd; c < n; ++c)
    if (marked(c) && L.home[c - nstd] >= 0) rsum[L.home[c - nstd]] -= r[c];
  for (int c = 0; c < nstd; ++c)
    if (marked(c)) a[c] = m.constrained[c] ? 0.0 : rsum[c] / L.msum[c];
  for (int c = nstd; c < n; ++c) {
    if (!marked(c)) continue;
    const int h = L.home[c - nstd];
    a[c] = m.constrained[c] ? 0.0 : r[c] / m.mass_csc[m.diag[c]] - (h >= 0 ? a[h] : 0.0);
  }
}

void lumped_xfem_acceleration(const Model& m, const std::vector<double>& r, const std::vector<char>* mark,
                              std::vector<double>& a) {
  std::vector<double> rsum;
  xfem_lumped_apply(m, xfem_lumped(m, mark), mark, r.data(), rsum, a.data());
}

}  // namespace

bool lumped_mass_solve(const Model& m, const std::vector<double>& r, std::vector<double>& x) {
  x.resize(m.ndof());
  return lumped_mass_solve_multi(m, 1, r.data(), x.data());
}

bool lumped_mass_solve_multi(const Model& m, int k, const double* B, double* X) {
  if (m.mass_kind != MassKind::Lumped) return false;
  const size_t n = static_cast<size_t>(m.ndof());
  if (m.mass_csc.empty()) {
    for (int c = 0; c < k; ++c)
      for (size_t d = 0; d < n; ++d) X[c * n + d] = m.constrained[d] ? 0.0 : B[c * n + d] / m.mass_lumped[d];
    return true;
  }
  const XfemLumped L = xfem_lumped(m, nullptr);
  std::vector<double> rsum;
  for (int c = 0; c < k; ++c) xfem_lumped_apply(m, L, nullptr, B + c * n, rsum, X + c * n);
  return true;
}

void size_workspace(const Model& m, Workspace& ws, bool zero) {
  const int n = m.ndof();
  ++ws.K_generation;  // a new or carried model: K and A are formed anew
  ws.tangent_cache = TangentCache{};  // a new model: the next assembly is a full one
  ws.tangent_cache.theta = m.tangent_reuse;
  if (!zero) {
    for (auto* w : {&ws.f_int, &ws.rhs, &ws.delta, &ws.du, &ws.tmp, &ws.tmp2, &ws.f_damp}) resize_with_headroom(*w, n);
    resize_with_headroom(ws.K, m.nnz());
    resize_with_headroom(ws.A, m.nnz());
    return;
  }
  for (auto* w : {&ws.f_int, &ws.rhs, &ws.delta, &ws.du, &ws.tmp, &ws.tmp2, &ws.f_damp}) w->assign(n, 0.0);
  ws.K.assign(m.nnz(), 0.0);
  ws.A.assign(m.nnz(), 0.0);
}

void init_state(const Model& m, State& s, Workspace& ws, bool consistent_a0) {
  const int n = m.ndof();
  s.time = 0.0;
  s.frame = 0;
  size_state(m, s);
  size_workspace(m, ws);
  prepare_solver(m, ws, s.frame);  // worker pool, assembly plan, symbolic analysis
  ws.refactorizations = 0;
  if (!consistent_a0) return;
  // Consistent initial acceleration on the free DOFs: M a0 = f_ext - f_int(0) = f_ext.
  for (int d = 0; d < n; ++d) ws.rhs[d] = m.constrained[d] ? 0.0 : m.f_gravity[d];
  if (m.mass_csc.empty()) {
    for (int d = 0; d < n; ++d) s.a[d] = ws.rhs[d] / m.mass_lumped[d];
  } else {
    std::copy(m.mass_csc.begin(), m.mass_csc.end(), ws.A.begin());
    ws.A_generation = 0;
    project_constraints(m, ws.A.data());
    ws.solver.factorize(ws.A.data());
    ws.solver.solve(ws.rhs.data(), s.a.data());
    ws.factor_current = false;  // the factor holds M, not the dynamics matrix
  }
  for (int d = 0; d < n; ++d)
    if (m.constrained[d]) s.a[d] = 0.0;
}

void attach_state(const Model& m, const State& s, Workspace& ws) {
  const auto check = [&](const std::vector<double>& f, size_t n, const char* name) {
    if (f.size() != n)
      throw Error(std::string("state: ") + name + " has " + std::to_string(f.size()) + " values, the model needs " +
                  std::to_string(n));
  };
  const size_t n = static_cast<size_t>(m.ndof());
  check(s.u, n, "u");
  check(s.v, n, "v");
  check(s.a, n, "a");
  check(s.R, 9 * static_cast<size_t>(m.nrot), "R");
  size_workspace(m, ws);
  ws.work.guess.clear();
  ws.contact_last_lambda.clear();  // another run's multipliers: the next frame starts cold
  ws.contact_last_key.clear();
  prepare_solver(m, ws, s.frame);
}

void step(const Model& m, State& s, Workspace& ws) {
  ws.timing = FrameTiming{};
  step_stages(m, s, ws);
}

void step_stages(const Model& m, State& s, Workspace& ws) {
  ws.timing.newton_capped = false;
  ws.newton_done = false;
  ws.rescue_pending = false;
  ws.rotation_fallbacks = 0;
  ws.newton_iterations_done = 0;
  begin_contacts(m, s, ws);
  const bool contacts = ws.contacts.nrow() > 0;
  // A recovery step (State::recovery) where one is due, but not with contact
  // or grasp rows under a policy whose contact compliance comes from a factor
  // of Newmark's matrix (lagged, warped: the mass term 4/dt^2 where backward
  // Euler's is 1/dt^2): a grasp dragged under the realtime preset, capped 12
  // frames in a row, pulled 132 N instead of 7 N.
  ws.recovery = s.recovery && m.material.model == MaterialModel::Corotated && m.recovery_steps &&
                !(contacts && m.solver.policy != SolverPolicy::Exact);
  ws.timing.recovery = ws.recovery;
  while (!ws.newton_done) {
    run_stage(ws.timing, kStageAssembly, [&] { assemble_system(m, s, ws); });
    do {
      if (factorization_due(m, ws)) run_stage(ws.timing, kStageFactorization, [&] { factorize_system(m, s, ws); });
      run_stage(ws.timing, kStageSolve, [&] { solve_system(m, s, ws); });
    } while (ws.rescue_pending);
    if (contacts) run_stage(ws.timing, kStageContact, [&] {
        solve_contacts(m, s, ws);
        decide_newton(m, s, ws);  // on the corrected increment
      });
  }
  run_stage(ws.timing, kStageIntegration, [&] { integrate(m, s, ws); });
  ws.timing.newton = ws.newton_iterations_done;
}

namespace {
// integrator.line_search. The tangent (its rotation term projected, the
// damping term's derivative through R left out) need not give a step that
// lowers the residual: a very soft cantilever at dt = 0.1 s leaves 8 of 30
// steps at a 30-iteration cap (6 with this); with the damping term on the
// assembled consistent tangent, drag15mm-20k's grasp frames cycled under
// `exact` (residual 0.2 <-> 0.47, rotation change 0.6 <-> 1.1 rad) and this
// converged them in 6-11 iterations. An iterate whose residual norm is
// larger than the last accepted one's is taken back halfway toward it
// (Delta, and the contact multipliers with their force, which enter the
// residual: the rows are the frame's, so a mean of two iterates that meet
// them meets them too), up to kMaxHalvings times; the last try is kept.
// Returns whether Delta changed (assemble again).
bool line_search_step_back(const Model& m, Workspace& ws, double rnorm, int halvings) {
  constexpr int kMaxHalvings = 3;
  const int n = m.ndof();
  auto halfway = [](std::vector<double>& v, const std::vector<double>& to, size_t count) {
    for (size_t i = 0; i < count; ++i) v[i] = 0.5 * (v[i] + to[i]);
  };
  if (ws.newton_iterations_done > 0 && rnorm > ws.accepted_rnorm && halvings < kMaxHalvings &&
      ws.accepted_delta.size() == static_cast<size_t>(n) && ws.accepted_lambda.size() == ws.contacts.lambda.size() &&
      ws.accepted_contact_force.size() == ws.contact_force.size()) {
    halfway(ws.delta, ws.accepted_delta, n);
    halfway(ws.contacts.lambda, ws.accepted_lambda, ws.contacts.lambda.size());
    halfway(ws.contact_force, ws.accepted_contact_force, ws.contact_force.size());
    ++ws.timing.line_search_halvings;
    return true;
  }
  ws.accepted_rnorm = rnorm;
  ws.accepted_delta.assign(ws.delta.begin(), ws.delta.begin() + n);
  ws.accepted_lambda.assign(ws.contacts.lambda.begin(), ws.contacts.lambda.end());
  ws.accepted_contact_force.assign(ws.contact_force.begin(), ws.contact_force.end());
  return false;
}

}  // namespace

void assemble_system(const Model& m, State& s, Workspace& ws) {
  const int n = m.ndof();
  const double t1 = s.time + m.dt;
  const double a_ray = m.material.rayleigh_mass, b_ray = m.material.rayleigh_stiffness;
  const bool linear = m.material.model == MaterialModel::Linear;
  const NewmarkCoefficients nc = newmark_coefficients(m, ws.recovery);
  if (ws.newton_iterations_done == 0) {
    // Increment Delta = u(t+dt) - u(t): constrained DOFs take their known
    // increments up front (projection, Algorithm 1); the solves then keep
    // them (rhs and off-diagonals zeroed) and find the free ones.
    // Free DOFs start from the constant-velocity predictor Delta = dt v, so the
    // first (often only) linearisation, rotations included, is taken about the
    // predicted configuration. Linearising about u(t) lags the rotations by a
    // whole step, and the non-dissipative average-acceleration rule then pumps
    // energy into a swinging, sagging body until it blows up (measured: the
    // default beam scene diverges by frame 60 that way; with the predictor one
    // iteration stays within a few percent of a 10-iteration solution). A
    // linear model is unaffected: its single solve is exact from any start.
    //
    // integrator.predictor "increment" (the realtime preset's) takes the
    // last step's increment instead, du = dt (v(t - dt) + v(t)) / 2 under the
    // trapezoidal rule: a smooth motion half a step behind, but without the
    // velocity's alternating part. The rule integrates a stiff, overdamped
    // mode as v1 = 2/dt Delta - v, so a sudden push (a contact, a grasp)
    // leaves v flipping sign every frame around the slow motion, and dt v
    // then starts Newton that far off (docs/numerics.md, "The Newton
    // predictor": under a probe the first residual was 2.5-4.7 N from dt v,
    // 0.6-0.8 N from du). The converged step is the same. Not the default:
    // one frozen-rotation solve per step from half a step behind let the
    // default beam scene gain energy and diverge (cmd_summary warns).
    const bool increment = m.increment_predictor && s.du.size() == static_cast<size_t>(n);
    for (int d = 0; d < n; ++d) ws.delta[d] = increment ? s.du[d] : m.dt * s.v[d];
    for (int d : m.fixed_dofs) ws.delta[d] = -s.u[d];
    for (const auto& p : m.prescribed) ws.delta[p.dof] = m.prescribed_value(p, t1) - s.u[p.dof];
  }
  for (int halvings = 0;; ++halvings) {
    // x = u + Delta; internal forces and tangent there.
    double* x = ws.tmp.data();
    for (int d = 0; d < n; ++d) x[d] = s.u[d] + ws.delta[d];
    // Newmark ([book] eq. (3.58); newmark_coefficients for general beta, gamma):
    // a1 = 4/dt^2 Delta - 4/dt v - a,  v1 = 2/dt Delta - v at beta = 1/4, gamma = 1/2.
    // Residual r = f_ext - f_int(x) - M a1 - D v1 with D = a M + b K. For
    // Delta = 0 this is eq. 3.60 with f_int the elastic force only (the book
    // folds the t-level viscous force D v into f_int, hence its D (2 v)).
    double* a1 = ws.du.data();
    double* v1 = ws.tmp2.data();
    for (int d = 0; d < n; ++d) {
      a1[d] = nc.a_d * ws.delta[d] + nc.a_v * s.v[d] + nc.a_a * s.a[d];
      v1[d] = nc.v_d * ws.delta[d] + nc.v_v * s.v[d] + nc.v_a * s.a[d];
    }
    // The damping matrix is b R K0 R^T with this iterate's rotations, whatever
    // the tangent: taken matrix-free (the rotated linear stress of v1's
    // gradient at each point, in the assembly's own pass over the elements),
    // not from the assembled K, which under `tangent: consistent` adds the
    // rotation term and under `tangent_reuse` holds kept blocks. With K the
    // converged step depended on both: hang-20k's first step iterated to a
    // 1e-8 residual moved by 0.55-2.5% with reuse 1e-2 (docs/numerics.md,
    // "Converged steps and the line search"), and exact and warped runs solved
    // different equations; under a grasp it made Newton cycle. For the
    // frozen-rotation tangent without reuse it is the same operator as K.
    const bool damp = b_ray > 0.0 && !linear;
    const double* K = internal_forces(m, s, ws, x, policy_needs_tangent(m), /*reuse_tangent=*/true,
                                      damp ? v1 : nullptr, damp ? ws.f_damp.data() : nullptr);
    ws.timing.tangent_updates += ws.tangent_cache.updated;
    ws.timing.assembly_workers = ws.work.pool ? ws.work.pool->active() : 1;
    // rhs = f_ext - f_int - M (a1 + a_ray v1) - b K v1
    for (int d = 0; d < n; ++d) a1[d] += a_ray * v1[d];
    if (m.mass_kind == MassKind::Lumped) {
      mass_matvec(m, a1, ws.rhs.data());  // O(ndof), X-FEM couplings included
    } else {  // consistent: a sparse product, on the workers
      sym_matvec_parallel(m, ws.work.plan, *ws.work.pool, m.mass_csc.data(), a1, ws.rhs.data());
    }
    for (int d = 0; d < n; ++d) ws.rhs[d] = m.f_gravity[d] - ws.f_int[d] - ws.rhs[d];
    // The contact and grasp force found by the step's earlier iterations
    // (engine/dynamics/contact_solve.h): an external force at t + dt.
    if (ws.contact_force.size() == static_cast<size_t>(n))
      for (int d = 0; d < n; ++d) ws.rhs[d] += ws.contact_force[d];
    if (b_ray > 0.0) {
      const double* Kv1 = ws.f_damp.data();  // the assembly's R K0 R^T v1
      if (linear) {
        sym_matvec_parallel(m, ws.work.plan, *ws.work.pool, K, v1, a1);
        Kv1 = a1;
      }
      for (int d = 0; d < n; ++d) ws.rhs[d] -= b_ray * Kv1[d];
    }
    double rnorm = 0.0, fnorm = 0.0;
    for (int d = 0; d < n; ++d) {
      if (m.constrained[d]) ws.rhs[d] = 0.0;
      rnorm += ws.rhs[d] * ws.rhs[d];
      fnorm += m.f_gravity[d] * m.f_gravity[d] + ws.f_int[d] * ws.f_int[d];
    }
    ws.last_residual = fnorm > 0 ? std::sqrt(rnorm / fnorm) : std::sqrt(rnorm);
    check_finite(ws.rhs, "residual", s);
    if (m.line_search && line_search_step_back(m, ws, std::sqrt(rnorm), halvings)) continue;
    // A = 4/dt^2 M + 2/dt D + K ([book] eq. (3.59); cM M + cK K in general), projected.
    form_dynamic_matrix(m, s, ws, K);
    return;
  }
}

void factorize_system(const Model& m, State& s, Workspace& ws) { factorize_for_policy(m, s, ws); }

void solve_system(const Model& m, State& s, Workspace& ws) {
  const int n = m.ndof();
  solve_for_policy(m, ws);
  if (ws.rescue_pending) return;  // the factorization stage runs again first
  check_finite(ws.du, "displacement increment", s);
  for (int d = 0; d < n; ++d) ws.delta[d] += ws.du[d];
  ++ws.newton_iterations_done;
  // With contact rows the contact stage corrects Delta first and decides.
  if (ws.contacts.nrow() == 0) decide_newton(m, s, ws);
}

void decide_newton(const Model& m, State& s, Workspace& ws) {
  const int n = m.ndof();
  const int it = ws.newton_iterations_done - 1;
  const bool adaptive = m.adaptive_newton();
  ws.newton_done = false;
  const int budget = m.solver.frame_iterations;
  const bool capped =
      it + 1 >= m.max_newton_iterations || ws.timing.budget_spent || (budget > 0 && ws.timing.iterations >= budget);
  if (!capped && it + 1 < m.newton_iterations) return;
  if (!adaptive) {
    ws.newton_done = true;
    return;
  }
  // The rotations were frozen at the start of this iteration. If the result
  // turns the body by more than rotation_tolerance, that linearisation was
  // poor: iterate again from the result. Measured: on a partially incised
  // soft beam the frozen-rotation error grows past 0.1 rad a few frames
  // before one-iteration stepping diverges; on smooth frames it stays below.
  // "The body": more than rotation_fraction of its volume, or rotation_rms in
  // the volume-weighted mean. The largest turn of any point was the test
  // until the twenty-sixth session: on the hanging liver 1-7 crushed points
  // (singular values of F near 0.1, whose rotation is ill-conditioned and
  // does not settle, 4e-6-3e-5 of the volume) kept it above 0.1 rad for 2-4
  // iterations while the rest had converged, and decided alone whether a
  // frame took a second iteration, so a policy and `exact` took different
  // ones (error at frame 30 4.2e-2). A grasp's or a probe's region is
  // 1.5e-4-6e-3 of the organ (docs/benchmarks.md, "Newton's stop over the
  // body"). Each body the cuts left (Model::rot_body) is judged by its own
  // volume: a thin slab cut off a swinging beam (5e-8 of its volume) turned
  // 0.1-3 rad a frame, under the whole tissue's fraction, and diverged.
  double* x = ws.tmp.data();
  for (int d = 0; d < n; ++d) x[d] = s.u[d] + ws.delta[d];
  const RotationChange rc =
      rotation_change(m, ws.work.plan, *ws.work.pool, x, s.R.data(), m.rotation_tolerance, m.rotation_fraction);
  ws.timing.rotation_change = rc.max;
  ws.timing.rotation_rms = std::max(rc.body_rms, rc.small_rms);
  ws.timing.rotation_above = std::max(rc.body_above, rc.small_above);
  const auto past = [&](double above, double rms) {
    return m.rotation_tolerance > 0 && (above > m.rotation_fraction || (m.rotation_rms > 0 && rms > m.rotation_rms));
  };
  const bool turning = past(rc.body_above, rc.body_rms);
  // A severed piece below rotation_fraction of the tissue that turns asks
  // for more iterations in cut frames only (where it is severed or cut
  // again: without them the liver_demo scene cut at nu = 0.499 inverted
  // 1684 points in a cut frame, with them 54), else for a recovery step next
  // (below): such a piece did not settle in 4 iterations (a 1e-8 m slab off
  // the swinging beam, 0.07-0.35 rad at the cap in 79% of frames, 2-3x the
  // frame time) and the recovery steps alone keep it bounded.
  const bool small_turning = past(rc.small_above, rc.small_rms);
  // integrator.residual_tolerance: the residual at this iteration's start
  // (the one after the solve needs another assembly), so a step stops one
  // iteration after its residual fell below it.
  const bool more = turning || (small_turning && ws.timing.cut_frame) ||
                    (m.residual_tolerance > 0 && ws.last_residual > m.residual_tolerance);
  ws.newton_done = capped || !more;
  // Stopped by the cap with the rotations still moving, or with a small
  // piece still turning: the step's Newton residual stays in the state, and
  // the next step is a recovery step (integrate, State::recovery). The
  // residual test alone does not count: it asks for converged references,
  // not for the stop that keeps a run stable.
  ws.timing.newton_capped = ws.newton_done && ((capped && turning) || small_turning);
}

void integrate(const Model& m, State& s, Workspace& ws) {
  const int n = m.ndof();
  const double t1 = s.time + m.dt;
  const NewmarkCoefficients nc = newmark_coefficients(m, ws.recovery);
  // Newmark update ([book] eq. (3.58), general beta and gamma).
  for (int d = 0; d < n; ++d) {
    const double a1 = nc.a_d * ws.delta[d] + nc.a_v * s.v[d] + nc.a_a * s.a[d];
    s.v[d] = nc.v_d * ws.delta[d] + nc.v_v * s.v[d] + nc.v_a * s.a[d];
    s.a[d] = a1;
    s.u[d] += ws.delta[d];
  }
  s.du.assign(ws.delta.begin(), ws.delta.begin() + n);  // the next step's predictor
  // Constrained DOFs move as prescribed, not as Newmark would integrate them:
  // from the increment alone, v1 = 2/dt Delta - v flips sign every frame once a
  // ramp stops (Delta = 0) and alternates 0, 2V while it runs, and that
  // sawtooth reaches the free DOFs through the damping coupling b K v.
  for (int d : m.fixed_dofs) s.v[d] = s.a[d] = 0.0;
  for (const auto& p : m.prescribed) {
    s.v[p.dof] = m.prescribed_velocity(p, t1);
    s.a[p.dof] = 0.0;  // piecewise linear in time
  }
  project_contact_kinematics(m, s, ws);
  // Recovery steps (docs/numerics.md): the trapezoidal rule conserves energy
  // for linear forces only; a step Newton left unconverged carries its
  // residual into the next, and on a stressed piece tumbling free after a cut
  // those errors compounded into a blow-up within 10-40 frames (a soft beam
  // severed while swinging, nu = 0.3 to 0.499, either tangent). The next step
  // is one backward Euler step, and so on until a step converges.
  s.recovery = ws.timing.newton_capped;
  s.time = t1;
  ++s.frame;
  check_motion_bounded(m, s);
}

void check_motion_bounded(const Model& m, const State& s) {
  const double length = m.body_length;
  const double limit = kDivergedSpeed * length;
  for (int d = 0; d < m.ndof(); ++d)
    if (std::abs(s.v[d]) > limit) {
      std::ostringstream os;
      os << "step: the motion diverged at frame " << s.frame << " (t = " << s.time << "): DOF " << d << " moves at "
         << std::abs(s.v[d]) << " units/s, more than " << kDivergedSpeed << " body lengths (" << length
         << ") a second; the simulation was stopped";
      // Advice for what this run is (it used to name lagged and cuts always).
      const bool iterative = m.solver.policy != SolverPolicy::Exact;
      if (iterative && m.has_cuts())
        os << ". Under solver.policy " << policy_name(m.solver.policy)
           << ", a tiny cut piece whose DOFs CG leaves far off can do this: raise solver.condense_below (condenses "
              "them out exactly), or use solver.policy exact";
      else if (iterative)
        os << ". Try solver.policy exact: if it runs, the iterative solve (solver.tolerance) let the motion grow";
      if (m.consistent_tangent) os << ". With integrator.tangent consistent: try frozen_rotation";
      if (m.material.poisson > 0.49 && m.newton_iterations == 1)
        os << ". Near-incompressible (material.poisson > 0.49) with one linearised solve a step: add "
              "material.rayleigh.stiffness (docs/numerics.md)";
      if (!m.prescribed.empty()) os << ". Check the prescribed displacements (a ramp too fast for the tissue)";
      throw NumericalError(os.str(), static_cast<long>(d));
    }
}

const double* internal_forces(const Model& m, State& s, Workspace& ws, const double* x, bool tangent, bool reuse_tangent,
                              const double* v, double* Kv) {
  if (m.material.model == MaterialModel::Linear) {
    sym_matvec_parallel(m, ws.work.plan, *ws.work.pool, m.K0_csc.data(), x, ws.f_int.data());
    return m.K0_csc.data();
  }
  // rotations, forces and (when asked) the tangent, on solver.threads workers
  TangentCache* cache = reuse_tangent && tangent && m.tangent_reuse > 0.0 ? &ws.tangent_cache : nullptr;
  const bool keeping = cache && cache->valid && !cache->bypass;  // K updated block by block, not rebuilt
  ws.tangent_cache.updated = tangent ? m.nelem : 0;  // what a full assembly recomputes (the cache overwrites it)
  if (tangent && !cache) ws.tangent_cache.valid = false;  // K rebuilt without it (a static solve): no longer the kept sum
  const int fallbacks = assemble_corotated(m, ws.work.plan, *ws.work.pool, x, s.R.data(), ws.f_int.data(),
                                          tangent ? ws.K.data() : nullptr, cache, v, Kv);
  if (tangent && !(keeping && ws.tangent_cache.updated == 0)) ++ws.K_generation;
  ws.rotation_fallbacks += fallbacks;
  ws.timing.inverted_points = fallbacks;
  return ws.K.data();
}

void consistent_acceleration(const Model& m, State& s, Workspace& ws, const std::vector<double>* contact_force) {
  const int n = m.ndof();
  // Forces and rotations only: the damping product K v is taken matrix-free
  // (R K0 R^T v, without the rotation term of a consistent tangent: this is an
  // estimate of a for the next step, and the tangent assembly cost as much as
  // the rest of a cut frame's rebuild, 10-20 ms at 10k DOF).
  // The corotated K v in the force pass itself (assemble_corotated's fv).
  std::vector<double> r(n), Mv(n), Kv(n, 0.0), z(n), p(n), Ap(n), diag(n);
  const bool damp = m.material.rayleigh_stiffness > 0, linear = m.material.model == MaterialModel::Linear;
  const double* K = internal_forces(m, s, ws, s.u.data(), false, false, damp && !linear ? s.v.data() : nullptr,
                                    damp && !linear ? Kv.data() : nullptr);
  // r = f_ext - f_int - (a_ray M + b_ray K) v
  mass_matvec(m, s.v.data(), Mv.data());
  if (damp && linear) sym_matvec(m, K, s.v.data(), Kv.data());
  for (int d = 0; d < n; ++d) {
    r[d] = m.constrained[d] ? 0.0
                            : m.f_gravity[d] - ws.f_int[d] - m.material.rayleigh_mass * Mv[d] -
                                  m.material.rayleigh_stiffness * Kv[d] +
                                  (contact_force ? (*contact_force)[d] : 0.0);
    diag[d] = m.mass_csc.empty() ? m.mass_lumped[d] : m.mass_csc[m.diag[d]];
  }
  if (lumped_mass_solve(m, r, s.a)) return;  // with enrichment too: a direct solve
  std::fill(s.a.begin(), s.a.end(), 0.0);
  const std::vector<double> rhs = r;
  // PCG on the free DOFs (constrained rows of r and of every iterate stay 0).
  bool converged = false;
  double rz = 0, r0 = 0;
  for (int d = 0; d < n; ++d) {
    z[d] = r[d] / diag[d];
    p[d] = z[d];
    rz += r[d] * z[d];
    r0 += r[d] * r[d];
  }
  for (int it = 0; it < 500 && rz > 0 && !converged; ++it) {
    mass_matvec(m, p.data(), Ap.data());
    for (int d = 0; d < n; ++d)
      if (m.constrained[d]) Ap[d] = 0.0;
    double pAp = 0;
    for (int d = 0; d < n; ++d) pAp += p[d] * Ap[d];
    const double alpha = rz / pAp;
    double rr = 0, rz_new = 0;
    for (int d = 0; d < n; ++d) {
      s.a[d] += alpha * p[d];
      r[d] -= alpha * Ap[d];
      z[d] = r[d] / diag[d];
      rr += r[d] * r[d];
      rz_new += r[d] * z[d];
    }
    if (rr <= 1e-28 * r0) {
      converged = true;
      break;
    }
    const double beta = rz_new / rz;
    rz = rz_new;
    for (int d = 0; d < n; ++d) p[d] = z[d] + beta * p[d];
  }
  if (converged || !(r0 > 0)) return;
  // Jacobi-preconditioned CG stalls where the consistent mass is badly
  // conditioned: the front enrichment's branch functions are close to the
  // quadratic shape functions away from the front (1642 iterations at 3k
  // DOF on the slit beam of tests/cutting/test_front_enrichment.cpp, and a
  // first step that lost 6e-6 of the gravity work when capped at 500). A
  // direct solve then: once per cut, as the factorization of the step.
  // Simplicial: BLAS-free, so safe beside the lagged policy's background
  // factorization (engine/solve/cholmod_solver.h, blas_concurrency_safe).
  std::vector<double> Mc = m.mass_csc;
  project_constraints(m, Mc.data());
  CholmodSolver direct;
  direct.configure(FactorMethod::Simplicial, OrderingMethod::Auto);
  direct.analyze(n, m.Ap, m.Ai);
  direct.factorize(Mc.data());
  direct.solve(rhs.data(), s.a.data());
}

void consistent_acceleration_near(const Model& m, State& s, Workspace& ws, const std::vector<int>& changed) {
  if (m.mass_kind != MassKind::Lumped || m.mass_csc.empty()) {
    consistent_acceleration(m, s, ws);
    return;
  }
  const int nstd = m.nnode, n = m.ndof();
  // Marked DOF nodes: those of the changed elements (their enriched nodes
  // enrich their own mesh nodes) and every enriched node of a marked mesh node.
  std::vector<char> mark(m.ndofnode, 0);
  for (int e : changed)
    for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k) mark[m.elem_dof_node[k]] = 1;
  for (int q = nstd; q < m.ndofnode; ++q)
    if (mark[m.cuts.enr_node[q - nstd]]) mark[q] = 1;
  std::vector<int> ring;  // elements with a marked node: all forces on marked DOFs
  for (int e = 0; e < m.nelem; ++e)
    for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k)
      if (mark[m.elem_dof_node[k]]) {
        ring.push_back(e);
        break;
      }
  std::vector<double> f(n, 0.0), Kv(n, 0.0);
  const bool damp = m.material.rayleigh_stiffness > 0;
  element_subset_forces(m, ws.work.plan, ring, s.u.data(), s.R.data(), f.data(), damp ? s.v.data() : nullptr, Kv.data());
  // M v on the marked DOF nodes (the diagonal and the u-q couplings), then the
  // lumped solve per mesh node.
  std::vector<double> Mv(n, 0.0), r(n, 0.0);
  for (int node = 0; node < m.ndofnode; ++node)
    for (int c = 3 * node; mark[node] && c < 3 * node + 3; ++c) Mv[c] = m.mass_csc[m.diag[c]] * s.v[c];
  for (int c = 3 * nstd; c < n; ++c) {
    if (!mark[c / 3]) continue;
    for (int k = m.Ap[c]; k < m.Ap[c + 1]; ++k)
      if (m.Ai[k] < 3 * nstd && m.mass_csc[k] != 0.0) {
        Mv[c] += m.mass_csc[k] * s.v[m.Ai[k]];
        Mv[m.Ai[k]] += m.mass_csc[k] * s.v[c];
      }
  }
  for (int node = 0; node < m.ndofnode; ++node)
    for (int c = 3 * node; mark[node] && c < 3 * node + 3; ++c)
      r[c] = m.constrained[c] ? 0.0
                              : m.f_gravity[c] - f[c] - m.material.rayleigh_mass * Mv[c] - m.material.rayleigh_stiffness * Kv[c];
  lumped_xfem_acceleration(m, r, &mark, s.a);
}

double total_energy(const Model& m, const State& s) {
  std::vector<double> Mv(m.ndof());
  mass_matvec(m, s.v.data(), Mv.data());
  double kin = 0.0, pot = 0.0;
  for (int d = 0; d < m.ndof(); ++d) {
    kin += 0.5 * s.v[d] * Mv[d];
    pot -= m.f_gravity[d] * s.u[d];
  }
  return kin + pot + elastic_energy(m, s.u.data(), s.R.data());
}

}  // namespace incise
