// engine/helper_thread.h: one long-lived thread per helper role, its tasks in
// order and one at a time, its priority and CPUs taken once; and the
// substitution worker's CPUs under solver.affinity "split".
#include <gtest/gtest.h>

#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "engine/helper_thread.h"
#include "engine/split_substitution.h"
#include "engine/thread_affinity.h"

namespace incise {
namespace {

cpu_set_t current_cpus() {
  cpu_set_t s;
  CPU_ZERO(&s);
  pthread_getaffinity_np(pthread_self(), sizeof s, &s);
  return s;
}

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

// Under "split" the helper threads and the substitution worker stay off the
// stepping thread's CPU, even when the pinned stepping thread creates them.
TEST(HelperThread, SplitKeepsHelpersAndTheSubstitutionWorkerOffTheSteppingCpu) {
  const cpu_set_t all = current_cpus();
  if (CPU_COUNT(&all) < 2) GTEST_SKIP() << "one CPU: nothing is pinned";
  std::thread stepping([&] {
    ASSERT_TRUE(set_thread_role(ThreadRole::Stepping));
    const int step_cpu = stepping_cpu();
    HelperThread helper(/*helper_cpus=*/true, HelperThread::Priority::Normal);
    cpu_set_t in_task;
    helper.run([&] { in_task = current_cpus(); });
    helper.wait();
    EXPECT_FALSE(CPU_ISSET(step_cpu, &in_task));
    EXPECT_EQ(CPU_COUNT(&in_task), CPU_COUNT(&all) - 1);
    SubstitutionWorker worker;
    struct Ctx {
      cpu_set_t cpus;
    } c;
    ASSERT_TRUE(worker.try_start([](void* p) { static_cast<Ctx*>(p)->cpus = current_cpus(); }, &c));
    worker.wait();
    EXPECT_FALSE(CPU_ISSET(step_cpu, &c.cpus));
  });
  stepping.join();
}

}  // namespace
}  // namespace incise
