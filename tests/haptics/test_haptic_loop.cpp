// The haptic loop (haptics/haptic_loop.h): the tick allocates nothing over
// 10,000 ticks on its own thread while the simulation steps; deadlines are
// absolute (whole periods from the start, however late a tick woke); bad
// device input (NaN, a pose 10 m away, a teleport) is rejected and logged,
// the last good pose holds, a device that stays where it jumped is taken
// back by gliding, and the force stays finite and under the device's limit.
#include <atomic>
#include <cmath>
#include <map>
#include <thread>

#include <gtest/gtest.h>

#include "engine/runtime/alloc_counter.h"
#include "haptics/replay_device.h"
#include "haptics/scripted_device.h"
#include "tests/haptics/haptic_test_util.h"

namespace incise {
namespace {

using test::kBlockTop;
using test::kProbeRadius;

const double kTouch = kBlockTop + kProbeRadius;

std::vector<std::array<double, 4>> press_and_hold() {
  return {{0.0, 0.05, 0.05, kTouch + 0.002}, {0.3, 0.05, 0.05, kTouch - 0.004}, {100.0, 0.05, 0.05, kTouch - 0.004}};
}

// Where allocations escape, so that the compiler may not elide them.
std::atomic<int*> g_sink{nullptr};

TEST(HapticLoop, TheCounterSeesAnAllocation) {
  const std::uint64_t before = thread_allocations();
  g_sink = new int(7);
  EXPECT_EQ(thread_allocations(), before + 1);
  delete g_sink.exchange(nullptr);
  // Per thread: a child's allocations do not show in the parent's count
  // (which the thread's start-up moves by the same amount either way).
  auto parent_delta = [](int child_allocations, std::uint64_t& child_count) {
    const std::uint64_t p0 = thread_allocations();
    std::thread([&] {
      const std::uint64_t c0 = thread_allocations();
      for (int i = 0; i < child_allocations; ++i) delete g_sink.exchange(new int(i));
      child_count = thread_allocations() - c0;
    }).join();
    return thread_allocations() - p0;
  };
  std::uint64_t one = 0, hundred = 0;
  const std::uint64_t d1 = parent_delta(1, one), d100 = parent_delta(100, hundred);
  EXPECT_EQ(one, 1u);
  EXPECT_EQ(hundred, 100u);
  EXPECT_EQ(d1, d100) << "the child's allocations are not the parent's";
  delete g_sink.exchange(nullptr);
}

TEST(HapticLoop, TheTickAllocatesNothingOverTenThousandTicksWithTheSimulationRunning) {
  HapticsSpec h;
  h.rate_hz = 5000;  // 10,000 ticks in 2 s
  h.realtime = false;
  auto b = test::make_haptic_block(test::scripted(press_and_hold()), {0.05, 0.05, kTouch + 0.002}, h);
  b.loop->start();
  int frames = 0;
  while (b.loop->ticks() < 10000 || frames < 10) {
    advance_frame(*b.sim);  // as fast as it goes: the models change under the ticks
    ++frames;
    b.loop->drain(b.records, b.events);
  }
  b.loop->stop();
  b.loop->drain(b.records, b.events);
  ASSERT_GE(b.records.size(), 10000u);
  EXPECT_EQ(b.loop->dropped(), 0u);
  std::uint64_t allocations = 0;
  int in_contact = 0;
  for (const TickRecord& r : b.records) {
    allocations += r.allocations;
    in_contact += test::norm(r.force) > 0.0;
  }
  EXPECT_EQ(allocations, 0u) << "over " << b.records.size() << " ticks and " << frames << " frames";
  EXPECT_GT(in_contact, 1000) << "the ticks solved contacts, not just free motion";
}

// The scripted device, with one read that stalls 3.5 ms (a device driver
// that hangs): the loop must skip the deadlines it missed, not run them late.
class StallingDevice : public ScriptedDevice {
 public:
  using ScriptedDevice::ScriptedDevice;
  bool read(double t, DeviceSample& out) override {
    if (++reads_ == 100) std::this_thread::sleep_for(std::chrono::microseconds(3500));
    return ScriptedDevice::read(t, out);
  }

