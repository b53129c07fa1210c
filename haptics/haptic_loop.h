#pragma once
// The 1 kHz haptic loop (../shared/DESIGN.md, "The loops"): a thread that
// wakes on absolute deadlines (clock_nanosleep, TIMER_ABSTIME: a late tick
// does not push the later ones back), reads the device, checks the reading
// (haptics/input_guard.h), solves the virtual coupling against the contact
// model the simulation last published (haptics/contact_model.h), clamps the
// force to the device's limit, writes it, and hands the checked device pose
// to the simulation (which holds the tool there through the same spring). The tick allocates nothing and takes no lock: models and
// poses cross between the threads through triple buffers, the force log and
// events through single-producer queues the main thread drains.
//
// Scheduling: SCHED_FIFO where the process may (root, CAP_SYS_NICE or
// RLIMIT_RTPRIO), else the default policy, said in scheduling(). On the
// helpers' CPUs when the stepping thread has a CPU of its own
// (engine/runtime/thread_affinity.h; start() gives it one), so a cut frame,
// which keeps the stepping CPU busy for tens of milliseconds, never delays a
// tick: on this kernel a woken thread of the same priority can wait a whole
// 4 ms scheduler tick behind a running one.
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <boost/lockfree/spsc_queue.hpp>

#include "haptics/contact_model.h"
#include "haptics/device.h"
#include "haptics/input_guard.h"
#include "haptics/triple_buffer.h"

namespace incise {

struct HapticSettings {
  int instrument = 0;          // the scene instrument the device drives
  double rate_hz = 1000.0;     // ticks per second
  double frame_dt = 1.0 / 30;  // the simulation's frame: a new model is blended in over one frame's ticks
  double stiffness = 1000.0;   // virtual coupling spring k (N per scene unit)
  double damping = 0.5;        // on the proxy's velocity relative to the device (N s per unit)
  double max_force = 3.3;      // N; the device's own limit applies too (the smaller)
  double scale = 1.0;          // device units -> scene units
  std::array<double, 3> offset{};
  GuardSettings guard;
  bool realtime = true;        // try SCHED_FIFO
};

// One tick, for the force log (t, fx, fy, fz, tick_us, late_us) and the
// recorded device stream.
struct TickRecord {
  double t = 0.0;                   // wake-up time, s since the loop started
  double deadline = 0.0;            // when it should have woken
  std::array<double, 3> force{};    // sent to the device (N)
  float compute_us = 0.0f;          // the tick's work after waking
  std::uint32_t allocations = 0;    // heap allocations during the tick (engine/runtime/alloc_counter.h)
  std::int16_t sweeps = 0;          // coupling solve sweeps (both models while blending)
  float blend_gap = 0.0f;           // blending: |f_new - f_old| of the two models at this pose (N); else 0
  bool have_reading = false;        // the device had a reading (raw is valid)
  DeviceSample raw;                 // the device's reading, as read (before mapping and checks)
};

class HapticLoop {
 public:
  HapticLoop(std::unique_ptr<HapticDevice> device, const HapticSettings& s, const ToolPose& start);
  ~HapticLoop();
  HapticLoop(const HapticLoop&) = delete;
  HapticLoop& operator=(const HapticLoop&) = delete;

  // Starts the device and the thread; the loop's clock starts now. Call it
  // from the stepping thread: with two CPUs or more it is pinned to one of
  // its own (unless already), and the haptic thread to the others. Throws
  // incise::Error when the device cannot start.
  void start();
  // Stops the thread and the device; idempotent.
  void stop();
  bool running() const { return thread_.joinable(); }
  // Seconds since start() on the loop's clock (CLOCK_MONOTONIC).
  double now() const;

  // --- simulation thread -------------------------------------------------
  // Fill model_buffer() whole, then publish_model(); never waits.
  HapticContactModel& model_buffer() { return models_.write_buffer(); }
  void publish_model() { models_.publish(); }
  // The latest tick's device pose, as checked (the start pose before the
  // first): where the simulation puts the instrument, held by the coupling
  // spring; and the proxy, where the spring leaves the tool in contact
  // (x_d + f / k), for drawing it.
  const ToolPose& device_pose() { refresh_poses(); return poses_read_.device; }
  ToolPose proxy_pose() {
    refresh_poses();
    ToolPose p = poses_read_.device;
    p.p = poses_read_.proxy;
    return p;
  }

  // --- any one other thread (the main loop) ------------------------------
  // Appends what the thread produced since the last call.
  void drain(std::vector<TickRecord>& records, std::vector<HapticEvent>& events);
  // Records and events the queues had no room for (the drain came too late).
  std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  std::uint64_t ticks() const { return ticks_.load(std::memory_order_relaxed); }
  // What the thread got: "SCHED_FIFO priority 80, CPU 0 (stepping thread: CPU 1)" or why not.
  std::string scheduling() const;
  const HapticDevice& device() const { return *device_; }
  const HapticSettings& settings() const { return s_; }
  double force_limit() const { return force_limit_; }
  int blend_ticks() const { return blend_ticks_; }
  // The model the ticks use now (the haptic thread's, or a test's that calls tick()).
  const HapticContactModel& current_model() const { return *current_; }

  // One tick at loop time t (its deadline: `deadline`). The thread calls it;
  // tests call it directly, without the thread, for exact repeatability.
  void tick(double t, double deadline);

 private:
  void run();
  // To the events queue, or counted as dropped when it is full.
  void log_event(double t, HapticEventKind kind, const std::array<double, 3>& value);
  void refresh_poses() {
    if (poses_.update()) poses_read_ = poses_.read_buffer();
  }

  std::unique_ptr<HapticDevice> device_;
  HapticSettings s_;
  double force_limit_;
  int blend_ticks_;
  InputGuard guard_;
  // Models: the reader's current one lives in the triple buffer; the one it
  // replaced is copied here to blend from.
  TripleBuffer<HapticContactModel> models_;
  const HapticContactModel* current_;
  HapticContactModel previous_;
  std::array<double, kMaxHapticRows> lambda_current_{}, lambda_previous_{};
  int blend_left_ = 0;
  std::array<double, 3> spring_prev_{};  // the coupling force of the previous tick
  std::array<double, 3> rel_velocity_{}; // filtered proxy velocity relative to the device
  double t_prev_ = -1.0;
  bool clamped_ = false;
  struct Poses {
    ToolPose device;
    std::array<double, 3> proxy{};
  };
  TripleBuffer<Poses> poses_;
  Poses poses_read_;
  boost::lockfree::spsc_queue<TickRecord, boost::lockfree::capacity<1 << 14>> records_;
  boost::lockfree::spsc_queue<HapticEvent, boost::lockfree::capacity<1024>> events_;
  std::atomic<std::uint64_t> dropped_{0}, ticks_{0};
  std::atomic<bool> stop_{false};
  std::string scheduling_;
  std::atomic<bool> scheduled_{false};
  long long t0_ns_ = 0;
  std::thread thread_;
};

}  // namespace incise
