#include "engine/dynamics/static_solve.h"

#include "engine/solve/linear_solve.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "engine/fem/assemble.h"
#include "engine/fem/assemble_parallel.h"
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
  const std::vector<double> load = static_gravity_load(m);  // f_gravity but on slivers' enriched DOFs
  double fext = 0.0;
  for (int d = 0; d < n; ++d)
    if (!m.constrained[d]) fext += load[d] * load[d];
  fext = std::sqrt(fext);
  StaticResult res;
  double ref = 0.0;
  // Workspace::solver must hold this pattern, and no background factorization may
  // run beside ours (unsafe with a serial OpenBLAS, blas_concurrency_safe): a
  // lagged dynamics state is reset.
  if (ws.work.job_running || ws.work.slot_pattern[0] != ws.work.pattern) prepare_solver(m, ws, s.frame);
  // The consistent tangent whatever integrator.tangent says: a plan of our own.
  AssemblyPlan plan;
  if (!linear) {
    plan = make_assembly_plan(m, ws.work.pool->size());
    plan.qp_own_rot = point_rotation_flags(m, true);
    plan.slot_weight = shared_slot_weights(m, true);
    plan.exact_rotation_term = true;
  }
  // Free residual f_ext - f_int(u) into ws.rhs and its norm; K (nnz) when asked.
  int fallbacks = 0;
  double shift = 0.0;  // relative raise of the enriched DOFs' diagonals, once one was needed
  const auto residual_at = [&](const double* u, bool tangent) {
    if (linear) {
      internal_forces(m, s, ws, u, false);
    } else {
      fallbacks = assemble_corotated(m, plan, *ws.work.pool, u, s.R.data(), ws.f_int.data(),
                                     tangent ? ws.K.data() : nullptr);
    }
    double r2 = 0.0;
    for (int d = 0; d < n; ++d) {
      ws.rhs[d] = m.constrained[d] ? 0.0 : load[d] - ws.f_int[d];
      r2 += ws.rhs[d] * ws.rhs[d];
    }
    return std::sqrt(r2);
  };
  double* trial = ws.tmp.data();
  double r = residual_at(s.u.data(), true);
  for (int it = 0; it <= max_iterations; ++it) {
    if (!std::isfinite(r)) {
      long bad = -1;  // the first DOF whose residual is not finite, else the largest (its square overflowed)
      for (int d = 0; d < n && bad < 0; ++d)
        if (!std::isfinite(ws.rhs[d])) bad = d;
      if (bad < 0 && n > 0) {
        bad = 0;
        for (int d = 1; d < n; ++d)
          if (std::abs(ws.rhs[d]) > std::abs(ws.rhs[bad])) bad = d;
      }
      throw NumericalError("static: non-finite residual at iteration " + std::to_string(it) +
                               (bad >= 0 ? " at DOF " + std::to_string(bad) : std::string()),
                           bad);
    }
    if (it == 0) ref = std::max(fext, r);
    res.iterations = it;
    res.residual = ref > 0 ? r / ref : 0.0;
    res.residuals.push_back(res.residual);
    if (res.residual <= tolerance) {
      res.converged = true;
      break;
    }
    if (it == max_iterations) break;
    if (!(linear && ws.factor_current)) {
      const auto factorize = [&](double shift) {
        const double* K = linear ? m.K0_csc.data() : ws.K.data();
        std::copy(K, K + m.nnz(), ws.A.begin());
        ws.A_generation = 0;
        for (int d = 3 * m.nnode; d < n && shift > 0.0; ++d) ws.A[m.diag[d]] *= 1.0 + shift;
        project_constraints(m, ws.A.data());
        ws.solver.factorize(ws.A.data());
        ++ws.refactorizations;
      };
      // The exact tangent first. Where Cholesky fails: with enrichment, the
      // same with the enriched DOFs' diagonals raised (kept for the later
      // iterations), then the projected tangent. Singular to roundoff: a
      // sliver's enriched DOFs (a cut within 1e-7 h of a node layer) have
      // modes of energy (thickness)^3 beside diagonals of order thickness.
      // A raise of kStaticEnrichedShift changes the step, not the residual
      // (static_gravity_load leaves those modes unloaded), so the solve still
      // converges. Indefinite: compressed rotation modes outweigh the rest
      // (near inversion, a buckling load); the projected tangent is positive
      // semi-definite.
      const auto factorized = [&](double sh) {
        try {
          factorize(sh);
          return true;
        } catch (const Error&) {
          if (linear) throw;
          return false;
        }
      };
      const bool can_shift = m.ndofnode > m.nnode && shift == 0.0;
      const auto shifted = [&] {
        if (!can_shift || !factorized(kStaticEnrichedShift)) return false;
        shift = kStaticEnrichedShift;
        res.shifted = 1;
        return true;
      };
      if (!factorized(shift) && !shifted()) {
        plan.exact_rotation_term = false;
        residual_at(s.u.data(), true);
        plan.exact_rotation_term = true;
        ++res.projected;
        if (!factorized(shift) && !shifted()) factorize(shift);  // throws: CHOLMOD's message names the DOF
      }
      ws.factor_current = linear;
    }
    ws.solver.solve(ws.rhs.data(), ws.du.data());
    for (int d = 0; d < n; ++d)
      if (!std::isfinite(ws.du[d]))
        throw NumericalError("static: non-finite Newton step at iteration " + std::to_string(it) + " at DOF " +
                                 std::to_string(d) + " (a singular tangent: a piece held by nothing?)",
                             d);
    // Backtracking on the total potential energy Pi(u) = U(u) - f_ext . u
    // (U: the corotated elastic energy, elastic_energy; -r its gradient on
    // the free DOFs): the full step, then halves until Pi drops by at least
    // 1e-4 alpha du . r (Armijo), or the residual norm drops (near the
    // solution Pi's change, O(r^2), is below its roundoff). The residual norm
    // alone is no merit: on a cantilever the Newton path raises it for an
    // iteration where the energy falls. Where no length passes (a step into
    // inversion), the shortest is taken and counted.
    double slope = 0.0;  // du . r = -dPi/dalpha at 0
    for (int d = 0; d < n; ++d) slope += ws.du[d] * ws.rhs[d];
    const auto energy_at = [&](const double* u) {  // after residual_at(u): s.R holds u's rotations
      double w = 0.0;
      for (int d = 0; d < n; ++d) w += load[d] * u[d];
      return elastic_energy(m, u, s.R.data()) - w;
    };
    double alpha = 1.0, r_new = 0.0;
    const bool search = !linear && slope > 0.0;
    double pi0 = 0.0;
    if (search) pi0 = energy_at(s.u.data());  // s.R: u's rotations (its tangent's assembly)
    // The full step is assembled with its tangent: taken (the usual case),
    // that is the next iteration's, and its forces are not computed twice.
    bool tangent_at_trial = false;
    for (int h = 0;; ++h) {
      for (int d = 0; d < n; ++d) trial[d] = s.u[d] + alpha * ws.du[d];
      tangent_at_trial = h == 0;
      r_new = residual_at(trial, tangent_at_trial);
      if (!search || (std::isfinite(r_new) && (r_new < r || energy_at(trial) <= pi0 - 1e-4 * alpha * slope))) break;
      if (h == kStaticLineSearchHalvings) {
        ++res.stalled;
        break;
      }
      alpha *= 0.5;
    }
    if (alpha < 1.0) ++res.shortened;
    res.smallest_step = std::min(res.smallest_step, alpha);
    std::copy(trial, trial + n, s.u.begin());
    // A shortened step: the tangent at the new point (ws.rhs holds its residual already).
    r = tangent_at_trial ? r_new : residual_at(s.u.data(), true);
  }
  res.inverted_points = fallbacks;
  ws.factor_current = false;  // the factor held K, not a dynamics matrix
  return res;
}

