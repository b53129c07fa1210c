#include "engine/dynamics/static_solve.h"

#include "engine/solve/linear_solve.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "engine/fem/assemble.h"
#include "engine/util/error.h"
#include "engine/dynamics/step.h"

namespace incise {

StaticResult solve_static(const Model& m, State& s, Workspace& ws, double tolerance, int max_iterations, double time) {
  const int n = m.ndof();
  const bool linear = m.material.model == MaterialModel::Linear;
  ws.work.wait_job();  // a lagged policy's background factorization may use ws.solver
  ws.work.job_running = false;
  for (int d : m.fixed_dofs) s.u[d] = 0.0;
  for (const auto& p : m.prescribed) s.u[p.dof] = time >= 0.0 ? m.prescribed_value(p, time) : p.value;
  double fext = 0.0;
  for (int d = 0; d < n; ++d)
    if (!m.constrained[d]) fext += m.f_gravity[d] * m.f_gravity[d];
  fext = std::sqrt(fext);
  StaticResult res;
  double ref = 0.0;
  // Workspace::solver must hold this pattern, and no background factorization may
  // run beside ours (unsafe with a serial OpenBLAS, blas_concurrency_safe): a
  // lagged dynamics state is reset.
  if (ws.work.job_running || ws.work.slot_pattern[0] != ws.work.pattern) prepare_solver(m, ws, s.frame);
  for (int it = 0; it <= max_iterations; ++it) {
    const double* K = internal_forces(m, s, ws, s.u.data(), true);
    double r2 = 0.0;
    for (int d = 0; d < n; ++d) {
      ws.rhs[d] = m.constrained[d] ? 0.0 : m.f_gravity[d] - ws.f_int[d];
      r2 += ws.rhs[d] * ws.rhs[d];
    }
    const double r = std::sqrt(r2);
    if (!std::isfinite(r)) throw Error("static: non-finite residual at iteration " + std::to_string(it));
    if (it == 0) ref = std::max(fext, r);
    res.iterations = it;
    res.residual = ref > 0 ? r / ref : 0.0;
    if (res.residual <= tolerance) {
      res.converged = true;
      break;
    }
    if (it == max_iterations) break;
    if (!(linear && ws.factor_current)) {
      std::copy(K, K + m.nnz(), ws.A.begin());
      project_constraints(m, ws.A.data());
      ws.solver.factorize(ws.A.data());
      ++ws.refactorizations;
      ws.factor_current = linear;
    }
    ws.solver.solve(ws.rhs.data(), ws.du.data());
    for (int d = 0; d < n; ++d) s.u[d] += ws.du[d];
  }
  ws.factor_current = false;  // the factor held K, not a dynamics matrix
  return res;
}

void start_at_static_equilibrium(const Model& m, State& s, Workspace& ws, double tolerance, int max_iterations,
                                 const std::string& scene_path) {
  const StaticResult r = solve_static(m, s, ws, tolerance, max_iterations, s.time);
  if (!r.converged) {
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  ": initial \"static\": the static solve did not reach static.tolerance %g in %d iterations "
                  "(relative residual %g); raise static.max_iterations or static.tolerance, or start from rest "
                  "(initial \"rest\")",
                  tolerance, r.iterations, r.residual);
    throw Error(scene_path + buf);
  }
  std::fill(s.v.begin(), s.v.end(), 0.0);
  consistent_acceleration(m, s, ws);  // M a = f_ext - f_int(u): the residual the solve left, ~0
}

}  // namespace incise
