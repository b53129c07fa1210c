// Substitutions on two threads (engine/solve/split_substitution.h): the split of a
// tet10 beam factor covers every supernode once with independent bins, and
// the two-thread solve equals the one-thread solve (double, float and binary16
// factors) to roundoff, in place too, over many repeated calls.
#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "engine/solve/cholmod_solver.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/solve/split_substitution.h"
#include "tests/engine/solve/factor_bounds.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

using test::random_vector;

Model beam(int nx, int nyz) { return test::tissue_beam(nx, nyz); }
std::vector<double> system_matrix(const Model& m) { return test::system_matrix(m, 3600.0); }

// (The bins' independence shows in TwoThreadSolveEqualsOneThreadSolve: a
// supernode whose ancestor sat in the other bin would read a stale row.)
TEST(SplitSubstitution, SplitCoversEverySupernodeOnceAndIsBalanced) {
  const Model m = beam(14, 4);
  CholmodSolver f;
  f.analyze(m.ndof(), m.Ap, m.Ai);
  const SubstitutionSplit& sp = f.substitution_split();
  ASSERT_TRUE(sp.valid());
  EXPECT_GE(sp.balance, 0.9);  // the stopping rule
  EXPECT_LT(sp.top_share, 0.5);
  std::vector<int> owner;  // supernode -> 0, 1 (bins) or 2 (top)
  int nsuper = 0;
  for (int k = 0; k < 2; ++k)
    for (const auto& r : sp.bins[k]) nsuper = std::max(nsuper, r.second + 1);
  for (int t : sp.top) nsuper = std::max(nsuper, t + 1);
  owner.assign(nsuper, -1);
  for (int k = 0; k < 2; ++k)
    for (const auto& r : sp.bins[k]) {
      ASSERT_LE(r.first, r.second);
      for (int s = r.first; s <= r.second; ++s) {
        EXPECT_EQ(owner[s], -1) << "supernode " << s << " twice";
        owner[s] = k;
      }
    }
  for (int t : sp.top) {
    EXPECT_EQ(owner[t], -1) << "supernode " << t << " twice";
    owner[t] = 2;
  }
  for (int s = 0; s < nsuper; ++s) EXPECT_NE(owner[s], -1) << "supernode " << s << " in no part";
  // The top's columns are those the split lists.
  EXPECT_FALSE(sp.top_cols.empty());
  EXPECT_LT(static_cast<int>(sp.top_cols.size()), m.ndof() / 2);
  for (size_t i = 1; i < sp.top_cols.size(); ++i) EXPECT_LT(sp.top_cols[i - 1], sp.top_cols[i]);
}

// The difference a split substitution may have from the one-thread one:
// only the top rows' sums are reordered (y_top + bin 0's updates + bin 1's,
// in double whatever the stored precision). Either order is a backward
// stable substitution, (L + dL) y = b with |dL| <= gamma_n(2^-53) |L|
// (Higham, "Accuracy and Stability of Numerical Algorithms", Thm 8.5), so
// the two results differ by at most twice the forward error bound
// gamma_n u cond(A) (Sec. 7.1), with cond_2(A) <= ||A||_inf ||A^-1||_2
// computed from the matrix (factor_bounds.h). On the 7k dynamic beam:
// cond_2 ~4e4 (||A||_inf ||A^-1||_2 ~ 8.8e4), bound 1.4e-7; measured
// differences 4e-17 .. 8e-17 (the worst-case gamma_n is n times the typical
// rounding and the error rarely lies along the smallest eigenvector), so
// the bound is loose by ~1e9 but still far below a real bug: a supernode
// read with a stale row of the other bin (the bins' independence broken)
// is off by O(1).
double reorder_bound(const Model& m, const std::vector<double>& A) {
  const int n = m.ndof();
  CholmodSolver f;  // one thread, double
  f.analyze(n, m.Ap, m.Ai);
  f.factorize(A.data());
  const double kappa = test::norm_inf(m, A) * test::inverse_norm(n, [&](const double* r, double* z) { f.solve(r, z); });
  return 2.0 * test::gamma_bound(n, test::kUnitDouble) * kappa;
}

