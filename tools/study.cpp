#include "tools/study.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>

#include "engine/util/error.h"

namespace incise {

namespace {

struct Alias {
  const char* knob;
  const char* key;
};
constexpr Alias kAliases[] = {{"order", "mesh.order"},
                              {"mesh", "mesh.file"},
                              {"rotation", "material.rotation"},
                              {"preset", "solver.preset"},
                              {"policy", "solver.policy"},
                              {"tolerance", "solver.tolerance"},
                              {"newton", "integrator.newton_iterations"},
                              {"mass", "mass"},
                              {"dt", "integrator.dt"}};

bool number(const std::string& s, double& v) {
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return !s.empty() && end && *end == '\0' && std::isfinite(v);
}

// Index of the best value by `better`; the last listed when a value is not a number.
int pick_by(const Sweep& s, bool (*better)(double, double)) {
  int best = -1;
  double bv = 0;
  for (size_t i = 0; i < s.values.size(); ++i) {
    double v = 0;
    if (!number(s.values[i], v)) return static_cast<int>(s.values.size()) - 1;  // not numeric: the last listed
    if (best < 0 || better(v, bv)) best = static_cast<int>(i), bv = v;
  }
  return best;
}

int pick_named(const Sweep& s, const char* want) {
  for (size_t i = 0; i < s.values.size(); ++i)
    if (s.values[i] == want) return static_cast<int>(i);
  return static_cast<int>(s.values.size()) - 1;
}

std::string fmt(double v, const char* f = "%.3g") {
  if (!std::isfinite(v)) return "nan";
  char buf[48];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

}  // namespace

Sweep parse_sweep(const std::string& text) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == text.size())
    throw Error("--sweep " + text + ": expected KNOB=V1,V2,... (e.g. --sweep order=1,2 --sweep solver.tolerance=1e-3,1e-6)");
  Sweep s;
  s.knob = text.substr(0, eq);
  s.key = s.knob;
  for (const Alias& a : kAliases)
    if (s.knob == a.knob) s.key = a.key;
  std::stringstream ss(text.substr(eq + 1));
  std::string v;
  while (std::getline(ss, v, ',')) {
    if (v.empty()) throw Error("--sweep " + text + ": an empty value");
    if (std::find(s.values.begin(), s.values.end(), v) != s.values.end())
      throw Error("--sweep " + text + ": the value " + v + " is listed twice");
    s.values.push_back(v);
  }
  if (s.values.empty()) throw Error("--sweep " + text + ": no values");
  return s;
}

int finest_value(const Sweep& s) {
  const auto larger = [](double a, double b) { return a > b; };
  const auto smaller = [](double a, double b) { return a < b; };
  if (s.key == "mesh.order" || s.key == "integrator.newton_iterations") return pick_by(s, larger);
  if (s.key == "solver.tolerance" || s.key == "integrator.dt") return pick_by(s, smaller);
  if (s.key == "material.rotation") return pick_named(s, "per_point");
  if (s.key == "solver.policy") return pick_named(s, "exact");
  if (s.key == "solver.preset") return pick_named(s, "reference");
  if (s.key == "mass") return pick_named(s, "consistent");
  return static_cast<int>(s.values.size()) - 1;
}

std::vector<std::vector<int>> study_points(const std::vector<Sweep>& sweeps) {
  std::vector<std::vector<int>> out(1);
  for (const Sweep& s : sweeps) {
    std::vector<std::vector<int>> next;
    for (const auto& p : out)
      for (size_t v = 0; v < s.values.size(); ++v) {
        next.push_back(p);
        next.back().push_back(static_cast<int>(v));
      }
    out = std::move(next);
  }
  return out;
}

int reference_point(const std::vector<Sweep>& sweeps) {
  int k = 0;
  for (const Sweep& s : sweeps) k = k * static_cast<int>(s.values.size()) + finest_value(s);
  return k;
}

std::vector<int> pareto_front(const std::vector<double>& cost, const std::vector<double>& error) {
  std::vector<int> front;
  const size_t n = cost.size();
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(cost[i]) || !std::isfinite(error[i])) continue;
    bool dominated = false;
    for (size_t j = 0; j < n && !dominated; ++j) {
      if (j == i || !std::isfinite(cost[j]) || !std::isfinite(error[j])) continue;
      dominated = cost[j] <= cost[i] && error[j] <= error[i] && (cost[j] < cost[i] || error[j] < error[i]);
    }
    if (!dominated) front.push_back(static_cast<int>(i));
  }
  std::sort(front.begin(), front.end(), [&](int a, int b) { return cost[a] != cost[b] ? cost[a] < cost[b] : a < b; });
  return front;
}

double relative_l2(const std::vector<double>& a, const std::vector<double>& b) {
  double d2 = 0, b2 = 0;
  int used = 0;
  for (size_t i = 0; i + 2 < a.size() && i + 2 < b.size(); i += 3) {
    bool finite = true;
    for (int c = 0; c < 3; ++c) finite = finite && std::isfinite(a[i + c]) && std::isfinite(b[i + c]);
    if (!finite) continue;
    for (int c = 0; c < 3; ++c) {
      d2 += (a[i + c] - b[i + c]) * (a[i + c] - b[i + c]);
      b2 += b[i + c] * b[i + c];
    }
    ++used;
  }
  if (used == 0) return std::numeric_limits<double>::quiet_NaN();
  return b2 > 0 ? std::sqrt(d2 / b2) : std::sqrt(d2);
}

