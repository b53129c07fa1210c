#pragma once
// A small fixed pool of worker threads for the simulation thread's stages
// (assembly, rotations, matrix-vector products). `run(fn)` calls fn(tid) on
// every worker, tid 0 being the calling thread itself, and returns when all are
// done. Workers sleep on a condition variable between calls, so an idle pool
// costs no CPU; `barrier()` synchronises the workers of one call (spin, then
// yield, so a descheduled peer on a loaded 2-core machine is not starved).
//
// The pool size is solver.threads (default 2). With 1 the pool starts no
// thread and run(fn) is fn(0): that is how a core is left for the 1 kHz haptic
// thread on a 2-core machine.
#include <atomic>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace incise {

class ThreadPool {
 public:
  explicit ThreadPool(int nthreads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return nthreads_; }
  // The workers a run() uses, the first `active()` of size() (all unless
  // set_active said fewer): a caller splits its work over active(), while
  // per-worker plans stay sized for size(). With 1, run(fn) is fn(0) and
  // wakes no worker (linear_solve.cpp stands the workers down while a late
  // background factorization needs their CPU). Not during a run().
  int active() const { return active_; }
  void set_active(int k) { active_ = k < 1 ? 1 : k > nthreads_ ? nthreads_ : k; }
  // fn(tid) for tid in [0, active()), tid 0 on the calling thread. Not reentrant.
  void run(const std::function<void(int)>& fn);
  // Called by every worker of the current run(); returns when all have arrived.
  void barrier();

  // [begin, end) of item range [0, n) for worker tid (contiguous, balanced).
  static void split(int n, int nthreads, int tid, int& begin, int& end) {
    begin = static_cast<int>(static_cast<long long>(n) * tid / nthreads);
    end = static_cast<int>(static_cast<long long>(n) * (tid + 1) / nthreads);
  }

 private:
  void worker(int tid);
  int nthreads_;
  int active_;
  int job_active_ = 1;  // active_ of the run in progress (read by the workers under mutex_)
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(int)>* job_ = nullptr;
  long long generation_ = 0;
  int pending_ = 0;
  bool stop_ = false;
  std::atomic<int> barrier_count_{0};
  std::atomic<int> barrier_generation_{0};
};

}  // namespace incise