// The two-thread result against the one-thread one for each stored precision,
// with the worker running (bins on two threads; a bin can still be taken over
// when the machine is loaded) and with a worker that never starts (every bin
// taken over: forward and backward, each solve). Each path is deterministic:
// in place equals out of place bit for bit and repeated solves agree bit for
// bit; the two paths differ from the one-thread solve by reordered roundoff.
TEST(SplitSubstitution, TwoThreadSolveEqualsOneThreadSolve) {
  const Model m = beam(14, 4);
  const int n = m.ndof();
  const std::vector<double> A = system_matrix(m);
  const double bound = reorder_bound(m, A);
  SubstitutionWorker running, stalled(/*launch=*/false);
  for (FactorCopy copy : {FactorCopy::None, FactorCopy::Float, FactorCopy::Half}) {
    SCOPED_TRACE(static_cast<int>(copy));
    CholmodSolver one, two, over;
    for (CholmodSolver* f : {&one, &two, &over}) {
      f->set_factor_copy(copy);
      f->analyze(n, m.Ap, m.Ai);
      f->factorize(A.data());
    }
    two.set_substitution_worker(&running);
    over.set_substitution_worker(&stalled);
    ASSERT_TRUE(two.substitutes_on_two_threads());
    ASSERT_TRUE(over.substitutes_on_two_threads());
    EXPECT_FALSE(one.substitutes_on_two_threads());
    for (unsigned seed = 1; seed <= 3; ++seed) {
      const std::vector<double> b = random_vector(n, seed);
      std::vector<double> x1(n), x2(n), xa = b, xo(n), xoa = b;
      one.solve_copy(b.data(), x1.data());
      // Worker running: the same bits in place, whether or not a bin was
      // taken over in either solve (a replay depends on it); roundoff from
      // the one-thread solve (the top rows add the bins' updates in another order).
      two.solve_copy(b.data(), x2.data());
      two.solve_copy(xa.data(), xa.data());  // in place
      EXPECT_LE(test::rel_diff(x2, x1), bound);
      EXPECT_EQ(xa, x2);
      // Every bin taken over: two takeovers per solve, and the same bits as
      // the worker's.
      const int o0 = over.stats().takeovers;
      over.solve_copy(b.data(), xo.data());
      EXPECT_EQ(over.stats().takeovers, o0 + 2);
      over.solve_copy(xoa.data(), xoa.data());
      EXPECT_EQ(over.stats().takeovers, o0 + 4);
      EXPECT_EQ(xoa, xo);
      EXPECT_EQ(xo, x2);
    }
    std::vector<double> xd1(n), xd2(n), xdo(n);  // the double substitution too
    const std::vector<double> b = random_vector(n, 9);
    one.solve(b.data(), xd1.data());
    two.solve(b.data(), xd2.data());
    over.solve(b.data(), xdo.data());
    EXPECT_LE(test::rel_diff(xd2, xd1), bound);
    EXPECT_EQ(xdo, xd2);
  }
}

// Repeated solves through one worker give the same bits each time (no race
// between the two threads' writes), and a simplicial factor stays serial.
TEST(SplitSubstitution, RepeatedSolvesAreIdenticalAndSimplicialStaysSerial) {
  const Model m = beam(10, 3);
  const int n = m.ndof();
  const std::vector<double> A = system_matrix(m);
  SubstitutionWorker worker;
  CholmodSolver f;
  f.set_substitution_worker(&worker);
  f.analyze(n, m.Ap, m.Ai);
  f.factorize(A.data());
  ASSERT_TRUE(f.substitutes_on_two_threads());
  const std::vector<double> b = random_vector(n, 4);
  std::vector<double> first(n), x(n);
  const double bound = reorder_bound(m, A);
  f.solve(b.data(), first.data());
  for (int k = 0; k < 200; ++k) {
    f.solve(b.data(), x.data());
    // Also when a bin was taken over (the worker stalled: a loaded machine).
    ASSERT_EQ(x, first) << "solve " << k << ", " << f.stats().takeovers << " takeovers so far";
  }
  EXPECT_LE(test::rel_diff(first, x), bound);
  CholmodSolver simplicial;
  simplicial.configure(FactorMethod::Simplicial, OrderingMethod::Auto);
  simplicial.set_substitution_worker(&worker);
  simplicial.analyze(n, m.Ap, m.Ai);
  simplicial.factorize(A.data());
  EXPECT_FALSE(simplicial.substitutes_on_two_threads());
  simplicial.solve(b.data(), x.data());
  EXPECT_LT(test::rel_diff(x, first), 1e-10);
}

