#include <cstdio>

#include "engine/runtime/simulation.h"
#include "engine/runtime/thread_affinity.h"
#include "tools/commands.h"
#include "tools/solver_report.h"

namespace incise {

void print_model_summary(const Simulation& sim) {
  const Model& m = sim.model;
  const FactorStats& f = sim.ws.solver.stats();
  const char* elem = m.mesh.order == 2 ? (m.material.rotation == RotationMode::Single ? "tet10SR" : "tet10") : "tet4";
  std::printf("scene %s\n", sim.scene.path.c_str());
  std::printf("  mesh %s: %d nodes, %d %s elements, %d DOF, %s %s, %s mass\n", sim.scene.mesh_file.c_str(), m.nnode,
              m.nelem, elem, m.ndof(), m.material.model == MaterialModel::Linear ? "linear" : "corotated",
              m.mesh.order == 2 && m.material.rotation == RotationMode::PerPoint ? "(rotation per cubature point)" : "",
              m.mass_kind == MassKind::Lumped ? "lumped" : "consistent");
  if (m.ndofnode > m.nnode)
    std::printf("  X-FEM: %d enriched DOF nodes (%d DOF) appended after the %d standard DOF\n", m.ndofnode - m.nnode,
                3 * (m.ndofnode - m.nnode), 3 * m.nnode);
  std::printf("  constraints: %zu fixed DOF, %zu prescribed DOF; dt %.6g s, %d Newton iteration(s) per step%s\n",
              m.fixed_dofs.size(), m.prescribed.size(), m.dt, m.newton_iterations,
              !m.adaptive_newton()           ? ""
              : m.residual_tolerance > 0 ? " (more, up to integrator.max_newton_iterations, while rotations move > "
                                           "rotation_tolerance over the body or the residual is above residual_tolerance)"
                                         : " (more, up to integrator.max_newton_iterations, while rotations move > rotation_tolerance over the body)");
  if (sim.scene.initial_static)
    std::printf("  initial: static equilibrium at t = 0 (solved at set-up, static.tolerance %g)\n", sim.scene.static_tolerance);
  if (m.material.model == MaterialModel::Corotated && m.material.rayleigh_stiffness == 0.0 &&
      m.newton_iterations == 1 && m.material.poisson > 0.49)
    std::printf("  warning: undamped corotated tissue with nu > 0.49 and one linearised solve per step can gain\n"
                "  energy at large dt; set material.rayleigh.stiffness (1e-4 s is enough) or more Newton iterations\n");
  // Measured on organ_instruments (its probe and scalpel, 90 frames) under
  // lagged, since small cut pieces integrate over their element
  // (docs/cutting.md, "Small pieces"): nu 0.49-0.497 held with either
  // tangent; 0.498 diverged (frozen_rotation) or reached 846 inverted points
  // and 696 N of contact force (consistent), 0.499 up to 7265 and 1.4 kN.
  // Under the reference preset (exact) 0.499 kept 1.3 N. docs/scene-format.md.
  bool cuts = !sim.scene.cuts.empty();
  for (const InstrumentSpec& ins : sim.scene.instruments) cuts = cuts || ins.kind == InstrumentSpec::Kind::Scalpel;
  if (m.material.model == MaterialModel::Corotated && m.material.poisson > 0.495 && cuts &&
      m.solver.policy != SolverPolicy::Exact)
    std::printf("  warning: near-incompressible tissue (material.poisson %g > 0.495) cut under solver.policy %s was\n"
                "  measured unstable from 0.498 (cut pieces spinning, hundreds of inverted points): use solver.preset\n"
                "  \"reference\" for such scenes (docs/scene-format.md, \"Which keys to set\")\n",
                m.material.poisson, policy_name(m.solver.policy));
  if (m.material.model == MaterialModel::Corotated && m.increment_predictor && !m.consistent_tangent &&
      !m.adaptive_newton())
    std::printf("  warning: integrator.predictor \"increment\" with the frozen-rotation tangent and a fixed number of\n"
                "  Newton iterations linearises half a step behind; a swinging body can gain energy (the default beam\n"
                "  scene diverged at frame 61 with one iteration): set integrator.tangent \"consistent\",\n"
                "  rotation_tolerance > 0, or predictor \"velocity\"\n");
  std::printf("  CHOLMOD %s, ordering %s: nnz(A) %d, nnz(L) %.0f, %.3g Mflop per factorization; setup %.1f ms\n",
              f.supernodal ? "supernodal" : "simplicial", f.ordering.c_str(), m.nnz(), f.nnz_L, f.flops * 1e-6,
              sim.setup_ms);
  const SolverSettings& o = m.solver;
  const RuntimeSettings& rt = sim.ws.runtime;
  std::printf("  solver.policy %s, %d assembly thread(s)", policy_name(o.policy), rt.threads);
  if (rt.substitution_threads > 1) std::printf(", substitutions on %d threads", rt.substitution_threads);
  if (m.tangent_reuse > 0) std::printf(", element tangents kept while F moves < %g", m.tangent_reuse);
  if (o.policy == SolverPolicy::Lagged || o.policy == SolverPolicy::WarpedCG)
    std::printf(", CG tolerance %.3g, max %d iterations, starting from %s", o.tolerance, o.max_iterations,
                o.previous_guess ? "the last frame's increment" : "zero");
  if (o.policy == SolverPolicy::Lagged)
    std::printf(", refresh every %d frame(s)%s%s%s", o.refresh_every,
                o.background ? (rt.idle_background && o.skip_late_factor ? " on a background thread at idle priority"
                                                                         : " on a background thread")
                             : "",
                o.warp ? ", warped by the node rotations since" : "",
                o.single_factorization && o.factor_copy == FactorCopy::Half ? ", factored in single precision, half-precision copy"
                : o.single_factorization                                    ? ", factored in single precision"
                : o.factor_copy == FactorCopy::Float                        ? ", float factor copy"
                : o.factor_copy == FactorCopy::Half                         ? ", half-precision factor copy"
                                                                            : "");
  if (o.policy == SolverPolicy::Lagged && o.background && o.skip_late_factor) std::printf(", late factors skipped");
  if (o.policy == SolverPolicy::Lagged && !sim.scene.cuts.empty())
    std::printf(", %s patch after cuts%s", o.multiplicative_patch ? "multiplicative" : "additive",
                !o.background ? "" : o.carry_ordering ? ", carried ordering while cutting" : ", searched ordering while cutting");
  if (o.policy == SolverPolicy::Lagged && o.rescue_after > 0)
    std::printf(", rescue after %d CG iterations", o.rescue_after);
  if (rt.split_affinity && stepping_cpu() >= 0)
    std::printf(", stepping thread on CPU %d, helpers on the others", stepping_cpu());
  else if (rt.split_affinity)
    std::printf(", affinity split not applied (fewer than two CPUs)");
  std::printf("\n");
  std::printf("%s", format_resolved_settings(sim.scene).c_str());
}

}  // namespace incise
