#include "engine/runtime/helper_thread.h"

#include <pthread.h>
#include <sched.h>

#include "engine/runtime/thread_affinity.h"

namespace incise {

HelperThread::HelperThread(bool helper_cpus, Priority priority)
    : helper_cpus_(helper_cpus), priority_(priority), thread_([this] { loop(); }) {}

HelperThread::~HelperThread() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_one();
  thread_.join();  // the loop finishes a pending task first
}

void HelperThread::run(std::function<void()> task) {
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [this] { return !pending_ && !busy_; });
  task_ = std::move(task);
  pending_ = true;
  lock.unlock();
  wake_.notify_one();
}

void HelperThread::wait() {
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [this] { return !pending_ && !busy_; });
}

int HelperThread::policy() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return policy_;
}

void HelperThread::loop() {
  if (helper_cpus_) set_thread_role(ThreadRole::Helper);
  else unpin_if_split();  // started by a pinned stepping thread: not on its one CPU
  if (priority_ == Priority::Idle) {
    sched_param sp{};
    pthread_setschedparam(pthread_self(), SCHED_IDLE, &sp);
  }
  std::unique_lock<std::mutex> lock(mutex_);
  policy_ = sched_getscheduler(0);
  for (;;) {
    wake_.wait(lock, [this] { return pending_ || stop_; });
    if (!pending_) return;  // stop_
    std::function<void()> task = std::move(task_);
    pending_ = false;
    busy_ = true;
    lock.unlock();
    task();  // tasks catch their own exceptions (an escaping one would end the process)
    task = nullptr;  // its captures go before the caller is told
    lock.lock();
    busy_ = false;
    done_.notify_all();
  }
}

}  // namespace incise
