// incise study: sweeps of accuracy knobs, each point an independent process,
// collected into a table and a plot of error against ms per frame with the
// Pareto front marked (tools/study.h; docs/study.md).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>

#include "engine/dynamics/step.h"
#include "engine/mesh/mesh_io.h"
#include "engine/output/probe.h"
#include "engine/runtime/simulation.h"
#include "engine/runtime/timing_stats.h"
#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "engine/util/json_depth.h"
#include "engine/util/number_text.h"
#include "tools/commands.h"
#include "tools/option_checks.h"
#include "tools/frame_list.h"
#include "tools/frame_loop.h"
#include "tools/probe_points.h"
#include "tools/solver_report.h"
#include "tools/spawn.h"
#include "tools/study.h"

namespace incise {

namespace {
namespace fs = std::filesystem;

struct StudyOptions {
  std::string scene, out = "study", frames = "30", reference, probe, collect;
  std::vector<std::string> sweeps;
  std::vector<ScenePatch> patches;  // --set
  int point = -1;                   // --point K: run that point only
  bool list = false;                // --list: the point commands not done yet
};

constexpr size_t kMaxSamples = 2000;  // body samples per field (the base mesh's corner nodes, strided)

// The plan and the point results: regular files, nested at most
// kMaxJsonDepth levels (nlohmann's dump and comparison recurse per level).
nlohmann::json read_json(const fs::path& p) {
  const std::string text = read_input_file(p.string(), kMaxTableBytes, "study file");
  check_json_depth(text, p.string());
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw Error(p.string() + ": not a study file (" + e.what() + ")");
  }
}

// study.json as make_plan writes it. The plan is read through const
// operator[], which asserts on a missing key: anything else is an error
// naming the file.
nlohmann::json read_plan(const fs::path& dir) {
  const fs::path p = dir / "study.json";
  const nlohmann::json plan = read_json(p);
  const auto bad = [&](const std::string& what) { throw Error(p.string() + ": not a study plan: " + what); };
  const auto strings = [](const nlohmann::json& a, size_t n) {
    if (!a.is_array() || (n != SIZE_MAX && a.size() != n)) return false;
    for (const auto& v : a)
      if (!v.is_string()) return false;
    return true;
  };
  if (!plan.is_object()) bad("not a JSON object");
  for (const char* k : {"scene", "probe", "reference"})
    if (!plan.contains(k) || !plan[k].is_string()) bad(std::string(k) + " must be a string");
  if (!plan.contains("frames") || !plan["frames"].is_array() || plan["frames"].empty()) bad("frames must be a non-empty array");
  for (const auto& f : plan["frames"])
    if (!f.is_number_integer() || f.get<long long>() < 1 || f.get<long long>() > kMaxFrames)
      bad("frames must be frame numbers from 1 to " + std::to_string(kMaxFrames));
  if (!plan.contains("sweeps") || !plan["sweeps"].is_array()) bad("sweeps must be an array");
  for (const auto& s : plan["sweeps"])
    if (!s.is_object() || !s.contains("knob") || !s["knob"].is_string() || !s.contains("key") || !s["key"].is_string() ||
        !s.contains("values") || !strings(s["values"], SIZE_MAX))
      bad("each sweep must be {knob, key, values: [strings]}");
  if (!plan.contains("points") || !plan["points"].is_array() || plan["points"].empty()) bad("points must be a non-empty array");
  for (const auto& pt : plan["points"])
    if (!strings(pt, plan["sweeps"].size())) bad("each point must list one string per sweep");
  if (!plan.contains("set") || !plan["set"].is_array()) bad("set must be an array");
  for (const auto& s : plan["set"])
    if (!s.is_object() || !s.contains("key") || !s["key"].is_string() || !s.contains("value") || !s["value"].is_string())
      bad("each set entry must be {key, value} strings");
  if (plan.contains("reference_file")) {
    if (!plan["reference_file"].is_string()) bad("reference_file must be a string");
  } else if (!plan.contains("reference_point") || !plan["reference_point"].is_number_integer() ||
             plan["reference_point"].get<long long>() < 0 ||
             plan["reference_point"].get<long long>() >= static_cast<long long>(plan["points"].size())) {
    bad("reference_point must be the index of a point");
  }
  return plan;
}

// Written whole or not at all: a killed point leaves no result to resume from.
void write_atomically(const fs::path& p, const std::string& text) { write_file_atomic(p.string(), text); }

fs::path point_file(const fs::path& dir, int k) { return dir / "points" / ("point_" + std::to_string(k) + ".json"); }

// The plan (DIR/study.json): everything a point process needs.
nlohmann::json make_plan(const StudyOptions& o) {
  if (o.sweeps.empty()) throw Error("study: give at least one --sweep KNOB=V1,V2,...");
  std::vector<Sweep> sweeps;
  for (const std::string& s : o.sweeps) {
    sweeps.push_back(parse_sweep(s));
    for (size_t t = 0; t + 1 < sweeps.size(); ++t)
      if (sweeps[t].key == sweeps.back().key) throw Error("study: " + sweeps.back().key + " is swept twice");
  }
  nlohmann::json plan;
  plan["scene"] = fs::absolute(o.scene).string();
  plan["frames"] = parse_frame_list(o.frames, "study");
  plan["sweeps"] = nlohmann::json::array();
  for (const Sweep& s : sweeps) plan["sweeps"].push_back({{"knob", s.knob}, {"key", s.key}, {"values", s.values}});
  plan["points"] = nlohmann::json::array();
  for (const auto& p : study_points(sweeps)) {
    nlohmann::json vals = nlohmann::json::array();
    for (size_t s = 0; s < p.size(); ++s) vals.push_back(sweeps[s].values[static_cast<size_t>(p[s])]);
    plan["points"].push_back(vals);
  }
  plan["set"] = nlohmann::json::array();
  for (const ScenePatch& p : o.patches) plan["set"].push_back({{"key", p.key}, {"value", p.value}});
  plan["probe"] = o.probe.empty() ? "" : fs::absolute(o.probe).string();
  if (!o.reference.empty()) {
    plan["reference_file"] = fs::absolute(o.reference).string();
    plan["reference"] = o.reference;
  } else {
    const int r = reference_point(sweeps);
    plan["reference_point"] = r;
    std::string desc = "point " + std::to_string(r) + " (";
    for (size_t s = 0; s < sweeps.size(); ++s)
      desc += (s ? ", " : "") + sweeps[s].knob + "=" + plan["points"][static_cast<size_t>(r)][s].get<std::string>();
    plan["reference"] = desc + ")";
  }
  // Every point's scene must parse before anything runs.
  for (const auto& vals : plan["points"]) {
    std::vector<ScenePatch> patches = o.patches;
    for (size_t s = 0; s < sweeps.size(); ++s)
      patches.push_back({sweeps[s].key, vals[s].get<std::string>(), "--sweep " + sweeps[s].knob + "=" + vals[s].get<std::string>()});
    load_scene(o.scene, patches);
  }
  return plan;
}

std::vector<ScenePatch> point_patches(const nlohmann::json& plan, int k, bool with_sweeps = true) {
  std::vector<ScenePatch> out;
  for (const auto& p : plan["set"]) out.push_back({p["key"], p["value"], "--set " + p["key"].get<std::string>()});
  if (!with_sweeps) return out;
  const auto& sw = plan["sweeps"];
  for (size_t s = 0; s < sw.size(); ++s) {
    const std::string v = plan["points"][static_cast<size_t>(k)][s];
    out.push_back({sw[s]["key"], v, "--sweep " + sw[s]["knob"].get<std::string>() + "=" + v});
  }
  return out;
}

// The body samples: the base scene's mesh's corner nodes (at most
// kMaxSamples, evenly strided), the same for every point of the study.
std::vector<std::array<double, 3>> body_samples(const nlohmann::json& plan) {
  const Scene base = load_scene(plan["scene"], point_patches(plan, 0, false));
  const Mesh mesh = read_mesh(base.mesh_file);
  std::vector<char> corner(static_cast<size_t>(mesh.nnode()), 0);
  for (int e = 0; e < mesh.ntet(); ++e)
    for (int a = 0; a < 4; ++a) corner[static_cast<size_t>(mesh.tet[static_cast<size_t>(e) * mesh.npe() + a])] = 1;
  std::vector<int> nodes;
  for (int n = 0; n < mesh.nnode(); ++n)
    if (corner[static_cast<size_t>(n)]) nodes.push_back(n);
  const size_t stride = std::max<size_t>(1, (nodes.size() + kMaxSamples - 1) / kMaxSamples);
  std::vector<std::array<double, 3>> out;
  for (size_t i = 0; i < nodes.size(); i += stride)
    out.push_back({mesh.X[3 * nodes[i]], mesh.X[3 * nodes[i] + 1], mesh.X[3 * nodes[i] + 2]});
  return out;
}

// u at the points, located in the current model (null where outside it).
nlohmann::json sample(const Simulation& sim, const std::vector<std::array<double, 3>>& pts) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& p : pts) {
    const ProbeHit hit = locate_point(sim.model, p.data());
    if (hit.elem < 0) {
      for (int c = 0; c < 3; ++c) out.push_back(nullptr);
      continue;
    }
    const auto u = interpolate_displacement(sim.model, sim.state.u.data(), hit);
    for (double v : u) out.push_back(std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr));
  }
  return out;
}

