#include "engine/runtime/trajectory.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <Eigen/Geometry>

#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "engine/util/number_text.h"

namespace incise {
namespace {

const char* const kNames[9] = {"t", "x", "y", "z", "qw", "qx", "qy", "qz", "jaw"};

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t") - a + 1);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  size_t start = 0;
  for (;;) {
    const size_t comma = line.find(',', start);
    out.push_back(trim(line.substr(start, comma - start)));
    if (comma == std::string::npos) return out;
    start = comma + 1;
  }
}

}  // namespace

Trajectory Trajectory::read(const std::string& path) {
  return parse(read_input_file(path, kMaxTableBytes, "trajectory file"), path);
}

Trajectory Trajectory::parse(const std::string& text, const std::string& path) {
  Trajectory tr;
  int ncol = 0;           // 8 or 9 once the header is read
  int header_line = 0;
  int line_no = 0;
  std::string prev_t;     // the previous keyframe's time as written, and its line
  int prev_line = 0;
  auto fail = [&](int line, const std::string& what) -> Error {
    return Error(path + ":" + std::to_string(line) + ": " + what);
  };
  std::istringstream lines(text);
  std::string raw;
  while (std::getline(lines, raw)) {
    ++line_no;
    if (!raw.empty() && raw.back() == '\r') raw.pop_back();
    const std::string line = trim(raw);
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> f = split(line);
    if (ncol == 0) {
      bool ok = f.size() == 8 || f.size() == 9;
      for (size_t k = 0; ok && k < f.size(); ++k) ok = f[k] == kNames[k];
      if (!ok) throw fail(line_no, "the header must be t,x,y,z,qw,qx,qy,qz or t,x,y,z,qw,qx,qy,qz,jaw, got \"" + line + "\"");
      ncol = static_cast<int>(f.size());
      header_line = line_no;
      continue;
    }
    if (static_cast<int>(f.size()) != ncol)
      throw fail(line_no, "expected " + std::to_string(ncol) + " values (as the header on line " + std::to_string(header_line) +
                              "), got " + std::to_string(f.size()));
    double v[9];
    for (int k = 0; k < ncol; ++k) {
      const std::string& s = f[k];
      char* end = nullptr;
      v[k] = s.empty() ? 0.0 : std::strtod(s.c_str(), &end);
      if (s.empty() || end != s.c_str() + s.size())
        throw fail(line_no, std::string(kNames[k]) + " must be a number, got \"" + s + "\"");
      if (!std::isfinite(v[k])) throw fail(line_no, std::string(kNames[k]) + " must be a finite number, got " + s);
      // Interpolating between +-1.7e308 overflowed to an infinite pose (and
      // times that far apart froze it): no scene unit makes such sizes sense.
      if (k < 4 && !(std::abs(v[k]) <= 1e12))
        throw fail(line_no, std::string(kNames[k]) + " must be within [-1e12, 1e12], got " + s);
    }
    if (!tr.t_.empty() && !(v[0] > tr.t_.back()))
      throw fail(line_no, "time must increase strictly: t = " + f[0] + " follows t = " + prev_t + " (line " +
                              std::to_string(prev_line) + ")");
    // Within 1e-3: a tracker's export rounded to 4 decimals (0.7071) is off
    // by 1e-5; a quaternion with a wrong or missing component is off by far more.
    const double n = std::sqrt(v[4] * v[4] + v[5] * v[5] + v[6] * v[6] + v[7] * v[7]);
    if (!(std::abs(n - 1.0) <= 1e-3))
      throw fail(line_no, "the quaternion qw,qx,qy,qz must have unit norm (within 1e-3), got norm " + number_text(n, 10));
    if (ncol == 9 && !(v[8] >= 0.0 && v[8] <= 1.0))
      throw fail(line_no, "jaw must be in [0, 1] (0 open .. 1 closed), got " + f[8]);
    tr.t_.push_back(v[0]);
    for (int d = 0; d < 3; ++d) tr.p_.push_back(v[1 + d]);
    for (int d = 0; d < 4; ++d) tr.q_.push_back(v[4 + d] / n);
    if (ncol == 9) tr.jaw_.push_back(v[8]);
    prev_t = f[0];
    prev_line = line_no;
  }
  if (ncol == 0)
    throw fail(std::max(line_no, 1), "no header: expected t,x,y,z,qw,qx,qy,qz[,jaw] and at least one keyframe");
  if (tr.t_.empty())
    throw fail(std::max(line_no, 1), "no keyframe after the header on line " + std::to_string(header_line) +
                                         "; at least one is needed");
  return tr;
}

std::array<double, 4> slerp(const std::array<double, 4>& a, const std::array<double, 4>& b, double u) {
  // Eigen's slerp takes the shorter arc (q and -q are the same rotation) and
  // falls back to linear weights for nearly parallel quaternions.
  const Eigen::Quaterniond qa(a[0], a[1], a[2], a[3]), qb(b[0], b[1], b[2], b[3]);
  const Eigen::Quaterniond q = qa.slerp(u, qb).normalized();
  return {q.w(), q.x(), q.y(), q.z()};
}

ToolPose Trajectory::sample(double t) const {
  ToolPose pose;
  const size_t last = t_.size() - 1;
  size_t k0 = 0, k1 = 0;  // keyframes around t (equal when clamped)
  double u = 0.0;
  if (!(t > t_.front())) {  // before the first keyframe (or NaN)
  } else if (t >= t_.back()) {
    k0 = k1 = last;
  } else {
    k1 = static_cast<size_t>(std::upper_bound(t_.begin(), t_.end(), t) - t_.begin());  // t_[k1 - 1] <= t < t_[k1]
    k0 = k1 - 1;
    u = (t - t_[k0]) / (t_[k1] - t_[k0]);
  }
  for (int d = 0; d < 3; ++d) pose.p[d] = (1.0 - u) * p_[3 * k0 + d] + u * p_[3 * k1 + d];
  const std::array<double, 4> a{q_[4 * k0], q_[4 * k0 + 1], q_[4 * k0 + 2], q_[4 * k0 + 3]};
  if (k0 == k1) {
    pose.q = a;
  } else {
    const std::array<double, 4> b{q_[4 * k1], q_[4 * k1 + 1], q_[4 * k1 + 2], q_[4 * k1 + 3]};
    pose.q = slerp(a, b, u);
  }
  if (!jaw_.empty()) pose.jaw = (1.0 - u) * jaw_[k0] + u * jaw_[k1];
  return pose;
}

}  // namespace incise
