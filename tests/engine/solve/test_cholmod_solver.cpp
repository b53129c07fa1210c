// CHOLMOD wrapper: solves against a dense reference, reuses the symbolic
// analysis across values, refuses indefinite matrices with a clear message.
#include <dlfcn.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <thread>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "engine/fem/assemble.h"
#include "engine/solve/cholmod_solver.h"
#include "engine/util/error.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/model/model.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

// Upper triangle of a dense matrix in compressed columns (all entries kept).
void upper_csc(const Eigen::MatrixXd& A, std::vector<int>& p, std::vector<int>& i, std::vector<double>& x) {
  p.assign(1, 0);
  i.clear();
  x.clear();
  for (int c = 0; c < A.cols(); ++c) {
    for (int r = 0; r <= c; ++r)
      if (A(r, c) != 0.0 || r == c) {
        i.push_back(r);
        x.push_back(A(r, c));
      }
    p.push_back(static_cast<int>(i.size()));
  }
}

TEST(Cholmod, SolvesLikeADenseCholeskyAndReusesTheAnalysis) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(-1, 1);
  const int n = 40;
  Eigen::MatrixXd B(n, n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) B(r, c) = std::abs(r - c) < 4 ? U(rng) : 0.0;  // banded
  Eigen::MatrixXd A = B * B.transpose() + n * Eigen::MatrixXd::Identity(n, n);
  std::vector<int> p, i;
  std::vector<double> x;
  upper_csc(A, p, i, x);
  CholmodSolver s;
  s.analyze(n, p, i);
  for (int round = 0; round < 2; ++round) {  // second round: new values, same pattern
    s.factorize(x.data());
    Eigen::VectorXd b = Eigen::VectorXd::Random(n), sol(n);
    s.solve(b.data(), sol.data());
    const Eigen::VectorXd ref = A.llt().solve(b);
    EXPECT_LT((sol - ref).norm(), 1e-12 * ref.norm());
    for (double& v : x) v *= 2.0;
    A *= 2.0;
  }
  EXPECT_GT(s.stats().nnz_L, 0.0);
  EXPECT_GT(s.stats().flops, 0.0);
}

// A tet10 beam's dynamic system matrix, SPD except at one DOF (its diagonal
// negated): every leading principal submatrix of P A P^T that excludes that
// DOF is a principal submatrix of the SPD matrix, so the first pivot that
// fails is exactly the one of that DOF, wherever the ordering puts it. The
// error must name the DOF (the column of A), not the position in the
// fill-reducing order (L->minor), so the DOF is chosen where the ordering
// moved it to another node.
// A 0 x 0 matrix (the lagged policy's patch when the mapped factor knows
// every node after a cut) has no values: factorize(nullptr) must not read
// any (it copied CHOLMOD's nzmax, at least 1, from null: a crash seen on the
// liver demo), for both factorization methods.
TEST(Cholmod, AnEmptyMatrixFactorizesWithoutValues) {
  for (FactorMethod method : {FactorMethod::Supernodal, FactorMethod::Simplicial}) {
    CholmodSolver s;
    s.configure(method, OrderingMethod::Amd);
    s.analyze(0, std::vector<int>{0}, std::vector<int>{});
    const std::vector<double> none;
    EXPECT_NO_THROW(s.factorize(none.data()));
  }
}

