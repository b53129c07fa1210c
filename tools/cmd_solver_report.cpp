#include <algorithm>
#include <cstdio>

#include "engine/solve/block_recycler.h"
#include "tools/solver_report.h"

namespace incise {

SolverReport solver_report(const Simulation& sim, const std::vector<FrameTiming>& frames, const TimingSummary& s,
                           double bandwidth_gbs) {
  SolverReport r;
  const Model& m = sim.model;
  const Workspace& st = sim.ws;
  r.policy = policy_name(m.solver.policy);
  r.threads = m.solver.threads;
  // the slot preconditioning at the end (lagged may have moved to `back`)
  const FactorStats& f = (st.work.front == 0 ? st.solver : st.work.back).stats();
  const FactorStats& f0 = st.solver.stats();
  r.nnz_L = f.nnz_L;
  r.flops = f.flops;
  r.factorizations = f0.factorizations + st.work.back.stats().factorizations;
  const double total_ms = f0.factor_ms_total + st.work.back.stats().factor_ms_total;
  if (r.factorizations > 0) r.factor_ms_mean = total_ms / r.factorizations;
  if (r.factor_ms_mean > 0) r.gflops = r.flops / (r.factor_ms_mean * 1e-3) * 1e-9;
  r.single_precision = f.single_precision;
  r.single_factorizations = f0.single_factorizations + st.work.back.stats().single_factorizations;
  r.single_fallbacks = f0.single_fallbacks + st.work.back.stats().single_fallbacks;
  std::vector<double> subs, its;
  double sub_ms = 0;
  long long nsub = 0;
  for (const auto& t : frames) {
    subs.push_back(t.solves);
    its.push_back(t.iterations);
    sub_ms += t.solve_kernel_ms;
    nsub += t.solves;
    if (!t.converged) ++r.not_converged_frames;
    r.rescue_frames += t.rescues > 0;
    r.max_residual = std::max(r.max_residual, t.residual);
  }
  r.substitutions_per_frame = percentiles(subs).median_ms;
  r.iterations = percentiles(its);
  if (nsub > 0) r.substitution_ms = sub_ms / nsub;
  const double bytes = 2.0 * 8.0 * r.nnz_L;
  if (r.substitution_ms > 0) r.solve_gbs = bytes / (r.substitution_ms * 1e-3) * 1e-9;
  r.bandwidth_gbs = bandwidth_gbs;
  r.bandwidth_limit_ms = bytes / (bandwidth_gbs * 1e9) * 1e3;
  if (r.bandwidth_limit_ms > 0) r.frame_multiple = s.frame.median_ms / r.bandwidth_limit_ms;
  return r;
}

std::string format_solver_report(const SolverReport& r) {
  char buf[1024];
  char single[64] = "";
  if (r.single_precision) std::snprintf(single, sizeof single, " (%d in single precision)", r.single_factorizations);
  std::snprintf(buf, sizeof buf,
                "solver: policy %s, %d assembly thread%s\n"
                "factor: nnz(L) %.3g, %.3g Mflop, %d factorization%s%s, mean %.2f ms = %.2f GFLOP/s\n"
                "solve: %.1f substitutions/frame (median), %.2f ms each = %.2f GB/s (L read twice, counted as doubles)\n"
                "frame: median = %.1fx the one-substitution bandwidth limit (%.2f ms at %.1f GB/s)\n",
                r.policy.c_str(), r.threads, r.threads == 1 ? "" : "s", r.nnz_L, r.flops * 1e-6, r.factorizations,
                r.factorizations == 1 ? "" : "s", single, r.factor_ms_mean, r.gflops, r.substitutions_per_frame,
                r.substitution_ms, r.solve_gbs, r.frame_multiple, r.bandwidth_limit_ms, r.bandwidth_gbs);
  std::string out = buf;
  if (r.single_fallbacks > 0) {
    std::snprintf(buf, sizeof buf, "factor: %d single-precision factorization%s met a pivot that was not positive and %s redone by CHOLMOD in double\n",
                  r.single_fallbacks, r.single_fallbacks == 1 ? "" : "s", r.single_fallbacks == 1 ? "was" : "were");
    out += buf;
  }
  const RecyclerStats rs = cholmod_block_recycler_stats();
  if (rs.reused + rs.grown + rs.fresh > 0) {
    std::snprintf(buf, sizeof buf,
                  "memory: CHOLMOD blocks >= 1 MiB since start: %ld reused, %ld grown, %ld newly allocated\n",
                  rs.reused, rs.grown, rs.fresh);
    out += buf;
  }
  if (r.policy == "lagged" || r.policy == "warped_cg") {
    std::snprintf(buf, sizeof buf, "CG: iterations/frame median %.0f, p99 %.0f, max %.0f; %d frame%s not converged (max residual %.2g)\n",
                  r.iterations.median_ms, r.iterations.p99_ms, r.iterations.max_ms, r.not_converged_frames,
                  r.not_converged_frames == 1 ? "" : "s", r.max_residual);
    out += buf;
    if (r.rescue_frames > 0) {
      std::snprintf(buf, sizeof buf, "rescues: %d frame%s factored the current matrix after solver.rescue_after CG iterations\n",
                    r.rescue_frames, r.rescue_frames == 1 ? "" : "s");
      out += buf;
    }
  }
  return out;
}

nlohmann::json solver_report_json(const SolverReport& r) {
  return {{"policy", r.policy},
          {"threads", r.threads},
          {"iterations", {{"median", r.iterations.median_ms}, {"p99", r.iterations.p99_ms}, {"max", r.iterations.max_ms}}},
          {"not_converged_frames", r.not_converged_frames},
          {"rescue_frames", r.rescue_frames},
          {"max_residual", r.max_residual},
          {"substitutions_per_frame", r.substitutions_per_frame},
          {"substitution_ms", r.substitution_ms},
          {"solve_gbs", r.solve_gbs},
          {"factorizations", r.factorizations},
          {"factor_ms_mean", r.factor_ms_mean},
          {"gflops", r.gflops},
          {"single_precision_factorization", r.single_precision},
          {"single_precision_factorizations", r.single_factorizations},
          {"single_precision_fallbacks", r.single_fallbacks},
          {"bandwidth_gbs", r.bandwidth_gbs},
          {"bandwidth_limit_ms", r.bandwidth_limit_ms},
          {"frame_bandwidth_multiple", r.frame_multiple}};
}

}  // namespace incise