std::string static_report(const StaticResult& r) {
  std::string out = "Newton (consistent tangent): residuals";
  char buf[96];
  for (double x : r.residuals) {
    std::snprintf(buf, sizeof buf, " %.1e", x);
    out += buf;
  }
  std::snprintf(buf, sizeof buf, "; line search shortened %d step(s) (shortest %g), %d without descent", r.shortened,
                r.smallest_step, r.stalled);
  out += buf;
  if (r.projected > 0) out += "; " + std::to_string(r.projected) + " iteration(s) on the projected tangent (exact one indefinite)";
  if (r.shifted > 0) out += "; enriched DOFs' diagonals raised by 1e-10 (a singular sliver)";
  if (r.inverted_points > 0) out += "; " + std::to_string(r.inverted_points) + " inverted cubature point(s) at the end";
  return out;
}

std::string static_failure_advice(const StaticResult& r) {
  const std::vector<double>& h = r.residuals;
  const size_t n = h.size();
  if (n < 4) return "raise static.max_iterations or loosen static.tolerance";
  const size_t half = n / 2;
  const double early = *std::min_element(h.begin(), h.begin() + static_cast<std::ptrdiff_t>(half));
  const double late = *std::min_element(h.begin() + static_cast<std::ptrdiff_t>(half), h.end());
  if (late < 0.1 * early) return "raise static.max_iterations (the residual is still falling) or loosen static.tolerance";
  char buf[256];
  if (late < 1e-5)
    std::snprintf(buf, sizeof buf,
                  "the residual stopped falling at %.1e, near double precision's floor for this body (its internal "
                  "forces cancel to roundoff there): loosen static.tolerance to about %.0e; more iterations do not help",
                  late, 4 * late);
  else
    std::snprintf(buf, sizeof buf,
                  "the residual stopped falling at %.1e: no equilibrium was found near the start (a load too large "
                  "for the material, a buckling or an unsupported piece); more iterations do not help",
                  late);
  return buf;
}

void start_at_static_equilibrium(const Model& m, State& s, Workspace& ws, double tolerance, int max_iterations,
                                 const std::string& scene_path) {
  const StaticResult r = solve_static(m, s, ws, tolerance, max_iterations, s.time);
  if (!r.converged) {
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  ": initial \"static\": the static solve did not reach static.tolerance %g in %d iterations "
                  "(relative residual %g); ",
                  tolerance, r.iterations, r.residual);
    throw Error(scene_path + buf + static_failure_advice(r) + "; or start from rest (initial \"rest\")");
  }
  std::fill(s.v.begin(), s.v.end(), 0.0);
  consistent_acceleration(m, s, ws);  // M a = f_ext - f_int(u): the residual the solve left, ~0
}

}  // namespace incise