 private:
  int reads_ = 0;
};

TEST(HapticLoop, DeadlinesStayWholePeriodsFromTheStartAfterAStall) {
  HapticsSpec h;
  h.realtime = false;
  auto device = std::make_unique<StallingDevice>(Trajectory::parse(test::probe_path(press_and_hold()), "p.csv"), "p.csv", 3.3);
  auto b = test::make_haptic_block(std::move(device), {0.05, 0.05, kTouch + 0.002}, h);
  b.loop->start();
  while (b.loop->ticks() < 300) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  b.loop->stop();
  b.loop->drain(b.records, b.events);
  EXPECT_EQ(b.loop->scheduling().rfind("SCHED_OTHER (haptics.realtime is false)", 0), 0u) << b.loop->scheduling();
  double prev = 0.0;
  int skipped = 0;
  for (const TickRecord& r : b.records) {
    const double k = r.deadline * 1000.0;
    EXPECT_NEAR(k, std::round(k), 1e-5) << "deadline " << r.deadline << " s is a whole number of 1 ms periods";
    EXPECT_GT(r.deadline, prev);
    EXPECT_GE(r.t, r.deadline - 1e-6) << "woken no earlier than the deadline";
    EXPECT_LT(r.t - r.deadline, 1e-3 + 1e-6) << "a tick runs within its period or is skipped";
    if (prev > 0.0) skipped += static_cast<int>(std::lround((r.deadline - prev) * 1000.0)) - 1;
    prev = r.deadline;
  }
  // The stalled tick ends 3.5 ms after its deadline D: D + 1 and D + 2 are
  // past, D + 3 is not yet (the loop wakes at once and runs it 0.5 ms late).
  EXPECT_GE(skipped, 2) << "the stall's missed deadlines were skipped";
  int overruns = 0;
  for (const HapticEvent& e : b.events) overruns += e.kind == HapticEventKind::Overrun;
  EXPECT_GE(overruns, 1);
}

TEST(HapticLoop, ARealTimeRequestIsGrantedOrRefusedInWords) {
  HapticsSpec h;  // realtime: true
  auto b = test::make_haptic_block(test::scripted(press_and_hold()), {0.05, 0.05, kTouch + 0.002}, h);
  b.loop->start();
  const std::string s = b.loop->scheduling();
  b.loop->stop();
  const bool granted = s.rfind("SCHED_FIFO priority ", 0) == 0;
  const bool refused = s.rfind("SCHED_OTHER: SCHED_FIFO refused (", 0) == 0;
  EXPECT_TRUE(granted || refused) << s;
}

// A replayed device stream, one reading per ms: pressing 4 mm into the block,
// then a NaN reading, a reading 10 m away, a 5 cm teleport for one reading,
// a non-unit quaternion, and finally a teleport 3 cm deeper into the tissue
// that stays (a re-homed device).
std::string hostile_stream(double t_stay) {
  std::string s = "t,x,y,z,qw,qx,qy,qz,jaw,buttons\n";
  char line[160];
  auto add = [&](double t, double x, double y, double z, double qw = 1.0) {
    std::snprintf(line, sizeof line, "%.4f,%.9g,%.9g,%.9g,%.9g,0,0,0,0,0\n", t, x, y, z, qw);
    s += line;
  };
  const double z0 = kTouch + 0.002, z1 = kTouch - 0.004;
  for (int i = 1; i <= 300; ++i) add(1e-3 * i, 0.05, 0.05, z0 + (z1 - z0) * std::min(1.0, i / 250.0));
  s += "0.3010,nan,0.05,0.05,1,0,0,0,0,0\n";
  add(0.302, 10.0, 0.05, 0.05);
  add(0.303, 0.10, 0.05, z1);
  add(0.304, 0.05, 0.05, z1, 1.5);
  for (int i = 305; i < 1000 * t_stay; ++i) add(1e-3 * i, 0.05, 0.05, z1);
  for (int i = static_cast<int>(1000 * t_stay); i < 1000 * t_stay + 1000; ++i) add(1e-3 * i, 0.05, 0.05, z1 - 0.03);
  return s;
}

TEST(HapticLoop, BadInputIsRejectedAndLoggedAndTheForceStaysBounded) {
  HapticsSpec h;
  h.damping = 0.0;
  const double t_stay = 0.5;
  auto device = std::make_unique<ReplayDevice>(ReplayDevice::parse(hostile_stream(t_stay), "hostile.csv", 2.0));
  auto b = test::make_haptic_block(std::move(device), {0.05, 0.05, kTouch + 0.002}, h);
  EXPECT_EQ(b.loop->force_limit(), 2.0) << "the device's limit, below the scene's 3.3 N";
  const double z1 = kTouch - 0.004;
  std::vector<std::array<double, 3>> pose_at_tick;
  const double period = 1e-3;
  while (b.t < t_stay + 1.0 - 0.5 * period) {
    b.step_until(b.t + period);
    pose_at_tick.push_back(b.loop->device_pose().p);
  }
  std::map<HapticEventKind, int> n;
  for (const HapticEvent& e : b.events) ++n[e.kind];
  EXPECT_EQ(n[HapticEventKind::NotFinite], 1);
  EXPECT_EQ(n[HapticEventKind::Workspace], 1);
  EXPECT_EQ(n[HapticEventKind::Jump], 2) << "the one-reading teleport and the one that stays";
  EXPECT_EQ(n[HapticEventKind::NotRotation], 1);
  EXPECT_EQ(n[HapticEventKind::Reacquired], 1);
  EXPECT_GE(n[HapticEventKind::ForceClamped], 1) << "3 cm deep asks for more than the device gives";
  // While the bad readings came (ticks 301-304) the pose held the last good one.
  for (int i = 300; i < 304; ++i) {
    EXPECT_NEAR(pose_at_tick[i][0], 0.05, 1e-12) << "tick " << i + 1;
    EXPECT_NEAR(pose_at_tick[i][2], z1, 1e-9) << "tick " << i + 1;
  }
  // After the lasting jump: held for guard.reacquire, then a glide at
  // guard.glide_speed (the hand itself moved slower than that here).
  double fastest = 0.0;
  for (size_t i = 1; i < pose_at_tick.size(); ++i)
    fastest = std::max(fastest, std::abs(pose_at_tick[i][2] - pose_at_tick[i - 1][2]) / period);
  EXPECT_LE(fastest, h.glide_speed * (1 + 1e-9)) << "the tool never moves faster than guard.glide_speed";
  const size_t back = static_cast<size_t>(1000 * (t_stay + h.reacquire)) + 40;
  ASSERT_LT(back, pose_at_tick.size());
  EXPECT_NEAR(pose_at_tick[back - 50][2], z1, 1e-9) << "still held before guard.reacquire ran out";
  EXPECT_NEAR(pose_at_tick.back()[2], z1 - 0.03, 1e-9) << "taken back in the end";
  for (const TickRecord& r : b.records) {
    ASSERT_TRUE(std::isfinite(r.force[0]) && std::isfinite(r.force[1]) && std::isfinite(r.force[2])) << r.t;
    ASSERT_LE(test::norm(r.force), 2.0 * (1 + 1e-12)) << r.t;
  }
  EXPECT_NEAR(test::norm(b.records.back().force), 2.0, 1e-9) << "at the limit, 3 cm deep";
}

}  // namespace
}  // namespace incise
