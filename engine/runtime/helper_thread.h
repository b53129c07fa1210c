#pragma once
// A long-lived thread that runs one task at a time for the stepping thread:
// the cut-ahead helper (cutting/cut_apply.cpp) and the lagged policy's
// background factorization (engine/solve/linear_solve.cpp).
//
// Both used to start a std::thread per task. A thread started by the pinned
// stepping thread (solver.affinity "split") inherits its one CPU and waits
// there behind it, up to a scheduler tick (4 ms at HZ=250), before it can
// move itself to the helpers' CPUs; and glibc gives a new thread whichever
// malloc arena is free, so the helper's 10-20 MB Model was often built in an
// arena that had not held one yet: 2,700-4,000 page faults, about 4 of its
// 10-13 ms (10k incision, measured with getrusage per task). This thread
// takes its CPUs and priority once, when it starts, and keeps its arena.
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>

namespace incise {

class HelperThread {
 public:
  enum class Priority { Normal, Idle };  // Idle: SCHED_IDLE (only CPU time nothing else wants)
  // helper_cpus: the Helper role of engine/runtime/thread_affinity.h (solver.affinity "split").
  HelperThread(bool helper_cpus, Priority priority);
  ~HelperThread();  // waits for the task
  HelperThread(const HelperThread&) = delete;
  HelperThread& operator=(const HelperThread&) = delete;

  // Runs task on the thread; waits first for a task still running.
  void run(std::function<void()> task);
  // Until the last task has returned.
  void wait();
  bool helper_cpus() const { return helper_cpus_; }
  Priority priority() const { return priority_; }
  // The scheduling policy the thread runs under (sched_getscheduler; -1 before it started).
  int policy() const;

 private:
  void loop();
  const bool helper_cpus_;
  const Priority priority_;
  mutable std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::function<void()> task_;
  bool pending_ = false, busy_ = false, stop_ = false;
  int policy_ = -1;
  std::thread thread_;
};

}  // namespace incise
