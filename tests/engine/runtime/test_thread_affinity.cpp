// solver.affinity "split" (engine/runtime/thread_affinity.h): the stepping thread on
// the last CPU of the process's set, helpers on the others, and workers that
// a pinned thread starts back on the whole set; the helper threads, the
// substitution worker and the assembly workers off the stepping CPU. Run on threads of their own:
// the test's main thread stays where it was.
#include <gtest/gtest.h>

#include <pthread.h>
#include <sched.h>

#include <thread>

#include "engine/runtime/helper_thread.h"
#include "engine/runtime/thread_pool.h"
#include "engine/solve/split_substitution.h"
#include "engine/runtime/thread_affinity.h"

namespace incise {
namespace {

cpu_set_t current_cpus() {
  cpu_set_t s;
  CPU_ZERO(&s);
  pthread_getaffinity_np(pthread_self(), sizeof s, &s);
  return s;
}

TEST(ThreadAffinity, SplitGivesTheSteppingThreadOneCpuAndTheHelpersTheRest) {
  const cpu_set_t all = current_cpus();
  const int n = CPU_COUNT(&all);
  int last = -1;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &all)) last = c;
  std::thread stepping([&] {
    const bool pinned = set_thread_role(ThreadRole::Stepping);
    if (n < 2) {  // nothing to split: nothing pinned, the set unchanged
      EXPECT_FALSE(pinned);
      cpu_set_t now = current_cpus();
      EXPECT_TRUE(CPU_EQUAL(&now, &all));
      return;
    }
    ASSERT_TRUE(pinned);
    EXPECT_EQ(stepping_cpu(), last);
    cpu_set_t mine = current_cpus();
    EXPECT_EQ(CPU_COUNT(&mine), 1);
    EXPECT_TRUE(CPU_ISSET(last, &mine));
    // A worker started from here inherits the one CPU, then takes the whole set back.
    std::thread worker([&] {
      cpu_set_t inherited = current_cpus();
      EXPECT_EQ(CPU_COUNT(&inherited), 1);
      unpin_if_split();
      cpu_set_t now = current_cpus();
      EXPECT_TRUE(CPU_EQUAL(&now, &all));
    });
    worker.join();
    std::thread helper([&] {
      ASSERT_TRUE(set_thread_role(ThreadRole::Helper));
      cpu_set_t now = current_cpus();
      EXPECT_EQ(CPU_COUNT(&now), n - 1);
      EXPECT_FALSE(CPU_ISSET(last, &now));
      unpin_if_split();  // a thread with a role keeps it
      now = current_cpus();
      EXPECT_FALSE(CPU_ISSET(last, &now));
    });
    helper.join();
  });
  stepping.join();
}

// Under "split" the helper threads and the substitution worker stay off the
// stepping thread's CPU, even when the pinned stepping thread creates them.
TEST(ThreadAffinity, HelpersAndTheSubstitutionWorkerStayOffTheSteppingCpu) {
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

// The assembly workers start before the stepping thread is pinned
// (prepare_workers) and then leave its CPU at their next job: the stepping
// thread runs worker 0's share there, so a worker beside it would only run
// while it waits.
TEST(ThreadAffinity, AssemblyWorkersLeaveTheSteppingCpu) {
  const cpu_set_t all = current_cpus();
  if (CPU_COUNT(&all) < 2) GTEST_SKIP() << "one CPU: nothing is pinned";
  std::thread stepping([&] {
    ThreadPool pool(3);
    cpu_set_t before[3], after[3];
    pool.run([&](int tid) { before[tid] = current_cpus(); });
    for (int t = 1; t < 3; ++t) EXPECT_TRUE(CPU_EQUAL(&before[t], &all));  // nothing pinned yet
    ASSERT_TRUE(set_thread_role(ThreadRole::Stepping));
    const int step_cpu = stepping_cpu();
    pool.run([&](int tid) { after[tid] = current_cpus(); });
    EXPECT_EQ(CPU_COUNT(&after[0]), 1);
    EXPECT_TRUE(CPU_ISSET(step_cpu, &after[0]));
    for (int t = 1; t < 3; ++t) {
      EXPECT_FALSE(CPU_ISSET(step_cpu, &after[t])) << "worker " << t;
      EXPECT_EQ(CPU_COUNT(&after[t]), CPU_COUNT(&all) - 1) << "worker " << t;
    }
  });
  stepping.join();
}

}  // namespace
}  // namespace incise
