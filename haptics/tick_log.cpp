#include "haptics/tick_log.h"

#include <cerrno>
#include <cstring>
#include <unistd.h>

#include "engine/util/error.h"

namespace incise {

TickLogWriter::TickLogWriter(std::string force_path, std::string device_path) {
  force_.path = std::move(force_path);
  device_.path = std::move(device_path);
  open(force_, "t,fx,fy,fz,tick_us,late_us\n");
  open(device_, "# device readings as received (haptics/replay_device.h)\nt,x,y,z,qw,qx,qy,qz,jaw,buttons\n");
}

TickLogWriter::~TickLogWriter() {
  for (Out* o : {&force_, &device_})
    if (o->f) {
      std::fclose(o->f);
      std::remove(o->tmp.c_str());
    }
}

void TickLogWriter::open(Out& o, const char* header) {
  if (o.path.empty()) return;
  o.tmp = o.path + ".tmp" + std::to_string(::getpid());
  o.f = std::fopen(o.tmp.c_str(), "wb");
  if (!o.f) throw Error(o.path + ": cannot write: " + std::strerror(errno));
  check(o, std::fputs(header, o.f) >= 0);
}

void TickLogWriter::check(Out& o, bool ok) {
  if (ok) return;
  const int err = errno;
  std::fclose(o.f);
  o.f = nullptr;
  std::remove(o.tmp.c_str());
  throw Error(o.path + ": cannot write: " + std::strerror(err));
}

void TickLogWriter::append(const std::vector<TickRecord>& records) {
  for (const TickRecord& r : records) {
    if (force_.f)
      check(force_, std::fprintf(force_.f, "%.6f,%.9g,%.9g,%.9g,%.2f,%.2f\n", r.t, r.force[0], r.force[1], r.force[2],
                                 static_cast<double>(r.compute_us), 1e6 * (r.t - r.deadline)) > 0);
    if (device_.f && r.have_reading && r.raw.fresh) {
      const ToolPose& p = r.raw.pose;
      check(device_, std::fprintf(device_.f, "%.9f,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%u\n", r.t, p.p[0],
                                  p.p[1], p.p[2], p.q[0], p.q[1], p.q[2], p.q[3], p.jaw, r.raw.buttons) > 0);
    }
  }
}

void TickLogWriter::finish() {
  for (Out* o : {&force_, &device_}) {
    if (!o->f) continue;
    std::FILE* f = o->f;
    o->f = nullptr;
    if (std::fclose(f) != 0 || std::rename(o->tmp.c_str(), o->path.c_str()) != 0) {
      const int err = errno;
      std::remove(o->tmp.c_str());
      throw Error(o->path + ": cannot write: " + std::strerror(err));
    }
  }
}

}  // namespace incise
