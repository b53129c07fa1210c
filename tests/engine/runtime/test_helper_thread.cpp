// engine/runtime/helper_thread.h: one long-lived thread per helper role, its tasks in
// order and one at a time, its priority taken once (its CPUs:
// test_thread_affinity.cpp).
#include <gtest/gtest.h>

#include <sched.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "engine/runtime/helper_thread.h"

namespace incise {
namespace {

TEST(HelperThread, RunsTasksInOrderOneAtATimeOnOneThread) {
  HelperThread helper(/*helper_cpus=*/false, HelperThread::Priority::Normal);
  std::vector<int> order;
  std::atomic<int> running{0}, overlap{0};
  std::thread::id first;
  for (int k = 0; k < 200; ++k)
    helper.run([&, k] {  // run() waits for the task before: `order` needs no lock
      if (running.fetch_add(1) != 0) overlap.fetch_add(1);
      if (k == 0) first = std::this_thread::get_id();
      else if (std::this_thread::get_id() != first) overlap.fetch_add(1000);
      if (k % 50 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
      order.push_back(k);
      running.fetch_sub(1);
    });
  helper.wait();
  ASSERT_EQ(order.size(), 200u);
  for (int k = 0; k < 200; ++k) EXPECT_EQ(order[k], k);
  EXPECT_EQ(overlap.load(), 0);
  EXPECT_NE(first, std::this_thread::get_id());
}

TEST(HelperThread, DestructorFinishesThePendingTask) {
  std::atomic<bool> ran{false};
  {
    HelperThread helper(false, HelperThread::Priority::Normal);
    helper.run([&] {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      ran = true;
    });
  }
  EXPECT_TRUE(ran.load());
}

TEST(HelperThread, IdlePriorityRunsUnderSchedIdle) {
  HelperThread idle(false, HelperThread::Priority::Idle), normal(false, HelperThread::Priority::Normal);
  int seen_idle = -2, seen_normal = -2;
  idle.run([&] { seen_idle = sched_getscheduler(0); });
  normal.run([&] { seen_normal = sched_getscheduler(0); });
  idle.wait();
  normal.wait();
  EXPECT_EQ(seen_idle, SCHED_IDLE);
  EXPECT_EQ(idle.policy(), SCHED_IDLE);
  EXPECT_EQ(seen_normal, SCHED_OTHER);
  EXPECT_EQ(normal.policy(), SCHED_OTHER);
}

}  // namespace
}  // namespace incise
