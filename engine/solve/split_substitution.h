#pragma once
// Substitutions on two threads (solver.substitution_threads: 2). A supernodal
// factor's elimination tree is cut into two bins of independent subtrees of
// about equal size (entries of L) and the top supernodes that are their common
// ancestors; the bins' forward and backward steps run at once, the top alone
// (CholmodSolver::solve, solve_copy). A substitution is bound by reading L, and
// two cores read about 1.7x what one does here (two 20k-DOF double
// substitutions at once: 9.1-9.5 ms each against 7.9 ms alone), so the bins
// gain where the second core is free: beside the lagged policy's background
// factorization, which runs at idle priority, it is.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include <cholmod.h>

namespace incise {

struct SubstitutionSplit {
  // bins[k]: inclusive ranges [first, root] of supernode indices, one per
  // subtree (CHOLMOD numbers supernodes in postorder: a subtree is the
  // contiguous range ending at its root), ascending.
  std::vector<std::pair<int, int>> bins[2];
  std::vector<int> top;       // the other supernodes, ascending (ancestors of the bins)
  std::vector<int> top_cols;  // the columns of the top supernodes
  double top_share = 1.0;     // entries of L in the top supernodes / all
  double balance = 0.0;       // smaller bin / larger bin (entries)
  bool valid() const { return !bins[0].empty() && !bins[1].empty(); }
};

// The split of a supernodal factor (symbolic or numeric). Expands the largest
// subtree into its children until the subtrees can be put into two bins
// within 10% of each other (greedy, largest first), or the top would hold
// more than half of L; returns an invalid split (no second bin) then, for a
// simplicial factor, or when the numbering is not a postorder.
SubstitutionSplit split_supernodes(const cholmod_factor* L);

// The worker's part of one substitution (CholmodSolver::split_substitute).
struct SplitJob {
  const cholmod_factor* L = nullptr;
  const void* Lx = nullptr;  // float, double or binary16 entries, by the task's type
  const double* inv_scale = nullptr;
  const SubstitutionSplit* sp = nullptr;
  double *y2 = nullptr, *w2 = nullptr;  // (n) its copy of the permuted vector; its supernode gather
  std::atomic<int> progress{0};         // supernodes done, for SubstitutionWorker::await
};

// The worker's part of a multi-column substitution (CholmodSolver::solve_copy_multi):
// one group of up to 16 columns, whole, on its own row-interleaved Y2 and gather W2.
struct MultiJob {
  const cholmod_factor* L = nullptr;
  const void* Lx = nullptr;  // float, double or binary16 entries, by the task's type
  const double* inv_scale = nullptr;
  int nb = 0;                           // four-column blocks in the group
  double *Y2 = nullptr, *W2 = nullptr;  // (n, 4 nb), (largest supernode rows, 4 nb)
  const std::vector<int>* path = nullptr;  // set: the forward half over these supernodes only (forward_half_multi)
  std::atomic<int> progress{0};         // supernodes done (forward and backward), for SubstitutionWorker::await
};

// One helper thread that runs a task on request, sleeping in between; no
// allocation per task. The thread that starts a task need not wait for it
// whatever happens on the other core: a substitution's caller waits only
// while the task makes progress (await), and otherwise does the task's work
// itself. A task that had not begun is withdrawn (it never runs); one that
// stalled part-way (its thread preempted) is left to finish on its own, and
// busy() stays true until it does, so what it reads and writes must stay
// alive and untouched until then (wait(ticket)). Tasks are numbered from 1
// in the order they start (their tickets), so a caller waits for its own
// task only, not for one another caller started since.
class SubstitutionWorker {
 public:
  SubstitutionWorker();
  // Tests: launch = false starts no thread until launch(), so a task stays
  // pending (as one whose thread is slow to wake).
  explicit SubstitutionWorker(bool launch);
  ~SubstitutionWorker();
  SubstitutionWorker(const SubstitutionWorker&) = delete;
  SubstitutionWorker& operator=(const SubstitutionWorker&) = delete;
  void launch();
  // Starts fn(arg) and returns its ticket; 0 (nothing started) while an
  // earlier task still runs.
  uint64_t try_start(void (*fn)(void*), void* arg);
  // Waits for the task started last while it makes progress: returns true
  // once it ran to the end (its writes are visible to the caller). Returns
  // false when `progress` (the task's own counter, bumped as it works) has not
  // changed for stall_ms: a task that had not begun is withdrawn, one that
  // had is left running (busy()).
  bool await(const std::atomic<int>& progress, double stall_ms);
  bool busy() const { return state_.load(std::memory_order_acquire) != kIdle; }
  // Blocks until no task is pending or running.
  void wait();
  // Blocks until the task with this ticket ended or was withdrawn (at once
  // for 0 or an ended one), whatever task runs after it.
  void wait(uint64_t ticket);

 private:
  enum { kIdle, kPending, kRunning };
  void loop();
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  void (*fn_)(void*) = nullptr;
  void* arg_ = nullptr;
  std::atomic<int> state_{kIdle};
  uint64_t started_ = 0, ended_ = 0;  // tickets: of the task started last, of the last that ended or was withdrawn (under mutex_)
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace incise
