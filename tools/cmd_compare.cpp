// incise compare: run a scene under the exact policy and under another policy
// side by side and print the relative L2 difference of the displacement field
// at chosen frames, with both policies' frame times and CG iterations.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "collision/collision_stage.h"
#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "engine/runtime/simulation.h"
#include "engine/dynamics/step.h"
#include "engine/runtime/timing_stats.h"
#include "tools/commands.h"
#include "tools/frame_list.h"
#include "tools/frame_loop.h"
#include "tools/solver_report.h"

namespace incise {

namespace {
struct CompareOptions {
  std::string scene, frames = "1,30,300", json;
  std::vector<std::string> policies;
  std::vector<ScenePatch> patches;  // --set and the solver flags, in order; each policy run gets them
  std::vector<ScenePatch> reference_patches;  // --reference-set: the reference's alone, applied last
};

// The patches of one policy's run: the command line's, less those of solver
// keys the policy does not use (one set of flags serves every policy: a
// --refresh-every is for lagged), the scene file's own such keys removed
// (null), then solver.policy. The scene parser checks the result.
std::vector<ScenePatch> policy_patches(const CompareOptions& o, const Scene& file, const std::string& policy) {
  std::vector<ScenePatch> out;
  int known = -1;
  for (int k = 0; k < 4; ++k)
    if (policy == policy_name(static_cast<SolverPolicy>(k))) known = k;
  auto unused = [&](const std::string& key) {
    return known >= 0 && key.rfind("solver.", 0) == 0 &&
           !solver_key_used_by(key.substr(7), static_cast<SolverPolicy>(known));
  };
  for (const ScenePatch& p : o.patches) {
    if (unused(p.key)) std::printf("%s: without %s (%s is not used by that policy)\n", policy.c_str(), p.given.c_str(), p.key.c_str());
    else out.push_back(p);
  }
  for (const auto& [key, origin] : file.origin)
    if (origin.kind == SettingOrigin::Kind::Scene && unused(key)) {
      std::printf("%s: without the scene's %s (not used by that policy)\n", policy.c_str(), key.c_str());
      out.push_back({key, "null", "compare --policy " + policy});
    }
  out.push_back({"solver.policy", policy, "--policy " + policy});
  return out;
}

// The reference's displacements at the checkpoints, and its timing summary.
struct Reference {
  std::vector<std::vector<double>> u;  // (checkpoints) u at each
  nlohmann::json exact;
  int ndof = 0;
  std::vector<GraspTaken> grasps;  // the points the reference's grasps took (imposed on the policies)
};

// The same scene and patches, then the whole solver object replaced by
// solver.preset "reference" (exact), no tangent reuse, the runs'
// integrator.tangent: no preset or solver flag reaches it. Then
// --reference-set (e.g. a converged reference: integrator.residual_tolerance,
// more Newton iterations, integrator.line_search).
Reference run_reference(const CompareOptions& o, const Scene& first_run, const std::vector<int>& checkpoints) {
  std::vector<ScenePatch> reference = o.patches;
  for (ScenePatch& p : exact_reference_patches(first_run)) reference.push_back(std::move(p));
  for (const ScenePatch& p : o.reference_patches) reference.push_back(p);
  auto ref = load_checked_simulation(o.scene, reference);
  print_model_summary(*ref);
  Reference r;
  std::vector<FrameTiming> t_ref;
  for (int k = 1; k <= checkpoints.back(); ++k) {
    t_ref.push_back(advance_frame(*ref));  // cutting stage, then the step
    if (std::find(checkpoints.begin(), checkpoints.end(), k) != checkpoints.end()) r.u.push_back(ref->state.u);
  }
  const TimingSummary sr = summarize(t_ref);
  std::printf("exact: frame median %.2f ms, p99 %.2f ms\n", sr.frame.median_ms, sr.frame.p99_ms);
  r.exact = {{"frame_median_ms", sr.frame.median_ms}, {"frame_p99_ms", sr.frame.p99_ms}, {"nnz_L", ref->ws.solver.stats().nnz_L}};
  r.ndof = ref->model.ndof();
  if (const CollisionData* cd = collision_data(*ref)) r.grasps = cd->taken;
  return r;
}

// One policy's run against the reference: the relative L2 error at each
// checkpoint (a diverging policy is a result, not the end of the comparison),
// frame times and the solver's report.
nlohmann::json run_policy(const CompareOptions& o, const std::string& policy, const std::vector<ScenePatch>& patches,
                          const std::vector<int>& checkpoints, const Reference& ref) {
  auto sim = load_checked_simulation(o.scene, patches);
  std::printf("--- %s\n", policy.c_str());
  // A grasp takes the surface points between its jaws when it closes; runs
  // whose tissue lies a little differently there take different points, a
  // discrete difference no solver tolerance removes. The policy's grasps
  // take the reference's points, so the error measures the solver.
  if (CollisionData* cd = collision_data(*sim); cd && !ref.grasps.empty()) {
    cd->imposed = ref.grasps;
    std::printf("grasps: the reference's held points imposed (%zu closing(s))\n", ref.grasps.size());
  }
  std::printf("%s", format_resolved_settings(sim->scene).c_str());
  std::printf("%8s %14s %14s\n", "frame", "rel L2 error", "|u_exact|");
  std::vector<FrameTiming> t_pol;
  nlohmann::json rows = nlohmann::json::array();
  try {
    for (int k = 1, c = 0; k <= checkpoints.back(); ++k) {
      t_pol.push_back(advance_frame(*sim));
      if (checkpoints[c] != k) continue;
      const std::vector<double>& ue = ref.u[c++];
      if (ue.size() != sim->state.u.size())
        throw Error("compare: at frame " + std::to_string(k) + " the policy's model has " +
                    std::to_string(sim->state.u.size()) + " DOFs and the reference " + std::to_string(ue.size()) +
                    ": the cuts did not produce the same pieces");
      double d2 = 0, u2 = 0;
      for (size_t i = 0; i < ue.size(); ++i) {
        const double d = sim->state.u[i] - ue[i];
        d2 += d * d;
        u2 += ue[i] * ue[i];
      }
      const double err = u2 > 0 ? std::sqrt(d2 / u2) : std::sqrt(d2);
      std::printf("%8d %14.3e %14.3e\n", k, err, std::sqrt(u2));
      std::fflush(stdout);
      rows.push_back({{"frame", k}, {"rel_l2_error", std::isfinite(err) ? err : 1e300}, {"u_norm", std::sqrt(u2)}});
    }
  } catch (const Error& e) {
    std::printf("%s: stopped at frame %d: %s\n", policy.c_str(), sim->state.frame + 1, e.what());
    rows.push_back({{"frame", sim->state.frame + 1}, {"failed", e.what()}});
  }
  const TimingSummary sp = summarize(t_pol);
  const SolverReport rp = solver_report(*sim, t_pol, sp);
  std::printf("%s: frame median %.2f ms, p99 %.2f ms; substitutions/frame %.0f\n", policy.c_str(), sp.frame.median_ms,
              sp.frame.p99_ms, rp.substitutions_per_frame);
  if (policy == "lagged" || policy == "warped_cg")
    std::printf("CG iterations/frame: median %.0f, max %.0f; %d frame(s) not converged (max residual %.2g)\n",
                rp.iterations.median_ms, rp.iterations.max_ms, rp.not_converged_frames, rp.max_residual);
  nlohmann::json pj = solver_report_json(rp);
  pj["errors"] = rows;
  pj["frame_median_ms"] = sp.frame.median_ms;
  pj["frame_p99_ms"] = sp.frame.p99_ms;
  pj["tolerance"] = sim->model.solver.tolerance;
  pj["refresh_every"] = sim->model.solver.refresh_every;
  pj["background"] = sim->model.solver.background;
  return pj;
}

void compare(const CompareOptions& o) {
  const std::vector<int> checkpoints = parse_frame_list(o.frames, "compare");
  // Every run's scene is resolved (and checked) before the reference starts.
  const Scene file = load_scene(o.scene);
  std::vector<std::string> policies = o.policies;
  std::vector<std::vector<ScenePatch>> runs;
  std::vector<Scene> resolved;
  for (const std::string& policy : policies) {
    runs.push_back(policy_patches(o, file, policy));
    resolved.push_back(load_scene(o.scene, runs.back()));
  }
  if (policies.empty()) {  // no --policy: the scene's own (after its preset and the patches)
    runs.push_back(o.patches);
    resolved.push_back(load_scene(o.scene, o.patches));
    policies.push_back(policy_name(resolved.back().solver.policy));
  }
  // The reference runs first, then each policy: never two at once, because a
  // lagged background factorization must be the only BLAS user with a serial
  // OpenBLAS (no locks; blas_concurrency_safe), and the timings stay apart.
  const Reference ref = run_reference(o, resolved.front(), checkpoints);
  nlohmann::json j;
  j["scene"] = o.scene;
  j["dof"] = ref.ndof;
  j["exact"] = ref.exact;
  j["policies"] = nlohmann::json::array();
  for (size_t r = 0; r < policies.size(); ++r) j["policies"].push_back(run_policy(o, policies[r], runs[r], checkpoints, ref));
  if (!o.json.empty()) {
    write_file_atomic(o.json, j.dump(2) + "\n");
    std::printf("wrote %s\n", o.json.c_str());
  }
}
}  // namespace

void add_compare_command(CLI::App& app) {
  auto opts = std::make_shared<CompareOptions>();
  auto* cmd = app.add_subcommand(
      "compare",
      "Run a scene under the exact reference and under --policy (or its own solver settings); print the relative L2 "
      "displacement error");
  cmd->add_option("scene", opts->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--frames", opts->frames, "Frames at which to report the error, comma-separated (default 1,30,300)");
  cmd->add_option("--json", opts->json, "Write the errors and timings as JSON");
  cmd->add_option("--policy", opts->policies,
                  "Policy (or comma-separated policies) to compare with exact (default: the scene's solver.policy, "
                  "after its preset and --set)")
      ->delimiter(',');
  add_set_option(*cmd, opts->patches);
  cmd->add_option_function<std::string>(
         "--reference-set",
         [opts](const std::string& text) {
           ScenePatch p;
           try {
             p = parse_scene_patch(text);
           } catch (const Error& e) {  // its messages start "--set TEXT: "
             const std::string what = e.what();
             throw Error("--reference-set" + (what.rfind("--set", 0) == 0 ? what.substr(5) : ": " + what));
           }
           p.given = "--reference-set " + text;
           opts->reference_patches.push_back(std::move(p));
         },
         "Override a scene key for the exact reference only, after everything else, e.g. for a converged reference: "
         "--reference-set integrator.residual_tolerance=1e-8 --reference-set integrator.max_newton_iterations=40 "
         "--reference-set integrator.line_search=true (repeatable)")
      ->trigger_on_parse()
      ->type_name("KEY=VALUE");
  add_solver_aliases(*cmd, opts->patches, /*with_policy=*/false);
  cmd->callback([opts] { compare(*opts); });
}

}  // namespace incise
