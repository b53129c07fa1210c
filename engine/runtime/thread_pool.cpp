#include "engine/runtime/thread_pool.h"

#include "engine/runtime/thread_affinity.h"

namespace incise {

ThreadPool::ThreadPool(int nthreads) : nthreads_(nthreads < 1 ? 1 : nthreads), active_(nthreads_) {
  for (int t = 1; t < nthreads_; ++t) threads_.emplace_back([this, t] { worker(t); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (auto& t : threads_) t.join();
}

void ThreadPool::worker(int tid) {
  unpin_if_split();  // started by a pinned stepping thread: not on its one CPU
  long long seen = 0;
  for (;;) {
    const std::function<void(int)>* job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      job = job_;
      if (tid >= job_active_) continue;  // stood down for this run
    }
    // Off the stepping thread's CPU once it has one (split affinity): the
    // stepping thread runs worker 0's share there, so a worker beside it ran
    // only while it waited (hang-20k, 2 workers: half the worker's samples on
    // the stepping CPU, assembly 4.7 -> 6.0 ms instead of faster).
    helper_if_split();
    (*job)(tid);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (--pending_ == 0) done_.notify_one();
    }
  }
}

void ThreadPool::run(const std::function<void(int)>& fn) {
  if (active_ == 1) {
    fn(0);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ = &fn;
    job_active_ = active_;
    pending_ = active_ - 1;
    ++generation_;
  }
  wake_.notify_all();
  fn(0);
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [&] { return pending_ == 0; });
  job_ = nullptr;
}

void ThreadPool::barrier() {
  if (active_ == 1) return;
  const int gen = barrier_generation_.load(std::memory_order_acquire);
  if (barrier_count_.fetch_add(1, std::memory_order_acq_rel) + 1 == active_) {
    barrier_count_.store(0, std::memory_order_relaxed);
    barrier_generation_.fetch_add(1, std::memory_order_acq_rel);
    return;
  }
  for (int spin = 0; barrier_generation_.load(std::memory_order_acquire) == gen; ++spin)
    if (spin > 2000) std::this_thread::yield();
}

}  // namespace incise
