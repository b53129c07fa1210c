// Substitutions on two threads (engine/split_substitution.h): the split of a
// tet10 beam factor covers every supernode once with independent bins, and
// the two-thread solve equals the one-thread solve (double, float and binary16
// factors) to roundoff, in place too, over many repeated calls.
#include <atomic>
#include <vector>

#include <gtest/gtest.h>

#include "engine/cholmod_solver.h"
#include "engine/mesh_tools.h"
#include "engine/split_substitution.h"
#include "test_util.h"

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

// The two-thread result against the one-thread one for each stored precision.
TEST(SplitSubstitution, TwoThreadSolveEqualsOneThreadSolve) {
  const Model m = beam(14, 4);
  const int n = m.ndof();
  const std::vector<double> A = system_matrix(m);
  SubstitutionWorker worker;
  for (FactorCopy copy : {FactorCopy::None, FactorCopy::Float, FactorCopy::Half}) {
    SCOPED_TRACE(static_cast<int>(copy));
    CholmodSolver one, two;
    for (CholmodSolver* f : {&one, &two}) {
      f->set_factor_copy(copy);
      f->analyze(n, m.Ap, m.Ai);
      f->factorize(A.data());
    }
    two.set_substitution_worker(&worker);
    ASSERT_TRUE(two.substitutes_on_two_threads());
    EXPECT_FALSE(one.substitutes_on_two_threads());
    for (unsigned seed = 1; seed <= 3; ++seed) {
      const std::vector<double> b = random_vector(n, seed);
      std::vector<double> x1(n), x2(n), xa = b;
      one.solve_copy(b.data(), x1.data());
      two.solve_copy(b.data(), x2.data());
      two.solve_copy(xa.data(), xa.data());  // in place
      // Only the top rows' sums are reordered: roundoff of the stored precision's solve.
      EXPECT_LT(test::rel_diff(x2, x1), 1e-13);
      EXPECT_EQ(xa, x2);
    }
    std::vector<double> xd1(n), xd2(n);  // the double substitution too
    const std::vector<double> b = random_vector(n, 9);
    one.solve(b.data(), xd1.data());
    two.solve(b.data(), xd2.data());
    EXPECT_LT(test::rel_diff(xd2, xd1), 1e-13);
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
  f.solve(b.data(), first.data());
  for (int k = 0; k < 200; ++k) {
    f.solve(b.data(), x.data());
    ASSERT_EQ(x, first) << "solve " << k;
  }
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
  std::atomic<int> count{0};
  for (int k = 0; k < 1000; ++k) {
    worker.start([](void* p) { ++*static_cast<std::atomic<int>*>(p); }, &count);
    worker.wait();
    ASSERT_EQ(count.load(), k + 1);
  }
}

}  // namespace
}  // namespace incise
