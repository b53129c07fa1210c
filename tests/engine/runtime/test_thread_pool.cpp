// ThreadPool (engine/runtime/thread_pool.h): run(fn) calls fn on the first
// active() workers only, tid 0 on the caller; barrier() counts those; the
// workers stood down by set_active come back when it is raised again.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

#include "engine/runtime/thread_pool.h"

namespace incise {
namespace {

TEST(ThreadPool, RunsTheActiveWorkersOnly) {
  ThreadPool pool(3);
  EXPECT_EQ(pool.active(), 3);
  for (int active : {3, 1, 2, 3}) {
    pool.set_active(active);
    ASSERT_EQ(pool.active(), active);
    std::vector<std::atomic<int>> calls(3);
    std::atomic<int> after_barrier{0};
    std::thread::id caller = std::this_thread::get_id(), ran_as_0;
    pool.run([&](int tid) {
      ++calls[tid];
      if (tid == 0) ran_as_0 = std::this_thread::get_id();
      pool.barrier();  // returns only once every active worker has arrived
      EXPECT_EQ(calls[0] + calls[1] + calls[2], active);
      ++after_barrier;
    });
    EXPECT_EQ(ran_as_0, caller);
    EXPECT_EQ(after_barrier, active);
    for (int t = 0; t < 3; ++t) EXPECT_EQ(calls[t], t < active ? 1 : 0) << "worker " << t << ", " << active << " active";
  }
  EXPECT_EQ(pool.size(), 3);
  pool.set_active(0);
  EXPECT_EQ(pool.active(), 1);
  pool.set_active(9);
  EXPECT_EQ(pool.active(), 3);
}

}  // namespace
}  // namespace incise
