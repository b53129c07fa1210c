// incise static: Newton to static equilibrium, optional probe of the
// displacement at reference points.
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "cutting/cut_apply.h"
#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "engine/output/probe.h"
#include "engine/output/result_grid.h"
#include "engine/runtime/failure_context.h"
#include "engine/runtime/simulation.h"
#include "engine/dynamics/static_solve.h"
#include "tools/commands.h"
#include "tools/probe_points.h"
#include "tools/frame_loop.h"
#include "tools/frame_outputs.h"
#include "tools/solver_report.h"

namespace incise {

namespace {
struct StaticOptions {
  std::string scene, probe, out, vtu;
  std::vector<ScenePatch> patches;  // --set
  bool keep_unconverged = false;    // --keep-unconverged: write --vtu/--out even when Newton did not converge
};

void run_static(const StaticOptions& o) {
  auto sim = load_checked_simulation(o.scene, o.patches);
  if (!sim->scene.instruments.empty())
    std::fprintf(stderr,
                 "note: static ignores the scene's %zu instrument(s): they act through the frames of run and bench\n",
                 sim->scene.instruments.size());
  if (!sim->scene.cuts.empty()) {
    const CutUpdate cut = apply_all_cuts(*sim);  // static: every cut at once
    std::printf("cuts: %d elements split into %d pieces, %d separated faces, %d enriched DOF nodes, %d bodies, "
                "%d front elements%s (%.1f ms)\n",
                cut.report.cut_elements, cut.report.pieces, cut.report.separated_faces, cut.report.enriched_nodes,
                cut.report.bodies, cut.report.front_elements, sim->scene.front_enrichment ? " enriched" : "", cut.ms);
  }
  print_model_summary(*sim);
  // Probe points are located before the solve so a bad point fails fast.
  std::vector<std::array<double, 3>> pts;
  std::vector<ProbeHit> hits;
  if (!o.probe.empty()) {
    pts = read_probe_points(o.probe);
    for (size_t k = 0; k < pts.size(); ++k) {
      hits.push_back(locate_point(sim->model, pts[k].data()));
      if (hits.back().elem < 0) {
        char buf[256];
        std::snprintf(buf, sizeof buf, "%s: point %zu (%.9g, %.9g, %.9g) is outside the mesh", o.probe.c_str(), k + 1,
                      pts[k][0], pts[k][1], pts[k][2]);
        throw Error(buf);
      }
    }
  }
  Stopwatch clock;
  StaticResult r;
  try {
    r = solve_static(sim->model, sim->state, sim->ws, sim->scene.static_tolerance, sim->scene.static_max_iterations);
  } catch (const NumericalError& e) {
    throw Error(o.scene + ": " + with_failure_context(e, sim->model));
  }
  std::printf("static: %s after %d Newton iteration(s), relative residual %.3e (tolerance %g), %.1f ms\n",
              r.converged ? "converged" : "NOT converged", r.iterations, r.residual, sim->scene.static_tolerance,
              clock.ms());
  std::printf("  %s\n", static_report(r).c_str());
  char buf[320];
  std::snprintf(buf, sizeof buf, ": static solve did not reach static.tolerance %g in %d iterations (relative residual %g); ",
                sim->scene.static_tolerance, r.iterations, r.residual);
  const std::string unconverged = buf + static_failure_advice(r);
  // An unconverged result is written only when asked for (and still exits 1).
  if (!r.converged && !o.keep_unconverged)
    throw Error(o.scene + unconverged +
                (!o.vtu.empty() || !pts.empty() ? "; nothing was written (--keep-unconverged writes the last iterate)" : ""));
  if (!o.vtu.empty()) {
    const VtuGrid grid = result_grid(sim->model, sim->state);
    check_output_finite(grid, o.vtu);
    write_vtu(grid, o.vtu);
  }
  if (!pts.empty()) {
    std::ostringstream os;
    os.precision(12);
    os << "x,y,z,ux,uy,uz\n";
    for (size_t k = 0; k < pts.size(); ++k) {
      const auto u = interpolate_displacement(sim->model, sim->state.u.data(), hits[k]);
      for (double c : u)
        if (!std::isfinite(c))
          throw Error((o.out.empty() ? std::string("static") : o.out) + ": the displacement at probe point " +
                      std::to_string(k + 1) + " is not finite; it is not written");
      os << pts[k][0] << "," << pts[k][1] << "," << pts[k][2] << "," << u[0] << "," << u[1] << "," << u[2] << "\n";
    }
    if (o.out.empty()) {
      std::printf("%s", os.str().c_str());
    } else {
      write_file_atomic(o.out, os.str());
      std::printf("wrote %s (%zu points)\n", o.out.c_str(), pts.size());
    }
  }
  if (!r.converged) throw Error(o.scene + unconverged + "; --keep-unconverged wrote the last iterate");
}
}  // namespace

void add_static_command(CLI::App& app) {
  auto opts = std::make_shared<StaticOptions>();
  auto* cmd = app.add_subcommand("static", "Solve the static equilibrium (Newton on the corotated forces)");
  cmd->add_option("scene", opts->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
  auto* probe = cmd->add_option("--probe", opts->probe, "CSV of reference points x,y,z (header allowed)")
                    ->check(CLI::ExistingFile);
  // Without --probe there is nothing to write there (it was ignored in silence).
  cmd->add_option("--out", opts->out, "Probe result CSV x,y,z,ux,uy,uz (default: stdout)")->needs(probe);
  cmd->add_option("--vtu", opts->vtu, "Also write the deformed mesh with fields to this .vtu");
  cmd->add_flag("--keep-unconverged", opts->keep_unconverged,
                "Write --vtu and --out even when Newton does not reach static.tolerance (the last iterate; the exit "
                "code is still 1). Without it a solve that does not converge writes nothing");
  add_set_option(*cmd, opts->patches);
  cmd->callback([opts] { run_static(*opts); });
}

}  // namespace incise