// --frames are frames of the base scene's dt (with the study's --set
// patches, not its sweeps): a point with another dt (a dt sweep) samples at
// the same times, its frame f dt_base / dt. Its samples were taken at the
// same frame numbers, i.e. other times (0.66 "error" between dt = 1/30 and
// 1/60 at frame 5 of a swinging beam). The steps of point k whose dt is
// `dt`; an error where a sample time is not a whole number of them.
std::vector<int> sample_steps(const nlohmann::json& plan, int k, double dt) {
  const std::vector<int> frames = plan["frames"];
  const double base_dt = load_scene(plan["scene"], point_patches(plan, k, false)).dt;
  std::vector<int> at;
  for (const int f : frames) {
    const double g = f * base_dt / dt;
    if (!(std::abs(g - std::round(g)) <= 1e-6 * std::max(1.0, g)))
      throw Error("study: integrator.dt " + number_text(dt, 6) + " does not reach frame " + std::to_string(f) +
                  " of the base scene's dt " + number_text(base_dt, 6) + " (t = " + number_text(f * base_dt, 6) +
                  " s) in whole steps; sweep dt by divisors of the base dt");
    at.push_back(static_cast<int>(std::round(g)));
  }
  return at;
}

// One point, in this process: its result file (a failure is a result too).
void run_point(const fs::path& dir, int k) {
  const nlohmann::json plan = read_plan(dir);
  if (k < 0 || k >= static_cast<int>(plan["points"].size()))
    throw Error("study: --point " + std::to_string(k) + " is not in " + (dir / "study.json").string() + " (points 0-" +
                std::to_string(plan["points"].size() - 1) + ")");
  nlohmann::json res;
  res["point"] = k;
  res["values"] = plan["points"][static_cast<size_t>(k)];
  try {
    const auto body = body_samples(plan);
    std::vector<std::array<double, 3>> probes;
    if (!plan["probe"].get<std::string>().empty()) probes = read_probe_points(plan["probe"]);
    auto sim = load_checked_simulation(plan["scene"], point_patches(plan, k));
    std::printf("%s", format_resolved_settings(sim->scene).c_str());
    const std::vector<int> at = sample_steps(plan, k, sim->model.dt);
    res["dof"] = sim->model.ndof();
    res["energy_start"] = total_energy(sim->model, sim->state);
    double energy_scale = std::abs(res["energy_start"].get<double>());
    std::vector<FrameTiming> t;
    res["samples"] = nlohmann::json::array();
    if (!probes.empty()) res["probe"] = nlohmann::json::array();
    for (int f = 1, c = 0; f <= at.back(); ++f) {
      t.push_back(advance_frame(*sim));
      if (at[static_cast<size_t>(c)] != f) continue;
      ++c;
      res["samples"].push_back(sample(*sim, body));
      energy_scale = std::max(energy_scale, std::abs(total_energy(sim->model, sim->state)));
      if (!probes.empty()) res["probe"].push_back(sample(*sim, probes));
    }
    res["energy_end"] = total_energy(sim->model, sim->state);
    res["energy_scale"] = energy_scale;
    const TimingSummary s = summarize(t);
    res["frame_ms"] = {{"median", s.frame.median_ms}, {"p99", s.frame.p99_ms}, {"max", s.frame.max_ms}};
    std::printf("point %d: %d DOF, frame median %.2f ms, p99 %.2f ms\n", k, sim->model.ndof(), s.frame.median_ms,
                s.frame.p99_ms);
  } catch (const Error& e) {
    res["failed"] = e.what();
    std::printf("point %d failed: %s\n", k, e.what());
  }
  fs::create_directories(dir / "points");
  write_atomically(point_file(dir, k), res.dump() + "\n");
}

