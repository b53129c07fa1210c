#include "engine/linear_solve.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <Eigen/Core>

#include "engine/assemble.h"
#include "engine/error.h"
#include "engine/polar.h"

namespace incise {

namespace {

using Mat3 = Eigen::Matrix3d;

// A = cK K + cM M with the constrained rows and columns projected out (Algorithm 1).
void form_matrix(const Model& m, const double* K, double* A) {
  const double dt = m.dt, a_ray = m.material.rayleigh_mass, b_ray = m.material.rayleigh_stiffness;
  const double cM = 4.0 / (dt * dt) + 2.0 * a_ray / dt, cK = 1.0 + 2.0 * b_ray / dt;
  for (int k = 0; k < m.nnz(); ++k) A[k] = cK * K[k];
  if (!m.mass_csc.empty()) {  // consistent, or lumped with X-FEM couplings
    for (int k = 0; k < m.nnz(); ++k) A[k] += cM * m.mass_csc[k];
  } else {
    for (int d = 0; d < m.ndof(); ++d) A[m.diag[d]] += cM * m.mass_lumped[d];
  }
  for (int k : m.constrained_entries) A[k] = 0.0;
  for (int d = 0; d < m.ndof(); ++d)
    if (m.constrained[d]) A[m.diag[d]] = 1.0;
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0.0;
  for (size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}

// One forward + back substitution, counted and timed.
void substitute(State& s, CholmodSolver& f, const double* b, double* x) {
  Stopwatch w;
  f.solve(b, x);
  s.timing.solves += 1;
  s.timing.solve_kernel_ms += w.ms();
}

// x = Rn A0^-1 Rn^T b with the rest factor in state.solver.
void warped_apply(const Model& m, State& s, const double* b, double* x) {
  auto& w = s.work;
  double* t = w.t.data();
  for (int node = 0; node < m.ndofnode; ++node) {
    const Eigen::Map<const Mat3> R(&w.Rn[9 * node]);
    Eigen::Map<Eigen::Vector3d>(t + 3 * node) = R.transpose() * Eigen::Map<const Eigen::Vector3d>(b + 3 * node);
  }
  substitute(s, s.solver, t, t);
  for (int node = 0; node < m.ndofnode; ++node) {
    const Eigen::Map<const Mat3> R(&w.Rn[9 * node]);
    Eigen::Map<Eigen::Vector3d>(x + 3 * node) = R * Eigen::Map<const Eigen::Vector3d>(t + 3 * node);
  }
}

// Preconditioned CG on A x = b from x = 0 to |r| <= tol |b|. Records iterations,
// residual and convergence in state.timing.
template <class Precond>
void pcg(const Model& m, State& s, const double* A, const double* b, double* x, const Precond& precond) {
  auto& w = s.work;
  const int n = m.ndof();
  std::vector<double>& r = w.r;
  std::vector<double>& z = w.z;
  std::vector<double>& p = w.p;
  std::vector<double>& q = w.q;
  std::copy(b, b + n, r.begin());
  std::fill(x, x + n, 0.0);
  const double bnorm = std::sqrt(dot(r, r));
  s.timing.residual = 0.0;
  s.timing.converged = true;
  if (bnorm == 0.0) return;
  const double tol = m.solver.tolerance;
  precond(r.data(), z.data());
  p = z;
  double rz = dot(r, z), rel = 1.0;
  int it = 0;
  while (it < m.solver.max_iterations) {
    sym_matvec_parallel(m, w.plan, *w.pool, A, p.data(), q.data());
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
    if (it == m.solver.max_iterations) break;
    precond(r.data(), z.data());
    const double rz_new = dot(r, z);
    const double beta = rz_new / rz;
    rz = rz_new;
    for (int i = 0; i < n; ++i) p[i] = z[i] + beta * p[i];
  }
  s.timing.iterations += it;
  s.timing.residual = rel;
  s.timing.converged = s.timing.converged && rel <= tol;
}

CholmodSolver& lag_factor(State& s, int which) { return which == 0 ? s.solver : s.work.back; }

// Lagged: make the front factor current for this frame (refresh policy).
void lagged_refresh(const Model& m, State& s, Stopwatch& clock) {
  auto& w = s.work;
  const int f = s.frame, k = m.solver.refresh_every;
  if (!s.factor_current) {  // first frame, or the factor was invalidated
    w.wait_job();
    w.job_running = false;
    w.front = 0;
    s.solver.factorize(s.A.data());
    ++s.refactorizations;
    s.factor_current = true;
    w.front_frame = w.last_launch = f;
  } else if (!m.solver.background) {
    if (f - w.front_frame >= k) {
      lag_factor(s, w.front).factorize(s.A.data());
      ++s.refactorizations;
      w.front_frame = f;
    }
  } else {
    if (w.job_running && f - w.job_frame >= k) {
      w.wait_job();  // deterministic: the factor started k frames ago is taken now
      w.job_running = false;
      if (w.job_error) {
        auto e = w.job_error;
        w.job_error = nullptr;
        std::rethrow_exception(e);
      }
      w.front ^= 1;
      w.front_frame = w.job_frame;
      ++s.refactorizations;
    }
    if (!w.job_running && f - w.last_launch >= k) {
      std::copy(s.A.begin(), s.A.end(), w.A_back.begin());
      CholmodSolver* back = &lag_factor(s, w.front ^ 1);
      const double* values = w.A_back.data();
      std::exception_ptr* err = &w.job_error;
      w.job = std::thread([back, values, err] {
        try {
          back->factorize(values);
        } catch (...) {
          *err = std::current_exception();
        }
      });
      w.job_running = true;
      w.job_frame = w.last_launch = f;
    }
  }
  s.timing.ms[kStageFactorization] += clock.lap();
}

void rest_factor(const Model& m, State& s, Stopwatch& clock) {
  if (s.factor_current) return;
  form_matrix(m, m.K0_csc.data(), s.A.data());
  s.solver.factorize(s.A.data());
  ++s.refactorizations;
  s.factor_current = true;
  s.timing.ms[kStageFactorization] += clock.lap();
}

}  // namespace

bool policy_needs_tangent(const Model& m) { return m.solver.policy != SolverPolicy::Warped; }

void prepare_solver(const Model& m, State& s) {
  auto& w = s.work;
  w.wait_job();
  w.job_running = false;
  w.job_error = nullptr;
  const int threads = std::max(1, m.solver.threads);
  if (!w.pool || w.pool->size() != threads) w.pool = std::make_unique<ThreadPool>(threads);
  w.plan = make_assembly_plan(m, threads);
  const int n = m.ndof();
  s.solver.configure(m.solver.factor, m.solver.ordering);
  s.solver.analyze(n, m.Ap, m.Ai);
  if (m.solver.policy == SolverPolicy::Lagged && m.solver.background) {
    w.back.configure(m.solver.factor, m.solver.ordering);
    w.back.analyze(n, m.Ap, m.Ai);
    w.A_back.assign(m.nnz(), 0.0);
  }
  w.front = 0;
  w.front_frame = w.last_launch = w.job_frame = -1;
  for (auto* v : {&w.r, &w.z, &w.p, &w.q, &w.t}) v->assign(n, 0.0);
  // Node -> rotation slot adjacency for the warped policies.
  w.node_rot_ptr.assign(m.ndofnode + 1, 0);
  w.node_rot.clear();
  w.node_rot_weight.clear();
  w.Rn.assign(9 * static_cast<size_t>(m.ndofnode), 0.0);
  for (int node = 0; node < m.ndofnode; ++node) w.Rn[9 * node] = w.Rn[9 * node + 4] = w.Rn[9 * node + 8] = 1.0;
  w.node_identity.assign(m.ndofnode, 0);
  // A node with some but not all components constrained keeps R = I so the
  // warped matrix stays projected; a fully constrained node may rotate (its
  // block is the identity either way).
  for (int node = 0; node < m.ndofnode; ++node) {
    const int c = m.constrained[3 * node] + m.constrained[3 * node + 1] + m.constrained[3 * node + 2];
    w.node_identity[node] = c > 0 && c < 3;
  }
  if (m.solver.policy == SolverPolicy::Warped || m.solver.policy == SolverPolicy::WarpedCG) {
    const auto& ep = w.plan.elem_rot_ptr;
    std::vector<int> count(m.ndofnode + 1, 0);
    for (int e = 0; e < m.nelem; ++e)
      for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k) count[m.elem_dof_node[k] + 1] += ep[e + 1] - ep[e];
    for (int node = 0; node < m.ndofnode; ++node) count[node + 1] += count[node];
    w.node_rot_ptr = count;
    w.node_rot.assign(count.back(), 0);
    w.node_rot_weight.assign(count.back(), 0.0);
    std::vector<int> next(count.begin(), count.end() - 1);
    for (int e = 0; e < m.nelem; ++e) {
      const int nslot = ep[e + 1] - ep[e];
      for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k) {
        const int node = m.elem_dof_node[k];
        for (int j = ep[e]; j < ep[e + 1]; ++j) {
          w.node_rot[next[node]] = w.plan.elem_rot[j];
          w.node_rot_weight[next[node]++] = m.elem_volume[e] / nslot;
        }
      }
    }
  }
  s.factor_current = false;
}