#include <CLI/CLI.hpp>

#include "engine/util/error.h"
#include "engine/dynamics/step.h"

namespace incise {

void add_solver_options(void* cli_app, SolverOverrides& o, bool with_policy) {
  auto* cmd = static_cast<CLI::App*>(cli_app);
  if (with_policy)
    cmd->add_option("--policy", o.policy, "Solver policy (overrides solver.policy)")
        ->check(CLI::IsMember({"exact", "lagged", "warped", "warped_cg"}));
  cmd->add_option("--tolerance", o.tolerance, "CG relative tolerance (lagged, warped_cg)")->check(CLI::Range(1e-300, 0.999));
  cmd->add_option("--max-iterations", o.max_iterations, "CG iterations per solve")->check(CLI::PositiveNumber);
  cmd->add_option("--refresh-every", o.refresh_every, "lagged: refactor every K frames")->check(CLI::PositiveNumber);
  cmd->add_flag("--background", o.background, "lagged: factorize on a second thread");
  cmd->add_option("--rescue-after", o.rescue_after,
                  "lagged: after N CG iterations factor the current matrix now and finish with it (0 = never)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--late-factor", o.late_factor,
                  "lagged, background: wait for a late factor (deterministic) or skip it until it is ready")
      ->check(CLI::IsMember({"wait", "skip"}));
  cmd->add_option("--patch", o.patch,
                  "lagged after cuts: combine the lagged factor with the patch of new DOFs additively or multiplicatively")
      ->check(CLI::IsMember({"additive", "multiplicative"}));
  cmd->add_option("--cut-ordering", o.cut_ordering,
                  "lagged, background, while cutting: analyze each new pattern with a carried-over ordering or search one")
      ->check(CLI::IsMember({"search", "carried"}));
  cmd->add_option("--background-priority", o.background_priority,
                  "lagged, background: run the background factorization at idle priority (the default) or normal")
      ->check(CLI::IsMember({"idle", "normal"}));
  cmd->add_option("--affinity", o.affinity,
                  "none: the kernel places the threads; split: the stepping thread gets a CPU of its own, the cut-ahead "
                  "helper and the background factorization the others (solver.affinity)")
      ->check(CLI::IsMember({"none", "split"}));
  cmd->add_flag("--warp", o.warp, "lagged: rotate the lagged factor by the node rotations since its frame");
  cmd->add_option("--single-precision", o.single_precision, "lagged: float copy of the factor for the substitutions")
      ->check(CLI::IsMember({"true", "false"}));
  cmd->add_option("--factor-copy", o.factor_copy,
                  "lagged: the factor copy the preconditioner substitutes with (none = CHOLMOD's doubles; half = binary16 "
                  "scaled per supernode)")
      ->check(CLI::IsMember({"none", "float", "half"}));
  cmd->add_option("--factor-precision", o.factor_precision,
                  "lagged: factor in double (CHOLMOD, then the copy) or in single precision straight into the float "
                  "copy (solver.factor_precision)")
      ->check(CLI::IsMember({"double", "single"}));
  cmd->add_option("--initial-guess", o.initial_guess,
                  "CG's start in the first Newton iteration: zero, or the last frame's increment scaled to the best "
                  "fit (solver.initial_guess)")
      ->check(CLI::IsMember({"zero", "previous"}));
  cmd->add_option("--threads", o.threads, "Assembly worker threads (solver.threads)")->check(CLI::Range(1, 64));
  cmd->add_option("--tangent-reuse", o.tangent_reuse,
                  "integrator.tangent_reuse of the policy runs: keep an element's tangent while its F moves less than "
                  "this (compare's exact reference keeps the scene's)")
      ->check(CLI::Range(0.0, 0.4999));
  cmd->add_option("--substitution-threads", o.substitution_threads,
                  "Threads of each substitution with a supernodal factor (solver.substitution_threads)")
      ->check(CLI::Range(1, 2));
  cmd->add_option("--factorization", o.factorization, "CHOLMOD method")
      ->check(CLI::IsMember({"auto", "supernodal", "simplicial"}));
  cmd->add_option("--ordering", o.ordering, "Fill-reducing ordering")->check(CLI::IsMember({"auto", "amd", "metis"}));
}

void apply_solver_overrides(Simulation& sim, const SolverOverrides& o) {
  // The scene's settings too: a cut rebuilds the model from the scene.
  SolverSettings& s = sim.scene.solver;
  if (!o.policy.empty()) {
    const char* names[] = {"exact", "lagged", "warped", "warped_cg"};
    for (int k = 0; k < 4; ++k)
      if (o.policy == names[k]) s.policy = static_cast<SolverPolicy>(k);
  }
  if (o.tolerance > 0) s.tolerance = o.tolerance;
  if (o.max_iterations > 0) s.max_iterations = o.max_iterations;
  if (o.refresh_every > 0) s.refresh_every = o.refresh_every;
  if (o.background) s.background = true;
  if (o.rescue_after >= 0) s.rescue_after = o.rescue_after;
  if (!o.late_factor.empty()) s.skip_late_factor = o.late_factor == "skip";
  if (!o.patch.empty()) s.multiplicative_patch = o.patch == "multiplicative";
  if (!o.cut_ordering.empty()) s.carry_ordering = o.cut_ordering == "carried";
  if (!o.background_priority.empty()) s.idle_background = o.background_priority == "idle";
  if (!o.affinity.empty()) s.split_affinity = o.affinity == "split";
  if (o.warp) s.warp = true;
  if (o.single_precision == "true") s.factor_copy = FactorCopy::Float;
  if (o.single_precision == "false") s.factor_copy = FactorCopy::None;
  if (!o.factor_copy.empty())
    s.factor_copy = o.factor_copy == "half" ? FactorCopy::Half : o.factor_copy == "float" ? FactorCopy::Float : FactorCopy::None;
  if (!o.initial_guess.empty()) s.previous_guess = o.initial_guess == "previous";
  if (!o.factor_precision.empty()) s.single_factorization = o.factor_precision == "single";
  if (s.single_factorization && s.factor_copy != FactorCopy::Float)
    throw Error("--factor-precision single factors straight into the float copy: it needs --factor-copy float");
  if (!o.factorization.empty() && o.factorization == "simplicial" && s.single_factorization)
    throw Error("--factor-precision single factors supernodes: it cannot go with --factorization simplicial");
  if (o.threads > 0) s.threads = o.threads;
  if (o.substitution_threads > 0) s.substitution_threads = o.substitution_threads;
  if (o.tangent_reuse >= 0) sim.scene.tangent_reuse = sim.model.tangent_reuse = o.tangent_reuse;
  if (!o.factorization.empty())
    s.factor = o.factorization == "simplicial" ? FactorMethod::Simplicial
               : o.factorization == "supernodal" ? FactorMethod::Supernodal
                                                 : FactorMethod::Auto;
  if (!o.ordering.empty())
    s.ordering = o.ordering == "amd" ? OrderingMethod::Amd : o.ordering == "metis" ? OrderingMethod::Metis : OrderingMethod::Auto;
  sim.model.solver = s;
  if (model_needs_rest_stiffness(sim.model) && sim.model.K0_csc.empty()) sim.model.K0_csc = rest_stiffness(sim.model);
  init_state(sim.model, sim.state, sim.ws);
}

}  // namespace incise