bool point_done(const fs::path& dir, int k) {
  const fs::path f = point_file(dir, k);
  if (!fs::is_regular_file(f)) return false;
  try {
    return read_json(f).contains("point");
  } catch (const Error&) {
    return false;
  }
}

std::string describe(const nlohmann::json& plan, int k) {
  std::string s;
  const auto& sw = plan["sweeps"];
  for (size_t i = 0; i < sw.size(); ++i)
    s += (i ? " " : "") + sw[i]["knob"].get<std::string>() + "=" + plan["points"][static_cast<size_t>(k)][i].get<std::string>();
  return s;
}

void collect(const fs::path& dir) {
  const nlohmann::json plan = read_plan(dir);
  const int n = static_cast<int>(plan["points"].size());
  std::vector<nlohmann::json> results(static_cast<size_t>(n));
  int missing = 0;
  for (int k = 0; k < n; ++k) {
    if (point_done(dir, k)) results[static_cast<size_t>(k)] = read_json(point_file(dir, k));
    else ++missing;
  }
  nlohmann::json reference;
  if (plan.contains("reference_file")) reference = read_json(plan["reference_file"].get<std::string>());
  else reference = results[plan["reference_point"].get<size_t>()];
  if (reference.is_null() || reference.contains("failed") || !reference.contains("samples"))
    throw Error("study: the reference (" + plan["reference"].get<std::string>() + ") has no result in " + dir.string() +
                (reference.contains("failed") ? ": it failed: " + reference["failed"].get<std::string>() : ""));
  const std::vector<StudyRow> rows = collect_rows(plan, results, reference);
  write_atomically(dir / "study.csv", study_csv(plan, rows));
  const std::string md = study_markdown(plan, rows);
  write_atomically(dir / "study.md", md);
  std::printf("%s\nwrote %s, %s\n", md.c_str(), (dir / "study.csv").c_str(), (dir / "study.md").c_str());
  if (missing > 0) std::printf("%d of %d point(s) not run yet (incise study --list --out %s)\n", missing, n, dir.c_str());
  // The plot: Debian's python3 with matplotlib; a missing one is a note, not an error.
  const char* env = std::getenv("INCISE_STUDY_PLOT_SCRIPT");
  const std::string script = env && *env ? env : INCISE_SCRIPTS_DIR "/plot-study.py";
  const std::string python = plot_python();
  const fs::path png = dir / "study.png";
  int status = -1;
  if (fs::is_regular_file(script)) {
    try {
      status = spawn_and_wait({python, script, (dir / "study.csv").string(), png.string()});
    } catch (const Error&) {
    }
  }
  if (status == 0) std::printf("wrote %s\n", png.c_str());
  else std::printf("no plot: %s %s failed or is missing (it needs python3-matplotlib)\n", python.c_str(), script.c_str());
}

