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
  r.threads = sim.ws.runtime.threads;
  // the slot preconditioning at the end (lagged may have moved to another)
  const FactorStats& f = st.slot(st.work.front).stats();
  r.nnz_L = f.nnz_L;
  r.flops = f.flops;
  double total_ms = 0;
  for (int k = 0; k < SolverWork::kSlots; ++k) {
    const FactorStats& fk = st.slot(k).stats();
    r.factorizations += fk.factorizations;
    total_ms += fk.factor_ms_total;
    r.single_factorizations += fk.single_factorizations;
    r.single_fallbacks += fk.single_fallbacks;
  }
  if (r.factorizations > 0) r.factor_ms_mean = total_ms / r.factorizations;
  if (r.factor_ms_mean > 0) r.gflops = r.flops / (r.factor_ms_mean * 1e-3) * 1e-9;
  r.single_precision = f.single_precision;
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
    r.capped_frames += t.newton_capped;
    r.recovery_frames += t.recovery;
    if (t.budget_spent) {
      ++r.budget_frames;
      r.max_budget_residual = std::max(r.max_budget_residual, t.residual);
    }
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
  if (r.capped_frames + r.recovery_frames > 0) {
    std::snprintf(buf, sizeof buf,
                  "newton: %d frame%s stopped with the rotations still moving (at integrator.max_newton_iterations, "
                  "or in a severed piece under integrator.rotation_fraction of the tissue); "
                  "%d recovery step%s (backward Euler, integrator.recovery; docs/numerics.md)\n",
                  r.capped_frames, r.capped_frames == 1 ? "" : "s", r.recovery_frames, r.recovery_frames == 1 ? "" : "s");
    out += buf;
  }
  if (r.policy == "lagged" || r.policy == "warped_cg") {
    std::snprintf(buf, sizeof buf, "CG: iterations/frame median %.0f, p99 %.0f, max %.0f; %d frame%s not converged (max residual %.2g)\n",
                  r.iterations.median_ms, r.iterations.p99_ms, r.iterations.max_ms, r.not_converged_frames,
                  r.not_converged_frames == 1 ? "" : "s", r.max_residual);
    out += buf;
    if (r.budget_frames > 0) {
      std::snprintf(buf, sizeof buf, "budget: %d frame%s spent solver.frame_iterations and took the residual they had (max %.2g)\n",
                    r.budget_frames, r.budget_frames == 1 ? "" : "s", r.max_budget_residual);
      out += buf;
    }
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
          {"budget_frames", r.budget_frames},
          {"capped_frames", r.capped_frames},
          {"recovery_frames", r.recovery_frames},
          {"max_budget_residual", r.max_budget_residual},
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

namespace incise {

std::string format_resolved_settings(const Scene& s) {
  std::string out = "settings";
  if (!s.preset.empty()) out += " (solver.preset \"" + s.preset + "\")";
  out += ": [preset], [scene], [--set] or the flag that set a value; unmarked: the default\n";
  std::string section, line;
  auto flush = [&] {
    if (!line.empty()) out += line + "\n";
    line.clear();
  };
  for (const ResolvedSetting& r : resolved_settings(s)) {
    const size_t dot = r.key.find('.');
    const std::string sec = r.key.substr(0, dot), name = r.key.substr(dot + 1);
    std::string item = name + " " + r.value;
    switch (r.origin.kind) {
      case SettingOrigin::Kind::Default: break;
      case SettingOrigin::Kind::Scene: item += " [scene]"; break;
      case SettingOrigin::Kind::Preset: item += " [preset]"; break;
      case SettingOrigin::Kind::Patch: {
        const std::string& g = r.origin.detail;
        // "--set solver.x=1" -> [--set], "--policy lagged" -> [--policy], "compare reference: ..." -> [compare reference]
        item += " [" + (g.rfind("--", 0) == 0 ? g.substr(0, g.find(' ')) : g.substr(0, g.find(':'))) + "]";
        break;
      }
    }
    if (sec != section) {
      flush();
      section = sec;
      line = "  " + sec + ": " + item;
    } else if (line.size() + item.size() + 2 > 110) {
      out += line + ",\n";
      line = std::string(4 + sec.size(), ' ') + item;
    } else {
      line += ", " + item;
    }
  }
  flush();
  return out;
}

void add_set_option(CLI::App& cmd, std::vector<ScenePatch>& patches) {
  cmd.add_option_function<std::string>(
         "--set", [&patches](const std::string& text) { patches.push_back(parse_scene_patch(text)); },
         "Override a scene key before the scene is parsed, e.g. --set solver.preset=realtime, --set integrator.dt=0.01, "
         "--set cuts.0.at_time=0.5 (repeatable; the value is JSON when it parses as JSON, else a string; null removes "
         "the key)")
      ->trigger_on_parse()
      ->type_name("KEY=VALUE");
}

void add_solver_aliases(CLI::App& cmd, std::vector<ScenePatch>& patches, bool with_policy) {
  struct Alias {
    const char* flag;
    const char* key;
    const char* help;
  };
  static const Alias options[] = {
      {"--policy", "solver.policy", "exact, lagged, warped or warped_cg"},
      {"--tolerance", "solver.tolerance", "CG relative tolerance (lagged, warped_cg)"},
      {"--max-iterations", "solver.max_iterations", "CG iterations per solve"},
      {"--refresh-every", "solver.refresh_every", "lagged: refactor every K frames"},
      {"--rescue-after", "solver.rescue_after", "lagged: after N CG iterations factor the current matrix now (0 = never)"},
      {"--late-factor", "solver.late_factor", "lagged, background: wait or skip"},
      {"--patch", "solver.patch", "lagged after cuts: additive or multiplicative"},
      {"--cut-ordering", "solver.cut_ordering", "lagged, background, while cutting: search or carried"},
      {"--background-priority", "solver.background_priority", "lagged, background: idle or normal"},
      {"--affinity", "solver.affinity", "none or split"},
      {"--single-precision", "solver.single_precision", "lagged: true (float factor copy) or false"},
      {"--factor-copy", "solver.factor_copy", "lagged: none, float or half"},
      {"--factor-precision", "solver.factor_precision", "lagged: double or single"},
      {"--initial-guess", "solver.initial_guess", "CG's start: zero or previous"},
      {"--threads", "solver.threads", "assembly worker threads"},
      {"--tangent-reuse", "integrator.tangent_reuse",
       "keep an element's tangent while its F moves less than this (compare's exact reference: 0)"},
      {"--substitution-threads", "solver.substitution_threads", "1 or 2"},
      {"--factorization", "solver.factorization", "auto, supernodal or simplicial"},
      {"--ordering", "solver.ordering", "auto, amd or metis"},
  };
  for (const Alias& a : options) {
    if (!with_policy && std::string(a.flag) == "--policy") continue;
    const std::string flag = a.flag, key = a.key;
    cmd.add_option_function<std::string>(
           flag, [&patches, flag, key](const std::string& v) { patches.push_back({key, v, flag + " " + v}); },
           std::string("= --set ") + a.key + "=VALUE: " + a.help)
        ->trigger_on_parse();
  }
  static const Alias flags[] = {{"--background", "solver.background", "lagged: factorize on a second thread"},
                                {"--warp", "solver.warp", "lagged: rotate the lagged factor by the node rotations"}};
  for (const Alias& a : flags) {
    const std::string flag = a.flag, key = a.key;
    cmd.add_flag_function(
           flag, [&patches, flag, key](std::int64_t) { patches.push_back({key, "true", flag}); },
           std::string("= --set ") + a.key + "=true: " + a.help)
        ->trigger_on_parse();
  }
}

}  // namespace incise
