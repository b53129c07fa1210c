// incise compare: run a scene under the exact policy and under another policy
// side by side and print the relative L2 difference of the displacement field
// at chosen frames, with both policies' frame times and CG iterations.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "engine/error.h"
#include "engine/simulation.h"
#include "engine/step.h"
#include "engine/timing_stats.h"
#include "tools/commands.h"
#include "tools/solver_report.h"

namespace incise {

namespace {
struct CompareOptions {
  std::string scene, frames = "1,30,300", json;
  SolverOverrides solver;
};

std::vector<int> parse_frames(const std::string& text) {
  std::vector<int> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || v < 1 || v > 1000000)
      throw Error("compare: --frames must be a comma-separated list of frame numbers >= 1, got \"" + text + "\"");
    out.push_back(static_cast<int>(v));
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

void compare(const CompareOptions& o) {
  if (o.solver.policy.empty()) throw Error("compare: --policy is required");
  const std::vector<int> checkpoints = parse_frames(o.frames);
  auto ref = load_simulation(o.scene);
  SolverOverrides exact;
  exact.policy = "exact";
  exact.threads = o.solver.threads;
  apply_solver_overrides(*ref, exact);
  auto sim = load_simulation(o.scene);
  apply_solver_overrides(*sim, o.solver);
  print_model_summary(*sim);
  std::vector<FrameTiming> t_ref, t_pol;
  // The reference runs first, then the policy: never both at once, because a
  // lagged background factorization must be the only BLAS user (Debian's
  // serial OpenBLAS has no locks).
  std::vector<std::vector<double>> u_ref;
  for (int k = 1; k <= checkpoints.back(); ++k) {
    step(ref->model, ref->state);
    t_ref.push_back(ref->state.timing);
    if (std::find(checkpoints.begin(), checkpoints.end(), k) != checkpoints.end()) u_ref.push_back(ref->state.u);
  }
  nlohmann::json rows = nlohmann::json::array();
  std::printf("%8s %14s %14s\n", "frame", "rel L2 error", "|u_exact|");
  for (int k = 1, c = 0; k <= checkpoints.back(); ++k) {
    step(sim->model, sim->state);
    t_pol.push_back(sim->state.timing);
    if (checkpoints[c] != k) continue;
    const std::vector<double>& ue = u_ref[c++];
    double d2 = 0, u2 = 0;
    for (size_t i = 0; i < ue.size(); ++i) {
      const double d = sim->state.u[i] - ue[i];
      d2 += d * d;
      u2 += ue[i] * ue[i];
    }
    const double err = u2 > 0 ? std::sqrt(d2 / u2) : std::sqrt(d2);
    std::printf("%8d %14.3e %14.3e\n", k, err, std::sqrt(u2));
    std::fflush(stdout);
    rows.push_back({{"frame", k}, {"rel_l2_error", err}, {"u_norm", std::sqrt(u2)}});
  }
  const TimingSummary sr = summarize(t_ref), sp = summarize(t_pol);
  const SolverReport rr = solver_report(*ref, t_ref, sr), rp = solver_report(*sim, t_pol, sp);
  std::printf("exact:  frame median %.2f ms, p99 %.2f ms\n", sr.frame.median_ms, sr.frame.p99_ms);
  std::printf("%s: frame median %.2f ms, p99 %.2f ms; substitutions/frame %.0f\n", rp.policy.c_str(),
              sp.frame.median_ms, sp.frame.p99_ms, rp.substitutions_per_frame);
  if (rp.policy == "lagged" || rp.policy == "warped_cg")
    std::printf("CG iterations/frame: median %.0f, max %.0f; %d frame(s) not converged (max residual %.2g)\n",
                rp.iterations.median_ms, rp.iterations.max_ms, rp.not_converged_frames, rp.max_residual);
  if (!o.json.empty()) {
    nlohmann::json j;
    j["scene"] = o.scene;
    j["dof"] = sim->model.ndof();
    j["errors"] = rows;
    j["exact"] = {{"frame_median_ms", sr.frame.median_ms}, {"frame_p99_ms", sr.frame.p99_ms}};
    j["policy"] = solver_report_json(rp);
    j["policy"]["frame_median_ms"] = sp.frame.median_ms;
    j["policy"]["frame_p99_ms"] = sp.frame.p99_ms;
    j["policy"]["tolerance"] = sim->model.solver.tolerance;
    j["policy"]["refresh_every"] = sim->model.solver.refresh_every;
    j["policy"]["background"] = sim->model.solver.background;
    std::ofstream os(o.json);
    if (!os) throw Error(o.json + ": cannot write the comparison");
    os << j.dump(2) << "\n";
    std::printf("wrote %s\n", o.json.c_str());
  }
}
}  // namespace

void add_compare_command(CLI::App& app) {
  auto opts = std::make_shared<CompareOptions>();
  auto* cmd = app.add_subcommand(
      "compare", "Run a scene under solver.policy exact and under --policy; print the relative L2 displacement error");
  cmd->add_option("scene", opts->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--frames", opts->frames, "Frames at which to report the error, comma-separated (default 1,30,300)");
  cmd->add_option("--json", opts->json, "Write the errors and timings as JSON");
  add_solver_options(cmd, opts->solver);
  cmd->callback([opts] { compare(*opts); });
}

}  // namespace incise