void study(const StudyOptions& o) {
  if (!o.collect.empty()) {
    collect(o.collect);
    return;
  }
  const fs::path dir = o.out;
  if (o.point >= 0) {
    run_point(dir, o.point);
    return;
  }
  if (o.scene.empty()) throw Error("study: give a scene file (or --collect DIR, or --point K --out DIR)");
  nlohmann::json plan = make_plan(o);
  // Every point's sample steps before any runs (a dt sweep with a dt that
  // does not divide the base one failed only when its point came up).
  for (int k = 0; k < static_cast<int>(plan["points"].size()); ++k)
    sample_steps(plan, k, load_scene(plan["scene"], point_patches(plan, k)).dt);
  // Resume: the same plan in DIR keeps its points; a different one is an error.
  if (fs::exists(dir / "study.json")) {
    if (read_plan(dir) != plan)
      throw Error("study: " + dir.string() + " holds a different study (" + (dir / "study.json").string() +
                  "); give another --out or remove it");
  } else {
    fs::create_directories(dir);
    write_atomically(dir / "study.json", plan.dump(1) + "\n");
  }
  const int n = static_cast<int>(plan["points"].size());
  const std::string exe = self_executable();
  if (o.list) {
    for (int k = 0; k < n; ++k)
      if (!point_done(dir, k)) std::printf("%s study --point %d --out %s\n", exe.c_str(), k, dir.c_str());
    return;
  }
  fs::create_directories(dir / "logs");
  Stopwatch clock;
  int ran = 0, done_before = 0;
  for (int k = 0; k < n; ++k) {
    if (point_done(dir, k)) {
      ++done_before;
      continue;
    }
    const fs::path log = dir / "logs" / ("point_" + std::to_string(k) + ".log");
    const int status = spawn_and_wait({exe, "study", "--point", std::to_string(k), "--out", dir.string()}, log.string());
    ++ran;
    const int left = n - done_before - ran;
    const double per = clock.ms() / 1000.0 / ran;
    std::fprintf(stderr, "study: point %d/%d (%s) %s; %d left, ETA %.0f s\n", k + 1, n, describe(plan, k).c_str(),
                 status == 0 && point_done(dir, k) ? "done" : ("failed (exit " + std::to_string(status) + ", " + log.string() + ")").c_str(),
                 left, per * left);
  }
  if (done_before > 0) std::fprintf(stderr, "study: %d point(s) were done before (resumed)\n", done_before);
  collect(dir);
}

}  // namespace

