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
#include <condition_variable>
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

// One helper thread that runs a task on request (start, then wait), sleeping
// in between; no allocation per task.
class SubstitutionWorker {
 public:
  SubstitutionWorker();
  ~SubstitutionWorker();
  SubstitutionWorker(const SubstitutionWorker&) = delete;
  SubstitutionWorker& operator=(const SubstitutionWorker&) = delete;
  void start(void (*fn)(void*), void* arg);
  void wait();

 private:
  void loop();
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  void (*fn_)(void*) = nullptr;
  void* arg_ = nullptr;
  bool pending_ = false, busy_ = false, stop_ = false;
  std::thread thread_;
};

}  // namespace incise
