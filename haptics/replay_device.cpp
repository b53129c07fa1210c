#include "haptics/replay_device.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "engine/mesh/mesh_text.h"  // the readers' line and number plumbing
#include "engine/util/error.h"

namespace incise {
namespace {

const char* const kColumns[10] = {"t", "x", "y", "z", "qw", "qx", "qy", "qz", "jaw", "buttons"};

void parse_stream(meshio::TextFile& f, std::vector<double>& t, std::vector<DeviceSample>& s) {
  std::string_view line;
  std::vector<std::string_view> fields;
  bool header = false;
  while (f.next(line)) {
    line = meshio::trim(line);
    if (line.empty() || line[0] == '#') continue;
    meshio::split(line, fields, true);
    if (!header) {
      bool ok = fields.size() == 10;
      for (size_t k = 0; ok && k < 10; ++k) ok = fields[k] == kColumns[k];
      if (!ok) f.fail("the header must be t,x,y,z,qw,qx,qy,qz,jaw,buttons, got " + meshio::quote(line));
      header = true;
      continue;
    }
    if (fields.size() != 10) f.fail("expected 10 values (t,x,y,z,qw,qx,qy,qz,jaw,buttons), got " + std::to_string(fields.size()));
    double v[9];
    for (int k = 0; k < 9; ++k)
      if (!meshio::parse_double(fields[k], v[k]))
        f.fail(std::string(kColumns[k]) + " must be a number (nan and inf allowed), got " + meshio::quote(fields[k]));
    long long buttons = 0;
    if (!meshio::parse_long(fields[9], buttons) || buttons < 0 || buttons > 0x7fffffffLL)
      f.fail("buttons must be an integer in [0, 2147483647], got " + meshio::quote(fields[9]));
    if (!std::isfinite(v[0])) f.fail("t must be a finite number, got " + meshio::quote(fields[0]));
    if (!t.empty() && !(v[0] > t.back())) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "time must increase strictly: t = %.9g follows t = %.9g", v[0], t.back());
      f.fail(buf);
    }
    DeviceSample d;
    d.pose.p = {v[1], v[2], v[3]};
    d.pose.q = {v[4], v[5], v[6], v[7]};
    d.pose.jaw = v[8];
    d.buttons = static_cast<unsigned>(buttons);
    d.fresh = true;
    t.push_back(v[0]);
    s.push_back(d);
  }
  if (!header) f.fail_at(std::max(f.line(), 1), "no header: expected t,x,y,z,qw,qx,qy,qz,jaw,buttons");
  if (t.empty()) f.fail_at(std::max(f.line(), 1), "no sample after the header; at least one is needed");
}

}  // namespace

ReplayDevice ReplayDevice::read_file(const std::string& path, double max_force) {
  meshio::TextFile f(path);
  return parse(f.text(), path, max_force);
}

ReplayDevice ReplayDevice::parse(const std::string& text, const std::string& path, double max_force) {
  if (!(max_force > 0.0) || !std::isfinite(max_force))
    throw Error(path + ": the device's force limit must be a finite number > 0");
  meshio::TextFile f = meshio::TextFile::from_text(path, text);
  ReplayDevice d;
  d.path_ = path;
  d.max_force_ = max_force;
  parse_stream(f, d.t_, d.s_);
  return d;
}

std::string ReplayDevice::describe() const {
  char buf[64];
  std::snprintf(buf, sizeof buf, " (%d samples, %.3f s)", samples(), end_time());
  return "replay of " + path_ + buf;
}

bool ReplayDevice::read(double t, DeviceSample& out) {
  const size_t before = next_;
  while (next_ < t_.size() && t_[next_] <= t) ++next_;
  if (next_ == 0) return false;
  out = s_[next_ - 1];
  out.fresh = next_ != before;
  return true;
}

}  // namespace incise