TEST(SplitSubstitution, WorkerRunsEachTaskOnce) {
  SubstitutionWorker worker;
  std::atomic<int> count{0}, progress{0};
  for (int k = 0; k < 1000; ++k) {
    const int before = count.load();
    ASSERT_TRUE(worker.try_start([](void* p) { ++*static_cast<std::atomic<int>*>(p); }, &count));
    if (k % 2) {
      worker.wait();
    } else {
      // No progress counter moves: await gives up after 50 ms at the latest,
      // so the task either ran (true) or was withdrawn (false, never runs).
      const bool ran = worker.await(progress, 50.0);
      worker.wait();
      ASSERT_EQ(count.load(), before + (ran ? 1 : 0));
      if (!ran) count.fetch_add(1);  // keep the tally: task k counted once either way
    }
    ASSERT_EQ(count.load(), k + 1);
  }
}

// A worker whose thread has not started yet (as one the kernel is slow to
// wake): await withdraws the task after the stall time and it never runs; a
// second task cannot start while one runs.
TEST(SplitSubstitution, AwaitWithdrawsATaskThatNeverBegan) {
  SubstitutionWorker worker(/*launch=*/false);
  std::atomic<int> count{0}, progress{0};
  auto bump = [](void* p) { ++*static_cast<std::atomic<int>*>(p); };
  ASSERT_TRUE(worker.try_start(bump, &count));
  EXPECT_TRUE(worker.busy());
  EXPECT_FALSE(worker.try_start(bump, &count));
  EXPECT_FALSE(worker.await(progress, 1.0));
  EXPECT_FALSE(worker.busy());
  worker.launch();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(count.load(), 0);  // withdrawn: never ran
  ASSERT_TRUE(worker.try_start(bump, &count));
  worker.wait();
  EXPECT_EQ(count.load(), 1);
}

// A task that stops making progress part-way is left running: await returns
// false, busy() stays true until it ends, wait() and wait(its ticket) block
// until then. Waiting for an ended task's ticket returns at once even while
// a later task holds the worker (a solver that gave up on its task must not
// wait for another caller's: that deadlocked a test whose caller released
// the later task only after its solve).
TEST(SplitSubstitution, AwaitLeavesAStalledTaskRunning) {
  SubstitutionWorker worker;
  struct Ctx {
    std::atomic<int> progress{0};
    std::atomic<bool> release{false}, ended{false};
  };
  auto hold = [](void* p) {
    auto& c = *static_cast<Ctx*>(p);
    c.progress = 1;
    while (!c.release) std::this_thread::sleep_for(std::chrono::microseconds(100));
    c.ended = true;
  };
  Ctx c, later;
  const uint64_t ticket = worker.try_start(hold, &c);
  ASSERT_GT(ticket, 0u);
  EXPECT_EQ(worker.try_start(hold, &later), 0u) << "busy: nothing started";
  while (c.progress.load() == 0) std::this_thread::yield();
  EXPECT_FALSE(worker.await(c.progress, 2.0));
  EXPECT_TRUE(worker.busy());
  EXPECT_FALSE(c.ended.load());
  std::thread releaser([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    c.release = true;
  });
  worker.wait(ticket);
  EXPECT_TRUE(c.ended.load()) << "wait(ticket) returned before its task ended";
  releaser.join();
  worker.wait();
  EXPECT_FALSE(worker.busy());
  const uint64_t next = worker.try_start(hold, &later);
  EXPECT_EQ(next, ticket + 1);
  while (later.progress.load() == 0) std::this_thread::yield();
  worker.wait(ticket);  // the ended one: at once, though `later` holds the worker
  worker.wait(0);
  EXPECT_TRUE(worker.busy());
  EXPECT_FALSE(later.ended.load());
  later.release = true;
  worker.wait(next);
  EXPECT_TRUE(later.ended.load());
}