TEST(Cholmod, IndefiniteMatrixIsAnErrorNamingTheDof) {
  const Model m = test::tissue_beam(6, 2);
  const int n = m.ndof();
  const std::vector<double> good = test::system_matrix(m, 3600.0);
  struct Setting {
    const char* name;
    FactorMethod method;
    OrderingMethod ordering;
    bool reversed;  // a given ordering: the reverse of the DOF numbering
  };
  const Setting settings[] = {{"supernodal AMD", FactorMethod::Supernodal, OrderingMethod::Amd, false},
                              {"supernodal METIS", FactorMethod::Supernodal, OrderingMethod::Metis, false},
                              {"supernodal reversed", FactorMethod::Supernodal, OrderingMethod::Auto, true},
                              {"simplicial AMD", FactorMethod::Simplicial, OrderingMethod::Amd, false},
                              {"simplicial reversed", FactorMethod::Simplicial, OrderingMethod::Auto, true}};
  for (const Setting& st : settings) {
    SCOPED_TRACE(st.name);
    std::vector<int> reversed(n);
    for (int k = 0; k < n; ++k) reversed[k] = n - 1 - k;
    CholmodSolver s;
    s.configure(st.method, st.ordering);
    s.analyze(n, m.Ap, m.Ai, st.reversed ? &reversed : nullptr);
    ASSERT_EQ(s.stats().supernodal, st.method == FactorMethod::Supernodal);
    const std::vector<int> perm = s.permutation();
    ASSERT_EQ(static_cast<int>(perm.size()), n);
    // The free DOF, past the middle of the numbering, that the ordering
    // eliminates at a position belonging to another node.
    std::vector<int> position(n);
    for (int k = 0; k < n; ++k) position[perm[k]] = k;
    int bad = -1;
    for (int d = n / 2; d < n && bad < 0; ++d)
      if (!m.constrained[d] && position[d] / 3 != d / 3) bad = d;
    ASSERT_GE(bad, 0) << "the ordering moves no DOF to another node";
    std::vector<double> A = good;
    A[m.diag[bad]] = -A[m.diag[bad]];
    // The solver knows the DOF only; the node is named where the Model is
    // at hand (engine/runtime/failure_context.h), from NumericalError::dof.
    const std::string expected = "at DOF " + std::to_string(bad) + " (pivot " + std::to_string(position[bad]) + " of " +
                                 std::to_string(n) + " in the fill-reducing order)";
    try {
      s.factorize(A.data());
      ADD_FAILURE() << "an indefinite matrix was factored";
    } catch (const NumericalError& e) {
      EXPECT_EQ(e.dof, bad);
      const std::string what = e.what();
      EXPECT_NE(what.find("not positive definite"), std::string::npos) << what;
      EXPECT_NE(what.find(expected), std::string::npos) << what << "\nexpected: " << expected;
    }
    EXPECT_FALSE(s.factorized());
    std::vector<double> x(n);
    EXPECT_THROW(s.solve(good.data(), x.data()), Error);
    s.factorize(good.data());  // the same analysis factors the SPD matrix
    EXPECT_TRUE(s.factorized());
  }
}

int threads_of_this_process() {
  int n = 0;
  for ([[maybe_unused]] const auto& t : std::filesystem::directory_iterator("/proc/self/task")) ++n;
  return n;
}

// Debian's CHOLMOD runs parts of the supernodal factorization in OpenMP teams
// of a size fixed at its compile time (4), ignoring OMP_NUM_THREADS; on a
// 2-core machine those threads took the stepping thread's core and made the
// factorization itself 2.5x slower. CholmodSolver makes OpenMP regions run on
// the thread that enters them: a factorization starts no thread.
TEST(Cholmod, SupernodalFactorizationStartsNoThreads) {
  const Model m = build_model(make_beam(1.0, 0.25, 0.25, 12, 3, 3, 1), test::basic_scene(2));
  std::vector<double> A = m.K0_csc;
  for (int d = 0; d < m.ndof(); ++d) A[m.diag[d]] += 1e3 * m.mass_lumped[d] + 1.0;  // SPD without supports
  const int before = threads_of_this_process();
  CholmodSolver f;
  f.configure(FactorMethod::Supernodal, OrderingMethod::Metis);
  f.analyze(m.ndof(), m.Ap, m.Ai);
  for (int k = 0; k < 2; ++k) f.factorize(A.data());
  EXPECT_GT(m.ndof(), 2000);
  EXPECT_TRUE(f.stats().supernodal);
  EXPECT_EQ(threads_of_this_process(), before) << "CHOLMOD started threads (OpenMP teams)";
  // The same on another thread (the setting is per thread): the lagged
  // policy's background job. Only that thread itself may be added.
  int during = 0;
  std::thread job([&] {
    f.factorize(A.data());
    during = threads_of_this_process();
  });
  job.join();
  EXPECT_EQ(during, before + 1) << "the background factorization started threads (OpenMP teams)";
  // The setting holds for CHOLMOD's calls only: the caller's own OpenMP
  // setting is as it was.
  if (auto get = reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "omp_get_max_active_levels"))) {
    const int levels = get();
    f.factorize(A.data());
    EXPECT_EQ(get(), levels);
    EXPECT_GT(levels, 0);
  }
}