void add_study_command(CLI::App& app) {
  auto opts = std::make_shared<StudyOptions>();
  auto* cmd = app.add_subcommand(
      "study",
      "Sweep accuracy knobs (each point its own process), then tabulate error against a reference versus ms per frame, "
      "with the Pareto front (docs/study.md)");
  cmd->add_option("scene", opts->scene, "Scene file (JSON)")->check(CLI::ExistingFile);
  cmd->add_option("--sweep", opts->sweeps,
                  "KNOB=V1,V2,... (repeatable): order, mesh (files, coarse to fine), rotation, preset, policy, "
                  "tolerance, newton, mass, dt, or any scene key");
  cmd->add_option("--frames", opts->frames, "Frames at which to compare, comma-separated; the last is the run length (default 30)");
  cmd->add_option("--reference", opts->reference,
                  "A point result (DIR/points/point_K.json of a finer study) to compare with (default: the point with "
                  "every knob at its finest value)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--probe", opts->probe, "Probe points x,y,z (reference coordinates): their error is reported too")
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", opts->out, "Study folder: study.json (the plan), points/, logs/, study.csv, study.md, study.png (default study)");
  cmd->add_option("--point", opts->point, "Run only point K of the plan in --out (GNU parallel, Slurm arrays: docs/study.md)")
      ->check(integer_in(0, 1000000000));
  cmd->add_flag("--list", opts->list, "Print the command of each point not done yet, one per line, and stop");
  cmd->add_option("--collect", opts->collect, "Gather the point results in DIR into the table and the plot");
  add_set_option(*cmd, opts->patches);
  cmd->callback([opts] {
    try {
      study(*opts);
    } catch (const nlohmann::json::exception& e) {  // a point result of another shape (the plan is checked)
      throw Error("study: a point result in " + (opts->collect.empty() ? opts->out : opts->collect) +
                  "/points is malformed: " + e.what());
    }
  });
}

}  // namespace incise