// A solve whose worker never starts does the worker's bins itself, each bin
// counted as a takeover, with the same bits as the worker gives once it runs
// (the one-thread substitution's result to roundoff: the bins' updates of
// the top rows come in another order).
TEST(SplitSubstitution, SolveTakesOverTheBinsOfAWorkerThatNeverStarts) {
  const Model m = beam(12, 4);
  const int n = m.ndof();
  const std::vector<double> A = system_matrix(m);
  SubstitutionWorker worker(/*launch=*/false);
  CholmodSolver one, two;
  for (CholmodSolver* f : {&one, &two}) {
    f->set_factor_copy(FactorCopy::Float);
    f->analyze(n, m.Ap, m.Ai);
    f->factorize(A.data());
  }
  two.set_substitution_worker(&worker);
  ASSERT_TRUE(two.substitutes_on_two_threads());
  const std::vector<double> b = random_vector(n, 5);
  std::vector<double> x1(n), x2(n);
  one.solve_copy(b.data(), x1.data());
  two.solve_copy(b.data(), x2.data());
  EXPECT_LE(test::rel_diff(x2, x1), reorder_bound(m, A));
  EXPECT_EQ(two.stats().split_substitutions, 1);
  EXPECT_EQ(two.stats().takeovers, 2);  // forward and backward
  worker.launch();
  std::vector<double> xw(n);
  two.solve_copy(b.data(), xw.data());
  EXPECT_EQ(xw, x2);
  EXPECT_EQ(two.stats().split_substitutions, 2);
}

// Holds the worker with a task that runs until `release` is set, once any
// task a solve gave up on (a loaded machine) has ended; its ticket.
uint64_t hold_worker(SubstitutionWorker& worker, std::atomic<bool>& release) {
  worker.wait();
  return worker.try_start(
      [](void* p) {
        while (!static_cast<std::atomic<bool>*>(p)->load()) std::this_thread::sleep_for(std::chrono::microseconds(100));
      },
      &release);
}

