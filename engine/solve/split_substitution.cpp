#include "engine/solve/split_substitution.h"

#include <algorithm>
#include <chrono>
#include <numeric>

#include "engine/runtime/thread_affinity.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace incise {

SubstitutionSplit split_supernodes(const cholmod_factor* L) {
  SubstitutionSplit sp;
  if (!L || !L->is_super || L->nsuper < 2) return sp;
  const int ns = static_cast<int>(L->nsuper);
  const int* super = static_cast<const int*>(L->super);
  const int* pi = static_cast<const int*>(L->pi);
  const int* Ls = static_cast<const int*>(L->s);
  const int n = super[ns];
  std::vector<int> col_sn(n), parent(ns, -1), first(ns), count(ns, 1);
  std::vector<double> work(ns), subtree(ns);
  for (int s = 0; s < ns; ++s)
    for (int k = super[s]; k < super[s + 1]; ++k) col_sn[k] = s;
  for (int s = 0; s < ns; ++s) {
    const int nscol = super[s + 1] - super[s], nsrow = pi[s + 1] - pi[s];
    work[s] = static_cast<double>(nscol) * nsrow;
    if (nsrow > nscol) parent[s] = col_sn[Ls[pi[s] + nscol]];
    if (parent[s] >= 0 && parent[s] <= s) return sp;  // not a topological numbering
  }
  std::iota(first.begin(), first.end(), 0);
  std::vector<std::vector<int>> children(ns);
  std::vector<int> roots;
  subtree = work;
  for (int s = 0; s < ns; ++s) {  // children before parents
    if (parent[s] < 0) {
      roots.push_back(s);
      continue;
    }
    const int p = parent[s];
    children[p].push_back(s);
    subtree[p] += subtree[s];
    count[p] += count[s];
    first[p] = std::min(first[p], first[s]);
  }
  const double total = std::accumulate(work.begin(), work.end(), 0.0);
  std::vector<int> cand = roots;
  double top_work = 0.0;
  for (int guard = 0; guard < ns; ++guard) {
    std::sort(cand.begin(), cand.end(), [&](int a, int b) { return subtree[a] > subtree[b]; });
    double bin[2] = {0, 0};
    std::vector<int> member[2];
    for (int c : cand) {  // largest first into the lighter bin
      const int k = bin[0] <= bin[1] ? 0 : 1;
      bin[k] += subtree[c];
      member[k].push_back(c);
    }
    const double lo = std::min(bin[0], bin[1]), hi = std::max(bin[0], bin[1]);
    if (cand.size() >= 2 && lo >= 0.9 * hi) {
      for (int k = 0; k < 2; ++k) {
        for (int c : member[k]) {
          if (c - first[c] + 1 != count[c]) return SubstitutionSplit{};  // subtree not contiguous: not postordered
          sp.bins[k].push_back({first[c], c});
        }
        std::sort(sp.bins[k].begin(), sp.bins[k].end());
      }
      sp.balance = hi > 0 ? lo / hi : 0.0;
      break;
    }
    // Expand the largest subtree: its root joins the top.
    const int c = cand.front();
    if (children[c].empty() || top_work + work[c] > 0.5 * total) return SubstitutionSplit{};
    top_work += work[c];
    sp.top.push_back(c);
    cand.erase(cand.begin());
    cand.insert(cand.end(), children[c].begin(), children[c].end());
  }
  if (!sp.valid()) return SubstitutionSplit{};
  std::sort(sp.top.begin(), sp.top.end());
  for (int t : sp.top)
    for (int k = super[t]; k < super[t + 1]; ++k) sp.top_cols.push_back(k);
  sp.top_share = total > 0 ? top_work / total : 1.0;
  return sp;
}

SubstitutionWorker::SubstitutionWorker() : SubstitutionWorker(true) {}

SubstitutionWorker::SubstitutionWorker(bool launch_now) {
  if (launch_now) launch();
}

void SubstitutionWorker::launch() {
  if (!thread_.joinable()) thread_ = std::thread([this] { loop(); });
}

SubstitutionWorker::~SubstitutionWorker() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_one();
  if (thread_.joinable()) thread_.join();
}

uint64_t SubstitutionWorker::try_start(void (*fn)(void*), void* arg) {
  uint64_t ticket;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (state_.load(std::memory_order_acquire) != kIdle) return 0;
    fn_ = fn;
    arg_ = arg;
    ticket = ++started_;
    state_.store(kPending, std::memory_order_release);
  }
  wake_.notify_one();
  return ticket;
}

bool SubstitutionWorker::await(const std::atomic<int>& progress, double stall_ms) {
  using clock = std::chrono::steady_clock;
  const auto stall = std::chrono::duration_cast<clock::duration>(std::chrono::duration<double, std::milli>(stall_ms));
  int seen = progress.load(std::memory_order_relaxed);
  auto since = clock::now();
  for (unsigned i = 0;; ++i) {
    if (state_.load(std::memory_order_acquire) == kIdle) return true;
#if defined(__x86_64__) || defined(__i386__)
    _mm_pause();
#endif
    if ((i & 31) != 31) continue;
    const auto now = clock::now();
    const int p = progress.load(std::memory_order_relaxed);
    if (p != seen) {
      seen = p;
      since = now;
    } else if (now - since > stall) {
      break;
    }
  }
  bool withdrawn = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    int expected = kPending;
    withdrawn = state_.compare_exchange_strong(expected, kIdle, std::memory_order_acq_rel);
    if (withdrawn) ended_ = started_;
  }
  if (withdrawn) {
    done_.notify_all();
    return false;
  }
  return state_.load(std::memory_order_acquire) == kIdle;  // it may have ended just now
}

void SubstitutionWorker::wait() {
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [this] { return state_.load(std::memory_order_acquire) == kIdle; });
}

void SubstitutionWorker::wait(uint64_t ticket) {
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [&] { return ended_ >= ticket; });
}

void SubstitutionWorker::loop() {
  unpin_if_split();  // started by a pinned stepping thread: not on its one CPU
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return state_.load(std::memory_order_acquire) == kPending || stop_; });
    int expected = kPending;
    if (!state_.compare_exchange_strong(expected, kRunning, std::memory_order_acq_rel)) {
      if (stop_) return;
      continue;  // withdrawn before it began
    }
    void (*fn)(void*) = fn_;
    void* arg = arg_;
    lock.unlock();
    helper_if_split();  // (the stepping thread may have been pinned since this thread started)
    fn(arg);
    lock.lock();
    ended_ = started_;
    state_.store(kIdle, std::memory_order_release);
    done_.notify_all();
  }
}

}  // namespace incise
