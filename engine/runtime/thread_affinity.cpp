#include "engine/runtime/thread_affinity.h"

#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <mutex>

namespace incise {

namespace {

// The process's CPU set as first seen (before any thread of ours was pinned).
const cpu_set_t& process_cpus() {
  static cpu_set_t set;
  static std::once_flag once;
  std::call_once(once, [] {
    CPU_ZERO(&set);
    if (sched_getaffinity(0, sizeof set, &set) != 0) CPU_ZERO(&set);
  });
  return set;
}

std::atomic<int> g_stepping_cpu{-1};
thread_local int t_role = -1;  // the role the calling thread was given

}  // namespace

bool set_thread_role(ThreadRole role) {
  if (t_role == static_cast<int>(role)) return true;
  const cpu_set_t& all = process_cpus();
  if (CPU_COUNT(&all) < 2) return false;
  int last = -1;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &all)) last = c;
  cpu_set_t mine = all;
  if (role == ThreadRole::Stepping) {
    CPU_ZERO(&mine);
    CPU_SET(last, &mine);
  } else if (role == ThreadRole::Helper) {
    CPU_CLR(last, &mine);
  }
  if (pthread_setaffinity_np(pthread_self(), sizeof mine, &mine) != 0) return false;
  t_role = static_cast<int>(role);
  if (role == ThreadRole::Stepping) g_stepping_cpu = last;
  return true;
}

void unpin_if_split() {
  if (g_stepping_cpu.load() >= 0 && t_role < 0) set_thread_role(ThreadRole::Any);
}

void helper_if_split() {
  if (g_stepping_cpu.load() >= 0 && t_role != static_cast<int>(ThreadRole::Helper)) set_thread_role(ThreadRole::Helper);
}

int stepping_cpu() { return g_stepping_cpu.load(); }

}  // namespace incise