namespace {

// A sampled field of a result at stated frame k (null entries: NaN).
std::vector<double> field(const nlohmann::json& result, const char* what, size_t k) {
  std::vector<double> out;
  if (!result.contains(what) || !result[what].is_array() || k >= result[what].size()) return out;
  for (const auto& v : result[what][k]) out.push_back(v.is_number() ? v.get<double>() : std::numeric_limits<double>::quiet_NaN());
  return out;
}

}  // namespace

std::vector<StudyRow> collect_rows(const nlohmann::json& plan, const std::vector<nlohmann::json>& results,
                                   const nlohmann::json& reference) {
  std::vector<StudyRow> rows;
  const size_t nframes = plan.at("frames").size();
  const auto& points = plan.at("points");
  for (size_t p = 0; p < points.size(); ++p) {
    StudyRow r;
    r.point = static_cast<int>(p);
    for (const auto& v : points[p]) r.values.push_back(v.get<std::string>());
    const nlohmann::json& res = p < results.size() ? results[p] : nlohmann::json();
    if (res.is_null()) {
      r.failure = "not run";
    } else if (res.contains("failed")) {
      r.failure = res["failed"].get<std::string>();
    } else {
      r.ok = true;
      r.dof = res.value("dof", 0);
      r.median_ms = res.at("frame_ms").at("median");
      r.p99_ms = res.at("frame_ms").at("p99");
      for (size_t k = 0; k < nframes; ++k) r.error.push_back(relative_l2(field(res, "samples", k), field(reference, "samples", k)));
      if (res.contains("probe"))
        r.probe_error = relative_l2(field(res, "probe", nframes - 1), field(reference, "probe", nframes - 1));
      const double e0 = res.value("energy_start", 0.0), e1 = res.value("energy_end", 0.0);
      const double scale = std::max({std::abs(e0), std::abs(e1), res.value("energy_scale", 0.0)});
      r.energy_drift = scale > 0.0 ? (e1 - e0) / scale : 0.0;
    }
    rows.push_back(std::move(r));
  }
  std::vector<double> cost, err;
  for (const StudyRow& r : rows) {
    cost.push_back(r.ok ? r.median_ms : std::numeric_limits<double>::quiet_NaN());
    // The reference itself (error 0) is a point like the others.
    err.push_back(r.ok && !r.error.empty() ? r.error.back() : std::numeric_limits<double>::quiet_NaN());
  }
  for (int i : pareto_front(cost, err)) rows[static_cast<size_t>(i)].pareto = true;
  return rows;
}

std::string study_csv(const nlohmann::json& plan, const std::vector<StudyRow>& rows) {
  std::ostringstream os;
  os << "point";
  for (const auto& s : plan.at("sweeps")) os << ',' << s.at("knob").get<std::string>();
  os << ",status,dof,median_ms,p99_ms";
  for (const auto& f : plan.at("frames")) os << ",error_at_" << f.get<int>();
  os << ",probe_error,energy_drift,pareto\n";
  for (const StudyRow& r : rows) {
    os << r.point;
    for (const std::string& v : r.values) os << ',' << v;
    os << ',' << (r.ok ? "ok" : "failed") << ',' << r.dof << ',' << fmt(r.median_ms, "%.4g") << ',' << fmt(r.p99_ms, "%.4g");
    for (size_t k = 0; k < plan.at("frames").size(); ++k) os << ',' << (k < r.error.size() ? fmt(r.error[k], "%.4g") : "nan");
    os << ',' << (r.probe_error >= 0 ? fmt(r.probe_error, "%.4g") : "") << ',' << fmt(r.energy_drift, "%.4g") << ','
       << (r.pareto ? 1 : 0) << '\n';
  }
  return os.str();
}

std::string study_markdown(const nlohmann::json& plan, const std::vector<StudyRow>& rows) {
  std::ostringstream os;
  os << "Study of " << plan.at("scene").get<std::string>() << ": reference " << plan.at("reference").get<std::string>()
     << "; error = relative L2 displacement error over the body against it; * = on the Pareto front of (median ms, "
        "error at frame "
     << plan.at("frames").back().get<int>() << ").\n\n|";
  for (const auto& s : plan.at("sweeps")) os << ' ' << s.at("knob").get<std::string>() << " |";
  os << " DOF | median ms | p99 ms |";
  for (const auto& f : plan.at("frames")) os << " error @" << f.get<int>() << " |";
  os << " probe error | energy drift | Pareto |\n|";
  const size_t ncol = plan.at("sweeps").size() + 3 + plan.at("frames").size() + 3;
  for (size_t c = 0; c < ncol; ++c) os << "---|";
  os << '\n';
  for (const StudyRow& r : rows) {
    os << '|';
    for (const std::string& v : r.values) os << ' ' << v << " |";
    if (!r.ok) {
      os << " failed: " << r.failure << " |";
      for (size_t c = 1; c < ncol - r.values.size(); ++c) os << " |";
      os << '\n';
      continue;
    }
    os << ' ' << r.dof << " | " << fmt(r.median_ms, "%.1f") << " | " << fmt(r.p99_ms, "%.1f") << " |";
    for (double e : r.error) os << ' ' << fmt(e, "%.2e") << " |";
    os << ' ' << (r.probe_error >= 0 ? fmt(r.probe_error, "%.2e") : "-") << " | " << fmt(r.energy_drift, "%.2e") << " | "
       << (r.pareto ? "*" : "") << " |\n";
  }
  return os.str();
}

}  // namespace incise
