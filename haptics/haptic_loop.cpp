#include "haptics/haptic_loop.h"

#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "engine/runtime/alloc_counter.h"
#include "engine/runtime/thread_affinity.h"
#include "engine/util/error.h"

namespace incise {
namespace {

long long monotonic_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<long long>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

timespec to_timespec(long long ns) {
  timespec ts;
  ts.tv_sec = static_cast<time_t>(ns / 1000000000LL);
  ts.tv_nsec = static_cast<long>(ns % 1000000000LL);
  return ts;
}

// SCHED_FIFO at 80 (above the kernel's threaded interrupts at 50), or the
// highest RLIMIT_RTPRIO grants an unprivileged process; the result in words.
std::string take_realtime_policy(bool wanted) {
  if (!wanted) return "SCHED_OTHER (haptics.realtime is false)";
  int prio = 80;
  rlimit rl{};
  if (getrlimit(RLIMIT_RTPRIO, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY && rl.rlim_cur > 0 &&
      static_cast<long long>(rl.rlim_cur) < prio)
    prio = static_cast<int>(rl.rlim_cur);
  sched_param sp{};
  sp.sched_priority = prio;
  const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  if (err == 0) return "SCHED_FIFO priority " + std::to_string(prio);
  return std::string("SCHED_OTHER: SCHED_FIFO refused (") + std::strerror(err) +
         "; it needs root, CAP_SYS_NICE or an RLIMIT_RTPRIO, e.g. `ulimit -r 80`), so ticks can wait behind other "
         "threads";
}

}  // namespace

HapticLoop::HapticLoop(std::unique_ptr<HapticDevice> device, const HapticSettings& s, const ToolPose& start)
    : device_(std::move(device)), s_(s), guard_(s.guard, start) {
  if (!device_) throw Error("haptics: no device");
  if (!(s_.rate_hz > 0.0)) throw Error("haptics: rate_hz must be > 0, got " + std::to_string(s_.rate_hz));
  if (!(s_.stiffness > 0.0)) throw Error("haptics: coupling.stiffness must be > 0, got " + std::to_string(s_.stiffness));
  if (!(s_.frame_dt > 0.0)) throw Error("haptics: the frame's dt must be > 0, got " + std::to_string(s_.frame_dt));
  force_limit_ = std::min(s_.max_force, device_->max_force());
  if (!(force_limit_ > 0.0)) throw Error("haptics: the device's force limit must be > 0, got " + std::to_string(force_limit_));
  blend_ticks_ = std::max(1, static_cast<int>(std::lround(s_.rate_hz * s_.frame_dt)));
  current_ = &models_.read_buffer();  // empty: rows = 0, no force until the first frame's model
  poses_read_.device = start;
  poses_read_.proxy = start.p;
}

HapticLoop::~HapticLoop() { stop(); }

double HapticLoop::now() const { return 1e-9 * static_cast<double>(monotonic_ns() - t0_ns_); }

void HapticLoop::start() {
  if (thread_.joinable()) return;
  device_->start();
  set_thread_role(ThreadRole::Stepping);  // the caller steps: a CPU of its own (false with one CPU)
  stop_ = false;
  scheduled_ = false;
  t0_ns_ = monotonic_ns();
  thread_ = std::thread([this] { run(); });
  while (!scheduled_.load(std::memory_order_acquire)) std::this_thread::yield();
}

void HapticLoop::stop() {
  if (thread_.joinable()) {
    stop_ = true;
    thread_.join();
  }
  device_->stop();
}

std::string HapticLoop::scheduling() const { return scheduled_ ? scheduling_ : "not started"; }

void HapticLoop::drain(std::vector<TickRecord>& records, std::vector<HapticEvent>& events) {
  records_.consume_all([&](const TickRecord& r) { records.push_back(r); });
  events_.consume_all([&](const HapticEvent& e) { events.push_back(e); });
}

void HapticLoop::log_event(double t, HapticEventKind kind, const std::array<double, 3>& value) {
  HapticEvent e;
  e.t = t;
  e.kind = kind;
  e.value = value;
  if (!events_.push(e)) dropped_.fetch_add(1, std::memory_order_relaxed);
}

void HapticLoop::run() {
  std::string where;
  if (stepping_cpu() < 0)
    where = ", CPU chosen by the kernel (one CPU: the stepping thread has none of its own)";
  else if (set_thread_role(ThreadRole::Helper))
    where = ", off the stepping thread's CPU " + std::to_string(stepping_cpu());
  else
    where = ", on the stepping thread's CPU " + std::to_string(stepping_cpu()) + " (the kernel refused to move it)";
  // The default 50 us timer slack would make every wake-up that late.
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  scheduling_ = take_realtime_policy(s_.realtime) + where;
  scheduled_.store(true, std::memory_order_release);
  const long long period = static_cast<long long>(std::llround(1e9 / s_.rate_hz));
  long long next = t0_ns_ + period;
  while (!stop_.load(std::memory_order_relaxed)) {
    const timespec ts = to_timespec(next);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
    const long long woke = monotonic_ns();
    // A tick that wakes after its successor's deadline: the missed ones are
    // dropped (a force is only worth sending now) and the event logged.
    const long long behind = (woke - next) / period;
    if (behind >= 1) {
      log_event(1e-9 * static_cast<double>(woke - t0_ns_), HapticEventKind::Overrun,
                {1e-6 * static_cast<double>(woke - next), static_cast<double>(behind), 0.0});
      next += behind * period;
    }
    tick(1e-9 * static_cast<double>(woke - t0_ns_), 1e-9 * static_cast<double>(next - t0_ns_));
    next += period;
  }
}

void HapticLoop::tick(double t, double deadline) {
  const std::uint64_t allocs0 = thread_allocations();
  const long long start_ns = monotonic_ns();
  TickRecord rec;
  rec.t = t;
  rec.deadline = deadline;
  rec.have_reading = device_->read(t, rec.raw);
  ToolPose mapped = rec.raw.pose;
  for (int k = 0; k < 3; ++k) mapped.p[k] = s_.scale * rec.raw.pose.p[k] + s_.offset[k];
  HapticEvent ev;
  bool has_event = false;
  const ToolPose& pose = guard_.filter(t, mapped, rec.have_reading && rec.raw.fresh, &ev, &has_event);
  if (has_event) log_event(ev.t, ev.kind, ev.value);

  // A new model only after the last blend ended: blending from a blend would jump.
  if (blend_left_ == 0 && models_.fresh()) {
    // Copied before the swap: update() hands the current buffer back to the writer.
    previous_ = *current_;
    lambda_previous_ = lambda_current_;
    models_.update();
    current_ = &models_.read_buffer();
    std::copy_n(current_->lambda0.begin(), current_->rows, lambda_current_.begin());
    blend_left_ = blend_ticks_;
  }
  int sweeps = 0, sw = 0;
  std::array<double, 3> spring = coupling_force(*current_, pose.p, lambda_current_.data(), &sw);
  sweeps += sw;
  if (blend_left_ > 0) {
    // Linear blend from the replaced model over one frame's ticks: a model
    // that disagrees with the last by F changes the force by F / blend_ticks
    // per tick at most (docs/haptics.md, "Continuity").
    const std::array<double, 3> old = coupling_force(previous_, pose.p, lambda_previous_.data(), &sw);
    sweeps += sw;
    const double w = static_cast<double>(blend_ticks_ - blend_left_ + 1) / blend_ticks_;
    rec.blend_gap = static_cast<float>(std::sqrt((spring[0] - old[0]) * (spring[0] - old[0]) + (spring[1] - old[1]) * (spring[1] - old[1]) +
                                                 (spring[2] - old[2]) * (spring[2] - old[2])));
    for (int k = 0; k < 3; ++k) spring[k] = (1.0 - w) * old[k] + w * spring[k];
    --blend_left_;
  }
  // Coupling damping on the proxy's velocity relative to the device: the
  // proxy sits at x_d + spring / k, so that velocity is d(spring)/dt / k,
  // low-passed at 100 Hz against the tick-to-tick noise of the solve.
  std::array<double, 3> force = spring;
  const double dt = t_prev_ < 0.0 ? 0.0 : t - t_prev_;
  if (dt > 0.0 && s_.damping > 0.0) {
    const double alpha = 1.0 - std::exp(-2.0 * M_PI * 100.0 * dt);
    for (int k = 0; k < 3; ++k) {
      rel_velocity_[k] += alpha * ((spring[k] - spring_prev_[k]) / (s_.stiffness * dt) - rel_velocity_[k]);
      force[k] += s_.damping * rel_velocity_[k];
    }
  }
  t_prev_ = t;
  spring_prev_ = spring;
  bool finite = true;
  for (double f : force) finite = finite && std::isfinite(f);
  if (!finite) {
    log_event(t, HapticEventKind::ForceNotFinite, force);
    force = spring = spring_prev_ = rel_velocity_ = {0.0, 0.0, 0.0};
    std::copy_n(current_->lambda0.begin(), current_->rows, lambda_current_.begin());
    std::copy_n(previous_.lambda0.begin(), previous_.rows, lambda_previous_.begin());
  }
  const double fn = std::sqrt(force[0] * force[0] + force[1] * force[1] + force[2] * force[2]);
  if (fn > force_limit_) {
    if (!clamped_) log_event(t, HapticEventKind::ForceClamped, force);
    for (double& f : force) f *= force_limit_ / fn;
  }
  clamped_ = fn > force_limit_;
  device_->write_force(t, force);

  Poses& out = poses_.write_buffer();
  out.device = pose;
  for (int k = 0; k < 3; ++k) out.proxy[k] = pose.p[k] + spring[k] / s_.stiffness;
  poses_.publish();

  rec.force = force;
  rec.sweeps = static_cast<std::int16_t>(std::min(sweeps, 32767));
  rec.compute_us = static_cast<float>(1e-3 * static_cast<double>(monotonic_ns() - start_ns));
  rec.allocations = static_cast<std::uint32_t>(thread_allocations() - allocs0);
  if (!records_.push(rec)) dropped_.fetch_add(1, std::memory_order_relaxed);
  ticks_.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace incise