void update_node_rotations(const Model& m, State& s) {
  auto& w = s.work;
  w.pool->run([&](int tid) {
    int b, e;
    ThreadPool::split(m.ndofnode, w.pool->size(), tid, b, e);
    for (int node = b; node < e; ++node) {
      Eigen::Map<Mat3> Rn(&w.Rn[9 * node]);
      if (w.node_identity[node] || w.node_rot_ptr[node] == w.node_rot_ptr[node + 1]) {
        Rn.setIdentity();
        continue;
      }
      Mat3 S = Mat3::Zero();
      for (int k = w.node_rot_ptr[node]; k < w.node_rot_ptr[node + 1]; ++k)
        S += w.node_rot_weight[k] * Eigen::Map<const Mat3>(&s.R[9 * w.node_rot[k]]);
      Mat3 R = Rn;
      extract_rotation(S, R);
      Rn = R;
    }
  });
}

void solve_system(const Model& m, State& s, const double* K, int iteration, Stopwatch& clock) {
  const bool linear = m.material.model == MaterialModel::Linear;
  double* du = s.du.data();
  switch (m.solver.policy) {
    case SolverPolicy::Exact:
      if (!(linear && s.factor_current)) {
        form_matrix(m, K, s.A.data());
        s.timing.ms[kStageAssembly] += clock.lap();
        s.solver.factorize(s.A.data());
        ++s.refactorizations;
        s.factor_current = true;
        s.timing.ms[kStageFactorization] += clock.lap();
      }
      substitute(s, s.solver, s.rhs.data(), du);
      break;
    case SolverPolicy::Lagged:
      form_matrix(m, K, s.A.data());
      s.timing.ms[kStageAssembly] += clock.lap();
      if (iteration == 0 || !s.factor_current) lagged_refresh(m, s, clock);
      pcg(m, s, s.A.data(), s.rhs.data(), du, [&](const double* r, double* z) {
        substitute(s, lag_factor(s, s.work.front), r, z);
      });
      break;
    case SolverPolicy::Warped:
      rest_factor(m, s, clock);
      update_node_rotations(m, s);
      warped_apply(m, s, s.rhs.data(), du);
      break;
    case SolverPolicy::WarpedCG:
      rest_factor(m, s, clock);
      form_matrix(m, K, s.A.data());
      update_node_rotations(m, s);
      s.timing.ms[kStageAssembly] += clock.lap();
      pcg(m, s, s.A.data(), s.rhs.data(), du, [&](const double* r, double* z) { warped_apply(m, s, r, z); });
      break;
  }
  s.timing.ms[kStageSolve] += clock.lap();
}

}  // namespace incise
