#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <fstream>

#include <nlohmann/json.hpp>

#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "tools/solver_report.h"
#include "tools/timing_json.h"

namespace incise {

double peak_rss_mb() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss / 1024.0;  // Linux: KB
}

void write_timing_json(const std::string& path, const Simulation& sim, const TimingSummary& s,
                       const std::vector<FrameTiming>* frames, double bandwidth_gbs, double pace_hz,
                       const nlohmann::json& extra) {
  auto pct = [](const Percentiles& p) {
    return nlohmann::json{{"median_ms", p.median_ms}, {"p95_ms", p.p95_ms}, {"p99_ms", p.p99_ms}, {"max_ms", p.max_ms}};
  };
  nlohmann::json j;
  j["scene"] = sim.scene.path;
  j["frames"] = s.frame.count;
  j["pace_hz"] = pace_hz;
  j["frame"] = pct(s.frame);
  j["frame"]["over_budget"] = s.over_budget;
  j["frame"]["budget_ms"] = s.budget_ms;
  for (int k = 0; k < kNumStages; ++k) {
    j["stages"][kStageNames[k]] = pct(s.stages[k]);
    j["stages"][kStageNames[k]]["runs"] = s.runs[k];
  }
  j["newton"] = {{"mean", s.newton_mean}, {"max", s.newton_max}};
  j["instruments"] = {{"contact_frames", s.contact_frames},   {"contacts_mean", s.contacts_mean},
                      {"contacts_max", s.contacts_max},       {"grasp_rows_max", s.grasp_rows_max},
                      {"pgs_sweeps_mean", s.contact_sweeps_mean}, {"max_depth", s.max_depth},
                      {"contact_force_max", s.contact_force_max},
                      {"contact_force_change", s.contact_force_change}, {"bvh_refits", s.bvh_refits},
                      {"bvh_rebuilds", s.bvh_rebuilds},       {"swept_frames", s.swept_frames},
                      {"speculative_frames", s.speculative_frames}};
  j["cut_frames"] = pct(s.cut_frames);
  j["cut_frames"]["count"] = s.cut_frames.count;
  j["cut_frames"]["prepared_ahead"] = s.cut_ahead;
  j["cut_frames"]["prepared_beside_collision"] = s.cut_early;
  for (int k = 0; k < kNumCutParts; ++k) {
    std::string name = kCutPartNames[k];
    name = name.substr(name.find_first_not_of(' '));
    std::replace(name.begin(), name.end(), ' ', '_');
    j["cut_frames"]["parts"][name] = pct(s.cut_parts[k]);
  }
  j["enriched_dof"] = 3 * (sim.model.ndofnode - sim.model.nnode);
  const Model& m = sim.model;
  j["dof"] = m.ndof();
  j["nodes"] = m.nnode;
  j["elements"] = m.nelem;
  j["element"] = m.mesh.order == 2 ? (m.material.rotation == RotationMode::Single ? "tet10SR" : "tet10") : "tet4";
  j["material"] = m.material.model == MaterialModel::Linear ? "linear" : "corotated";
  const FactorStats& f = sim.ws.solver.stats();
  j["factor"] = {{"nnz_L", f.nnz_L}, {"flops", f.flops}, {"ordering", f.ordering}, {"nnz_A", m.nnz()},
                 {"supernodal", f.supernodal}};
  if (frames) {
    const SolverReport r = solver_report(sim, *frames, s, bandwidth_gbs);
    j["solver"] = solver_report_json(r);
    j["factor"]["gflops"] = r.gflops;
    j["factor"]["factorizations"] = r.factorizations;
    j["factor"]["mean_ms"] = r.factor_ms_mean;
    j["factor"]["single_precision_factorization"] = r.single_precision;
    j["factor"]["single_precision_fallbacks"] = r.single_fallbacks;
    j["factor"]["single_precision_factorizations"] = r.single_factorizations;
    j["solve"] = {{"gbs", r.solve_gbs}, {"substitution_ms", r.substitution_ms},
                  {"substitutions_per_frame", r.substitutions_per_frame}};
    j["frame"]["bandwidth_limit_ms"] = r.bandwidth_limit_ms;
    j["frame"]["bandwidth_multiple"] = r.frame_multiple;
    nlohmann::json& pf = j["per_frame"];
    pf["frame_ms"] = nlohmann::json::array();
    pf["cut"] = nlohmann::json::array();
    for (const FrameTiming& t : *frames) {
      pf["frame_ms"].push_back(t.frame_ms);
      pf["cut"].push_back(t.cut_frame ? 1 : 0);
    }
    for (int k = 0; k < kNumStages; ++k) {
      if (s.runs[k] == 0) continue;
      nlohmann::json& col = pf["stages"][kStageNames[k]];
      col = nlohmann::json::array();
      for (const FrameTiming& t : *frames) col.push_back(t.ms[k]);
    }
  } else {
    j["solver"] = {{"policy", policy_name(m.solver.policy)}, {"threads", sim.ws.runtime.threads}};
  }
  j["refactorizations"] = sim.ws.refactorizations;
  j["setup_ms"] = sim.setup_ms;
  j["peak_rss_mb"] = peak_rss_mb();
  j["plain_frames"] = pct(s.plain_frames);
  j["plain_frames"]["count"] = s.plain_frames.count;
  j.update(extra);
  write_file_atomic(path, j.dump(2) + "\n");
}

}  // namespace incise