// A multi-column substitution gives its second group to the worker (51
// columns: 16, 16, 16, 3; 2-48: two halves of up to 24): the same bits as on
// one thread, whether the worker runs it, never starts (the caller takes it
// over, counted) or is busy with another task; in place too.
TEST(SplitSubstitution, MultiColumnSolveGivesAGroupToTheWorkerWithTheSameBits) {
  const Model m = beam(12, 4);
  const int n = m.ndof(), k = 51;
  const std::vector<double> A = system_matrix(m);
  SubstitutionWorker running, stalled(/*launch=*/false);
  CholmodSolver one, two, late;
  for (CholmodSolver* f : {&one, &two, &late}) {
    f->set_factor_copy(FactorCopy::Float);
    f->analyze(n, m.Ap, m.Ai);
    f->factorize(A.data());
  }
  two.set_substitution_worker(&running);
  late.set_substitution_worker(&stalled);
  ASSERT_TRUE(two.substitutes_on_two_threads());
  const std::vector<double> B = random_vector(n * k, 9);
  std::vector<double> X1(B.size()), X2(B.size()), X3(B.size()), inplace = B;
  one.solve_copy_multi(k, B.data(), X1.data());
  for (int rep = 0; rep < 20; ++rep) {  // the worker's wake-up races the caller's groups
    two.solve_copy_multi(k, B.data(), X2.data());
    ASSERT_EQ(X2, X1) << "repeat " << rep;
  }
  for (int kk : {2, 9, 16, 27, 35, 48}) {  // two groups of half each: the same bits as groups of 16 on one thread
    std::vector<double> Y1(static_cast<size_t>(n) * kk), Y2(Y1.size());
    one.solve_copy_multi(kk, B.data(), Y1.data());
    two.solve_copy_multi(kk, B.data(), Y2.data());
    ASSERT_EQ(Y2, Y1) << kk << " columns";
  }
  for (int kk : {1, 9, 27, 41}) {  // the forward half's groups the same way (forward_half_multi)
    std::vector<int> nz, r1, r2;
    for (int d = 0; d < 12; ++d) nz.push_back(d);
    std::vector<double> Bs(static_cast<size_t>(n) * kk, 0.0), Z1, Z2;
    for (int c = 0; c < kk; ++c)
      for (int d : nz) Bs[static_cast<size_t>(c) * n + d] = B[static_cast<size_t>(c) * n + d];
    ASSERT_TRUE(one.forward_half_multi(kk, Bs.data(), nz, r1, Z1));
    ASSERT_TRUE(two.forward_half_multi(kk, Bs.data(), nz, r2, Z2));
    EXPECT_EQ(r2, r1);
    ASSERT_EQ(Z2, Z1) << kk << " columns, forward half";
    std::vector<double> x1(n), x2(n);  // and the backward half: the top, then the bins (the same supernodes' arithmetic)
    one.backward_half(r1, Z1.data(), x1.data());
    for (int rep = 0; rep < 5; ++rep) {
      two.backward_half(r1, Z1.data(), x2.data());
      ASSERT_EQ(x2, x1) << kk << " columns, backward half, repeat " << rep;
    }
  }
  two.solve_copy_multi(k, inplace.data(), inplace.data());
  EXPECT_EQ(inplace, X1) << "in place";
  late.solve_copy_multi(k, B.data(), X3.data());
  EXPECT_EQ(X3, X1);
  EXPECT_EQ(late.stats().takeovers, 1) << "the group the worker never started";
  stalled.launch();
  std::atomic<bool> release{false};
  ASSERT_TRUE(hold_worker(running, release));
  const int takeovers = two.stats().takeovers;
  two.solve_copy_multi(k, B.data(), X2.data());
  EXPECT_EQ(X2, X1) << "busy worker: every group here";
  EXPECT_EQ(two.stats().takeovers, takeovers);
  release = true;
  running.wait();
}

// While a bin given up on still runs on the worker (here: the worker is
// held by another task), solves do both bins on this thread, with the same
// bits as with the worker free, and factorizing again waits for it.
TEST(SplitSubstitution, BusyWorkerKeepsSolvesOnOneThread) {
  const Model m = beam(10, 3);
  const int n = m.ndof();
  const std::vector<double> A = system_matrix(m);
  SubstitutionWorker worker;
  CholmodSolver one, two;
  for (CholmodSolver* f : {&one, &two}) {
    f->analyze(n, m.Ap, m.Ai);
    f->factorize(A.data());
  }
  two.set_substitution_worker(&worker);
  const std::vector<double> b = random_vector(n, 6);
  std::vector<double> x1(n), x2(n), xfree(n);
  two.solve(b.data(), xfree.data());
  std::atomic<bool> release{false};
  ASSERT_TRUE(hold_worker(worker, release));
  one.solve(b.data(), x1.data());
  const int takeovers = two.stats().takeovers;
  two.solve(b.data(), x2.data());
  EXPECT_EQ(x2, xfree);
  EXPECT_EQ(two.stats().takeovers, takeovers) << "nothing started, nothing taken over";
  EXPECT_LE(test::rel_diff(x2, x1), reorder_bound(m, A));
  release = true;
  worker.wait();
  two.factorize(A.data());
  two.solve(b.data(), x2.data());
  EXPECT_EQ(x2, xfree);
}

}  // namespace
}  // namespace incise