// Two supernodal (BLAS) factorizations on two threads at once, as the lagged
// policy's patch on the stepping thread runs beside the background job. With
// Debian's serial OpenBLAS 0.3.21 78-94 of these 460 rounds gave a wrong
// factor; with the pthread build (what tools/scripts/install-deps.sh
// installs) none. blas_concurrency_safe() tells the engine which it has; where
// it says safe, every round must be exact.
TEST(Cholmod, ConcurrentSupernodalFactorizationsAreExactWhereBlasIsSafe) {
  if (!blas_concurrency_safe())
    GTEST_SKIP() << "this BLAS is not safe for concurrent calls: the engine keeps BLAS on one thread at a time";
  const Model big = test::tissue_beam(12, 3), small = test::tissue_beam(8, 2);
  std::atomic<int> wrong{0}, rounds{0};
  auto work = [&](const Model& m, int count) {
    const std::vector<double> A = test::system_matrix(m, 3600.0);
    const int n = m.ndof();
    const std::vector<double> b = test::random_vector(n, 3);
    CholmodSolver f;
    f.configure(FactorMethod::Supernodal, OrderingMethod::Amd);
    f.analyze(n, m.Ap, m.Ai);
    std::vector<double> x(n), r(n);
    for (int k = 0; k < count; ++k, ++rounds) {
      try {
        f.factorize(A.data());
      } catch (const Error&) {  // "not positive definite": a corrupted factorization
        ++wrong;
        continue;
      }
      f.solve(b.data(), x.data());
      sym_matvec(m, A.data(), x.data(), r.data());
      double rn = 0, bn = 0;
      for (int d = 0; d < n; ++d) rn += (r[d] - b[d]) * (r[d] - b[d]), bn += b[d] * b[d];
      if (!(std::sqrt(rn / bn) < 1e-9)) ++wrong;
    }
  };
  std::thread a([&] { work(big, 40); }), c([&] { work(small, 250); });
  a.join();
  c.join();
  EXPECT_EQ(rounds.load(), 290);
  EXPECT_EQ(wrong.load(), 0) << "of " << rounds.load() << " concurrent factorizations";
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

// solve_copy_multi (the contact compliance's k columns in one substitution)
// gives each column what solve_copy gives it, for the double factor, the
// float and half copies, the single-precision factorization and a
// simplicial factor; B and X may alias.
TEST(Cholmod, MultiColumnSolveMatchesOneColumnAtATime) {
  const Model m = test::tissue_beam(8, 2);
  const std::vector<double> A = test::system_matrix(m, 3600.0);
  const int n = m.ndof(), k = 5;
  std::vector<double> B = test::random_vector(n * k, 11);
  struct Case {
    const char* name;
    FactorMethod method;
    FactorCopy copy;
    bool single;
  };
  for (const Case c : {Case{"double", FactorMethod::Supernodal, FactorCopy::None, false},
                       Case{"float copy", FactorMethod::Supernodal, FactorCopy::Float, false},
                       Case{"half copy", FactorMethod::Supernodal, FactorCopy::Half, false},
                       Case{"single factorization", FactorMethod::Supernodal, FactorCopy::Float, true},
                       Case{"single factorization, half copy", FactorMethod::Supernodal, FactorCopy::Half, true},
                       Case{"simplicial", FactorMethod::Simplicial, FactorCopy::None, false}}) {
    CholmodSolver f;
    f.configure(c.method, OrderingMethod::Amd);
    f.set_factor_copy(c.copy);
    f.set_single_factorization(c.single);
    f.analyze(n, m.Ap, m.Ai);
    f.factorize(A.data());
    std::vector<double> X(B.size()), one(n);
    f.solve_copy_multi(k, B.data(), X.data());
    std::vector<double> Y = B;
    f.solve_copy_multi(k, Y.data(), Y.data());  // in place
    for (int col = 0; col < k; ++col) {
      f.solve_copy(B.data() + static_cast<size_t>(col) * n, one.data());
      double diff = 0.0, norm = 0.0;
      for (int i = 0; i < n; ++i) {
        diff = std::max(diff, std::abs(X[static_cast<size_t>(col) * n + i] - one[i]));
        norm = std::max(norm, std::abs(one[i]));
        ASSERT_EQ(X[static_cast<size_t>(col) * n + i], Y[static_cast<size_t>(col) * n + i]) << c.name;
      }
      // the same arithmetic per column, summed in another order
      EXPECT_LT(diff, 1e-12 * norm) << c.name << " column " << col;
    }
  }
}

// forward_half_multi (the contact compliance without Y): for columns that
// are zero outside a few nodes' DOFs (a contact row's support),
// Z_i . Z_j = B_i^T X_j with X = solve_copy_multi(B), for the double factor,
// the float and half copies and the single-precision factorization, from a
// part of the factor's rows (the paths from those DOFs up the tree); 20
// columns are two groups; and backward_half(Z c) = X c. A simplicial factor
// has no supernodal tree: false.
TEST(Cholmod, ForwardHalfGivesTheComplianceOfSparseColumns) {
  const Model m = test::tissue_beam(8, 2);
  const std::vector<double> A = test::system_matrix(m, 3600.0);
  const int n = m.ndof(), k = 20;
  std::vector<int> nz;
  for (int node : {0, 1, 5})
    for (int i = 0; i < 3; ++i) nz.push_back(3 * node + i);
  const std::vector<double> values = test::random_vector(static_cast<int>(nz.size()) * k, 12);
  std::vector<double> B(static_cast<size_t>(n) * k, 0.0);
  for (int c = 0; c < k; ++c)
    for (size_t t = 0; t < nz.size(); ++t) B[static_cast<size_t>(c) * n + nz[t]] = values[c * nz.size() + t];
  struct Case {
    const char* name;
    FactorCopy copy;
    bool single;
  };
  for (const Case c : {Case{"double", FactorCopy::None, false}, Case{"float copy", FactorCopy::Float, false},
                       Case{"half copy", FactorCopy::Half, false}, Case{"single factorization", FactorCopy::Float, true},
                       Case{"single factorization, half copy", FactorCopy::Half, true}}) {
    CholmodSolver f;
    f.configure(FactorMethod::Supernodal, OrderingMethod::Amd);
    f.set_factor_copy(c.copy);
    f.set_single_factorization(c.single);
    f.analyze(n, m.Ap, m.Ai);
    f.factorize(A.data());
    std::vector<double> X(B.size()), Z;
    std::vector<int> rows;
    f.solve_copy_multi(k, B.data(), X.data());
    ASSERT_TRUE(f.forward_half_multi(k, B.data(), nz, rows, Z)) << c.name;
    ASSERT_EQ(Z.size(), rows.size() * k);
    EXPECT_LT(rows.size(), static_cast<size_t>(n)) << c.name << ": the paths skip part of the factor";
    double diff = 0.0, norm = 0.0;
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < k; ++j) {
        double zz = 0.0, bx = 0.0;
        for (size_t t = 0; t < rows.size(); ++t) zz += Z[i * rows.size() + t] * Z[j * rows.size() + t];
        for (int d = 0; d < n; ++d) bx += B[static_cast<size_t>(i) * n + d] * X[static_cast<size_t>(j) * n + d];
        diff = std::max(diff, std::abs(zz - bx));
        norm = std::max(norm, std::abs(bx));
      }
    EXPECT_LT(diff, 1e-12 * norm) << c.name;
    if (std::string(c.name) == "double") std::printf("[ forward half: %zu of %d rows ]\n", rows.size(), n);
    // The backward half from Z c is the solve of B c: X c, to roundoff (the
    // forward half of B c summed as Z's columns are).
    const std::vector<double> coef = test::random_vector(k, 13);
    std::vector<double> zc(rows.size(), 0.0), x(n), xc(n, 0.0);
    for (int i = 0; i < k; ++i)
      for (size_t t = 0; t < rows.size(); ++t) zc[t] += Z[i * rows.size() + t] * coef[i];
    for (int i = 0; i < k; ++i)
      for (int d = 0; d < n; ++d) xc[d] += X[static_cast<size_t>(i) * n + d] * coef[i];
    f.backward_half(rows, zc.data(), x.data());
    double xdiff = 0.0, xnorm = 0.0;
    for (int d = 0; d < n; ++d) {
      xdiff = std::max(xdiff, std::abs(x[d] - xc[d]));
      xnorm = std::max(xnorm, std::abs(xc[d]));
    }
    EXPECT_LT(xdiff, 1e-12 * xnorm) << c.name << ": backward half";
  }
  CholmodSolver simplicial;
  simplicial.configure(FactorMethod::Simplicial, OrderingMethod::Amd);
  simplicial.analyze(n, m.Ap, m.Ai);
  simplicial.factorize(A.data());
  std::vector<int> rows{-1};
  std::vector<double> Z{-1.0};
  EXPECT_FALSE(simplicial.forward_half_multi(k, B.data(), nz, rows, Z));
  EXPECT_EQ(rows, std::vector<int>{-1});
  EXPECT_EQ(Z, std::vector<double>{-1.0});
}

}  // namespace
}  // namespace incise
