// Solver policies (issue 4): warped is exact where it should be, every
// iterative policy converges to the exact trajectory as its tolerance
// tightens, and the background factorization is deterministic.
#include <sched.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "engine/solve/linear_solve.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/dynamics/state.h"
#include "engine/dynamics/step.h"
#include "engine/fem/polar.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

// A free body (no constraints), rigidly rotated by Q, released under gravity:
// every slot has rotation Q, so A = cM M + Q K0 Q^T = Q A0 Q^T with lumped mass.
std::vector<double> rigid_step(SolverPolicy policy, int order, RotationMode rot) {
  const Mesh mesh = make_beam(1.0, 0.4, 0.3, 3, 2, 2, 1);
  Scene s = test::basic_scene(order, MaterialModel::Corotated, rot);
  s.gravity = {0.3, -0.2, -9.81};
  s.material.rayleigh_stiffness = 0.01;
  s.material.rayleigh_mass = 0.5;
  s.solver.policy = policy;
  const Model m = build_model(mesh, s);
  State st; Workspace ws;
  init_state(m, st, ws);
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(1.2, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  for (int n = 0; n < m.nnode; ++n) {
    const Eigen::Vector3d X(m.X[3 * n], m.X[3 * n + 1], m.X[3 * n + 2]);
    const Eigen::Vector3d x = Q * X;
    for (int d = 0; d < 3; ++d) {
      st.u[3 * n + d] = x[d] - X[d];
      st.v[3 * n + d] = 0.1 * (d + 1);  // a rigid translation velocity
    }
  }
  step(m, st, ws);
  return st.u;
}

TEST(SolverPolicies, WarpedIsExactForARigidRotationWithLumpedMass) {
  for (int order : {1, 2})
    for (RotationMode rot : {RotationMode::PerPoint, RotationMode::Single}) {
      if (order == 1 && rot == RotationMode::Single) continue;
      const auto exact = rigid_step(SolverPolicy::Exact, order, rot);
      const auto warped = rigid_step(SolverPolicy::Warped, order, rot);
      EXPECT_LT(test::rel_diff(warped, exact), 1e-12) << "order " << order;
    }
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

// The own BLAS-free supernodal substitution equals cholmod_solve2.
TEST(SolverPolicies, OwnSupernodalSubstitutionMatchesCholmod) {
  const Mesh mesh = make_beam(2.0, 0.5, 0.5, 8, 2, 2, 1);
  Scene s = test::basic_scene(2);
  s.fixed.push_back(test::box_region({-1, -1, -1}, {0, 2, 2}));
  const Model m = build_model(mesh, s);
  for (FactorMethod method : {FactorMethod::Supernodal, FactorMethod::Simplicial}) {
    CholmodSolver solver;
    solver.configure(method, OrderingMethod::Auto);
    solver.analyze(m.ndof(), m.Ap, m.Ai);
    std::vector<double> A = m.K0_csc;
    for (int d = 0; d < m.ndof(); ++d) A[m.diag[d]] += 1e3 * m.mass_lumped[d];
    solver.factorize(A.data());
    EXPECT_EQ(solver.stats().supernodal, method == FactorMethod::Supernodal);
    std::vector<double> b(m.ndof()), x1(m.ndof()), x2(m.ndof());
    for (int d = 0; d < m.ndof(); ++d) b[d] = std::sin(0.37 * d) + 0.1;
    solver.solve(b.data(), x1.data());
    solver.solve_cholmod(b.data(), x2.data());
    EXPECT_LT(test::rel_diff(x1, x2), 1e-12);
  }
}

}  // namespace
}  // namespace incise

#include "engine/fem/assemble.h"
#include "engine/fem/assemble_parallel.h"

namespace incise {
namespace {

// A small swinging cantilever: clamped at x = 0, the free end prescribed to
// move through a large arc while gravity acts (a miniature of
// assets/scenes/swing_beam.json).
Scene swing_scene(SolverSettings solver) {
  Scene s = test::swing_scene();
  s.rotation_tolerance = 0.0;  // one linearised solve per frame: the counts below are per solve
  s.solver = solver;
  return s;
}

std::vector<double> run_swing(const SolverSettings& solver, int frames, std::vector<int>* iterations = nullptr) {
  const Mesh mesh = make_beam(2.0, 0.4, 0.4, 6, 1, 1, 1);
  const Model m = build_model(mesh, swing_scene(solver));
  State st; Workspace ws;
  init_state(m, st, ws);
  for (int k = 0; k < frames; ++k) {
    step(m, st, ws);
    if (iterations) iterations->push_back(ws.timing.iterations);
  }
  return st.u;
}

TEST(SolverPolicies, IterativePoliciesConvergeToExactAsToleranceTightens) {
  const int frames = 30;
  const auto exact = run_swing(SolverSettings{}, frames);
  struct Case {
    const char* name;
    SolverSettings s;
  };
  std::vector<Case> cases;
  {
    SolverSettings s;
    s.policy = SolverPolicy::Lagged;
    s.refresh_every = 4;
    cases.push_back({"lagged refresh 4", s});
    s.factor_copy = FactorCopy::Half;  // the coarser preconditioner converges all the same
    cases.push_back({"lagged refresh 4, half copy", s});
    s.factor_copy = FactorCopy::Float;
    s.background = true;
    s.refresh_every = 2;
    cases.push_back({"lagged background refresh 2", s});
    s.single_factorization = true;  // factored in float (engine/solve/single_factor.h)
    cases.push_back({"lagged background refresh 2, single-precision factorization", s});
    s.coarse = true;  // two-level: the corner-node coarse level (engine/solve/coarse_space.h)
    cases.push_back({"lagged background refresh 2, two-level", s});
    SolverSettings w;
    w.policy = SolverPolicy::WarpedCG;
    cases.push_back({"warped_cg", w});
  }
  for (auto c : cases) {
    c.s.max_iterations = 500;
    double prev = 1e300;
    for (double tol : {1e-2, 1e-4, 1e-6, 1e-8, 1e-10}) {
      c.s.tolerance = tol;
      std::vector<int> its;
      const double err = test::rel_diff(run_swing(c.s, frames, &its), exact);
      if (tol == 1e-2) {
        EXPECT_GT(err, 1e-8) << c.name << ": the loosest tolerance should show an error";
      }
      EXPECT_LT(err, prev * 1.0000001 + 1e-13) << c.name << " tolerance " << tol;
      prev = err;
      int total = 0;
      for (int i : its) total += i;
      EXPECT_GT(total, 0) << c.name;
    }
    EXPECT_LT(prev, 1e-8) << c.name << " at the tightest tolerance";
  }
}

// solver.matrix_precision "single": CG's products read A rounded to float,
// so each solve is of a matrix about 6e-8 off, and a frame's single Newton
// iteration keeps that much of the step: at real-time tolerances the error
// against exact is the double matrix's (CG's tolerance dominates it by five
// orders; measured at 1e-4: 1.32e-5 against 1.33e-5, 1.22e-5 in the
// ASan build, where a solve stops at another CG iteration), and as the
// tolerance tightens it falls to a floor near the float rounding of A
// (measured: 3.9e-8 at 1e-10, against 4.4e-12 in double).
TEST(SolverPolicies, SinglePrecisionMatrixConvergesToTheRoundingOfA) {
  const int frames = 30;
  const auto exact = run_swing(SolverSettings{}, frames);
  SolverSettings s;
  s.policy = SolverPolicy::Lagged;
  s.background = true;
  s.refresh_every = 2;
  s.single_factorization = true;
  s.max_iterations = 500;
  double prev = 1e300;
  for (double tol : {1e-2, 1e-4, 1e-6, 1e-10}) {
    s.tolerance = tol;
    s.single_matrix = false;
    const double err_double = test::rel_diff(run_swing(s, frames), exact);
    s.single_matrix = true;
    const double err_single = test::rel_diff(run_swing(s, frames), exact);
    if (tol >= 1e-4) {  // the same within what a CG iteration more or less in a frame makes
      EXPECT_LT(err_single, 1.5 * err_double) << "tolerance " << tol;
      EXPECT_GT(err_single, err_double / 1.5) << "tolerance " << tol;
    }
    if (tol >= 1e-6) {
      EXPECT_LT(err_single, prev) << "tolerance " << tol;
    }
    prev = err_single;
    if (tol == 1e-10) {
      EXPECT_LT(err_single, 2e-7) << "the floor: A's float rounding";
      EXPECT_GT(err_single, 100 * err_double) << "CG's products read the float copy";
    }
  }
}

TEST(SolverPolicies, WarpedIsExactForTheLinearMaterial) {
  SolverSettings w;
  w.policy = SolverPolicy::Warped;
  const Mesh mesh = make_beam(2.0, 0.4, 0.4, 6, 1, 1, 1);
  Scene se = swing_scene(SolverSettings{}), sw = swing_scene(w);
  se.material.model = sw.material.model = MaterialModel::Linear;
  const Model me = build_model(mesh, se), mw = build_model(mesh, sw);
  State a, b; Workspace a_ws, b_ws;
  init_state(me, a, a_ws);
  init_state(mw, b, b_ws);
  for (int k = 0; k < 20; ++k) {
    step(me, a, a_ws);
    step(mw, b, b_ws);
  }
  EXPECT_LT(test::rel_diff(b.u, a.u), 1e-13);
}

TEST(SolverPolicies, WarpedAloneIsReportedAsOneSubstitutionAndNoIterations) {
  SolverSettings w;
  w.policy = SolverPolicy::Warped;
  const Mesh mesh = make_beam(2.0, 0.4, 0.4, 6, 1, 1, 1);
  const Model m = build_model(mesh, swing_scene(w));
  State st; Workspace ws;
  init_state(m, st, ws);
  step(m, st, ws);
  step(m, st, ws);
  EXPECT_EQ(ws.timing.solves, 1);
  EXPECT_EQ(ws.timing.iterations, 0);
  EXPECT_EQ(ws.refactorizations, 1) << "the rest factor is computed once";
}

TEST(SolverPolicies, BackgroundFactorizationIsDeterministic) {
  SolverSettings s;
  s.policy = SolverPolicy::Lagged;
  s.background = true;
  s.tolerance = 1e-5;
  const auto a = run_swing(s, 20), b = run_swing(s, 20);
  EXPECT_EQ(a, b) << "the factor started k frames ago is always the one used";
}

// solver.background_priority: with late_factor "skip" the background job runs
// at SCHED_IDLE by default (the stepping thread, the cut helper and a haptic
// thread come first) and at the normal policy when asked; with "wait" the
// step blocks on the job, so it keeps the normal policy either way.
TEST(SolverPolicies, BackgroundJobRunsAtIdlePriorityOnlyWhenTheStepNeverWaitsForIt) {
  const Mesh mesh = make_beam(2.0, 0.4, 0.4, 6, 1, 1, 1);
  for (bool skip : {true, false})
    for (bool idle : {true, false}) {
      SolverSettings solver;
      solver.policy = SolverPolicy::Lagged;
      solver.background = true;
      solver.refresh_every = 2;
      solver.tolerance = 1e-6;
      solver.skip_late_factor = skip;
      const Model m = build_model(mesh, swing_scene(solver));
      State st; Workspace ws;
      ws.runtime.idle_background = idle;
      init_state(m, st, ws);
      for (int k = 0; k < 8; ++k) step(m, st, ws);
      ws.work.wait_job();
      EXPECT_EQ(ws.work.job_policy, idle && skip ? SCHED_IDLE : SCHED_OTHER)
          << (idle ? "idle" : "normal") << ", late_factor " << (skip ? "skip" : "wait");
    }
}

TEST(SolverPolicies, SkippingLateFactorsStaysWithinTheCgTolerance) {
  // late_factor "skip" takes a background factor whenever it is ready, so
  // which factor preconditions a frame depends on timing; the result must
  // still be exact to the CG tolerance.
  const int frames = 20;
  const auto exact = run_swing(SolverSettings{}, frames);
  SolverSettings s;
  s.policy = SolverPolicy::Lagged;
  s.background = true;
  s.skip_late_factor = true;
  s.refresh_every = 2;
  s.tolerance = 1e-10;
  s.max_iterations = 500;
  EXPECT_LT(test::rel_diff(run_swing(s, frames), exact), 1e-8);
}

// late_factor "skip" leaves to the clock whether a finished background factor
// is taken; a replay imposes the recorded choice instead
// (Workspace::imposed_late_factor_call, docs/replay.md). Imposing "take it
// at the first refresh call whenever it is due" waits for the job and gives
// the bits of late_factor "wait"; imposing "never" keeps the first factor.
TEST(SolverPolicies, ImposedLateFactorChoicesDecideWhatTheClockWould) {
  SolverSettings s;
  s.policy = SolverPolicy::Lagged;
  s.background = true;
  s.refresh_every = 2;
  s.tolerance = 1e-5;
  const Mesh mesh = make_beam(2.0, 0.4, 0.4, 6, 1, 1, 1);
  const auto run = [&](bool skip, int imposed, std::vector<int>* calls, int* last_age) {
    SolverSettings solver = s;
    solver.skip_late_factor = skip;
    const Model m = build_model(mesh, swing_scene(solver));
    State st; Workspace ws;
    init_state(m, st, ws);
    for (int k = 0; k < 16; ++k) {
      ws.imposed_late_factor_call = imposed;
      step(m, st, ws);
      calls->push_back(ws.timing.late_factor_call);
      *last_age = ws.timing.factor_age;
    }
    return st.u;
  };
  std::vector<int> wait_calls, take_calls, never_calls;
  int age = 0;
  const auto u_wait = run(false, Workspace::kClockDecides, &wait_calls, &age);
  const auto u_take = run(true, 0, &take_calls, &age);
  EXPECT_EQ(u_take, u_wait);
  EXPECT_EQ(std::count(wait_calls.begin(), wait_calls.end(), -1), 16) << "wait: the clock chooses nothing";
  EXPECT_GE(std::count(take_calls.begin(), take_calls.end(), 0), 6) << "taken every 2nd frame";
  run(true, -1, &never_calls, &age);
  EXPECT_EQ(std::count(never_calls.begin(), never_calls.end(), -1), 16);
  EXPECT_GE(age, 14) << "never taken: the first frame's factor preconditions the last";
}

TEST(SolverPolicies, LaggedRefreshEveryFrameIsOneIterationPerFrame) {
  SolverSettings s;
  s.policy = SolverPolicy::Lagged;
  s.refresh_every = 1;
  std::vector<int> its;
  run_swing(s, 10, &its);
  for (int i : its) EXPECT_EQ(i, 1);
}

// solver.initial_guess "previous": CG starts from the last frame's first
// increment scaled to the best fit. It never starts above |b| (the frames
// it helps start below 1), saves iterations over a swinging run at the same
// tolerance, and both starts reach the same trajectory within it.
TEST(SolverPolicies, PreviousIncrementStartSavesIterationsAndKeepsTheTrajectory) {
  const int frames = 30;
  const auto exact = run_swing(SolverSettings{}, frames);
  for (SolverPolicy policy : {SolverPolicy::Lagged, SolverPolicy::WarpedCG}) {
    SolverSettings s;
    s.policy = policy;
    s.refresh_every = 4;
    s.tolerance = 1e-4;
    s.max_iterations = 500;
    int total[2] = {0, 0};
    std::vector<double> u[2];
    for (int g = 0; g < 2; ++g) {
      s.previous_guess = g == 1;
      const Mesh mesh = make_beam(2.0, 0.4, 0.4, 6, 1, 1, 1);
      const Model m = build_model(mesh, swing_scene(s));
      State st; Workspace ws;
      init_state(m, st, ws);
      int helped = 0;
      for (int k = 0; k < frames; ++k) {
        step(m, st, ws);
        total[g] += ws.timing.iterations;
        EXPECT_LE(ws.timing.start_residual, 1.0);
        helped += ws.timing.start_residual < 1.0;
        EXPECT_TRUE(ws.timing.converged);
      }
      if (g == 0) {
        EXPECT_EQ(helped, 0) << "no start but zero without the guess";
      } else {
        EXPECT_GE(helped, frames / 2) << policy_name(policy);
      }
      u[g] = st.u;
    }
    std::printf("[ %s: %d CG iterations from zero, %d from the last increment ]\n", policy_name(policy), total[0], total[1]);
    EXPECT_LT(total[1], total[0]) << policy_name(policy);
    // Both within the tolerance's reach of exact (errors ~1e-5 at 1e-4).
    EXPECT_LT(test::rel_diff(u[0], exact), 1e-3) << policy_name(policy);
    EXPECT_LT(test::rel_diff(u[1], exact), 1e-3) << policy_name(policy);
  }
}

// The lagged policy with a factor refreshed every 50 frames: far from the
// swinging beam's matrix within a few frames.
SolverSettings stale_lagged(double tolerance) {
  SolverSettings s;
  s.policy = SolverPolicy::Lagged;
  s.refresh_every = 50;
  s.tolerance = tolerance;
  s.max_iterations = 500;
  return s;
}

TEST(SolverPolicies, LaggedRescueRefactorsWhenCgStallsAndStaysExact) {
  // A factor refreshed every 50 frames is far from the swinging beam's
  // matrix: CG needs many iterations. With rescue_after = 3 a frame that has
  // not converged after 3 iterations factors its matrix and finishes with it,
  // so no frame takes more than 3 + 1 iterations per Newton iteration, and the
  // trajectory matches exact to the CG tolerance.
  const int frames = 20;
  const auto exact = run_swing(SolverSettings{}, frames);
  SolverSettings s = stale_lagged(1e-10);
  std::vector<int> slow;
  const auto lagged = run_swing(s, frames, &slow);
  s.rescue_after = 3;
  const Mesh mesh = make_beam(2.0, 0.4, 0.4, 6, 1, 1, 1);
  const Model m = build_model(mesh, swing_scene(s));
  State st; Workspace ws;
  init_state(m, st, ws);
  int rescues = 0, worst = 0;
  for (int k = 0; k < frames; ++k) {
    step(m, st, ws);
    rescues += ws.timing.rescues;
    worst = std::max(worst, ws.timing.iterations / std::max(1, ws.newton_iterations_done));
    EXPECT_TRUE(ws.timing.converged) << "frame " << k;
  }
  EXPECT_GT(*std::max_element(slow.begin(), slow.end()), 10) << "without rescue CG must struggle";
  EXPECT_GT(rescues, 0);
  EXPECT_LE(worst, 3 + 2) << "3 stalled iterations, then 1-2 with the fresh factor";
  EXPECT_LT(test::rel_diff(st.u, exact), 1e-8);
  EXPECT_LT(test::rel_diff(lagged, exact), 1e-8);
}

// A rescue while a background job runs factors the current matrix into the
// third slot at once instead of waiting for the job (whose matrix is older)
// and then factoring (with a BLAS that allows two factorizations at once:
// Debian's threaded OpenBLAS, which install-deps.sh installs); the job, when
// it ends, is dropped: the factor in use never goes back to an older frame.
// Deterministic ("wait"), so the trajectory is exact's to the CG tolerance.
TEST(SolverPolicies, LaggedRescueBesideARunningJobDoesNotWaitAndDropsTheOlderJob) {
  const int frames = 20;
  const auto exact = run_swing(SolverSettings{}, frames);
  // Without rescues CG takes 17-31 iterations a frame while the first
  // factor ages (frames 1-5) and 40-69 once older: a rescue after 35 comes
  // while the job launched at frame 4 runs (measured).
  SolverSettings s = stale_lagged(1e-10);
  s.refresh_every = 4;
  s.background = true;
  s.rescue_after = 35;
  const Mesh mesh = make_beam(2.0, 0.4, 0.4, 6, 1, 1, 1);
  const Model m = build_model(mesh, swing_scene(s));
  State st; Workspace ws;
  init_state(m, st, ws);
  int rescues = 0, beside_job = 0, last_front_frame = -1;
  for (int k = 0; k < frames; ++k) {
    step(m, st, ws);
    const SolverWork& w = ws.work;
    rescues += ws.timing.rescues;
    // The rescue's factor is this frame's; the job launched earlier still runs.
    if (ws.timing.rescues > 0 && w.job_running && w.job_frame < w.front_frame) {
      EXPECT_EQ(w.front_frame, st.frame - 1) << "frame " << k;  // (step advanced st.frame)
      EXPECT_NE(w.front, w.job_slot);
      ++beside_job;
    }
    EXPECT_GE(w.front_frame, last_front_frame) << "frame " << k << ": an older job was taken after a rescue";
    last_front_frame = w.front_frame;
    EXPECT_TRUE(ws.timing.converged) << "frame " << k;
  }
  EXPECT_GT(rescues, 0);
  if (blas_concurrency_safe()) {
    EXPECT_GT(beside_job, 0) << "no rescue happened while a job ran: the case is not tested";
    EXPECT_GT(ws.slot(2).stats().factorizations, 0) << "the third slot was never used";
  } else {  // a serial BLAS: two factorizations must not overlap, the rescue waits
    EXPECT_EQ(beside_job, 0);
    EXPECT_EQ(ws.slot(2).stats().factorizations, 0);
  }
  EXPECT_LT(test::rel_diff(st.u, exact), 1e-8);
}

// A factor refreshed every 50 frames is far from the swinging beam's matrix;
// the fresh coarse level (solver.coarse "corners") takes the smooth part of
// the error, so CG needs fewer iterations for the same trajectory.
TEST(SolverPolicies, TwoLevelNeedsFewerIterationsWithAStaleFactor) {
  const int frames = 20;
  const auto exact = run_swing(SolverSettings{}, frames);
  SolverSettings s = stale_lagged(1e-8);
  std::vector<int> one, two;
  const auto u1 = run_swing(s, frames, &one);
  s.coarse = true;
  const auto u2 = run_swing(s, frames, &two);
  int n1 = 0, n2 = 0;
  for (int i : one) n1 += i;
  for (int i : two) n2 += i;
  std::printf("[ CG iterations over %d frames: lagged %d, two-level %d ]\n", frames, n1, n2);
  EXPECT_LT(n2, n1);
  EXPECT_LT(test::rel_diff(u1, exact), 1e-6);
  EXPECT_LT(test::rel_diff(u2, exact), 1e-6);
}

// solver.frame_iterations: a budget far too small to converge (one CG
// iteration per frame, a factor refreshed every 50 frames, tolerance 1e-10,
// rescue after 3). No frame goes past its budget, none rescues, the frames
// that stopped short say so with the residual they took, and the state
// stays finite and bounded (NaN never comes out of a starved frame).
TEST(SolverPolicies, FrameIterationBudgetCapsCgAndReportsTheResidualTaken) {
  SolverSettings s = stale_lagged(1e-10);
  s.rescue_after = 3;
  s.frame_iterations = 1;
  for (bool coarse : {false, true}) {
    s.coarse = coarse;
    Scene sc = swing_scene(s);
    sc.rotation_tolerance = 0.1;  // Newton may want more iterations: the budget stops them
    const Mesh mesh = make_beam(2.0, 0.4, 0.4, 6, 1, 1, 1);
    const Model m = build_model(mesh, sc);
    State st; Workspace ws;
    init_state(m, st, ws);
    int spent = 0;
    for (int k = 0; k < 60; ++k) {
      step(m, st, ws);
      EXPECT_LE(ws.timing.iterations, 1) << "frame " << k;
      EXPECT_EQ(ws.timing.rescues, 0) << "frame " << k;
      EXPECT_EQ(ws.timing.newton, 1) << "frame " << k;
      if (ws.timing.budget_spent) {
        ++spent;
        EXPECT_FALSE(ws.timing.converged);
        EXPECT_GT(ws.timing.residual, s.tolerance) << "frame " << k;
        EXPECT_TRUE(std::isfinite(ws.timing.residual)) << "frame " << k;
      }
    }
    EXPECT_GT(spent, 30) << "coarse " << coarse;
    double umax = 0.0;
    for (double x : st.u) {
      ASSERT_TRUE(std::isfinite(x));
      umax = std::max(umax, std::abs(x));
    }
    EXPECT_LT(umax, 2.0) << "coarse " << coarse << ": the 2 m beam stays within its own length of rest";
  }
}

// apply_factor_inverse_multi (the contact compliance's columns in one
// substitution) gives each column what apply_factor_inverse gives it, under
// every policy, with the lagged factor warped by the rotations since its
// frame, and with a lagged patch (solver.contact_patch around a grasp row:
// column by column, in place as the contact stage calls it).
TEST(SolverPolicies, MultiColumnFactorInverseMatchesOneColumnAtATime) {
  std::vector<SolverSettings> settings(5);
  settings[1].policy = SolverPolicy::Lagged;
  settings[1].refresh_every = 5;
  settings[1].warp = true;
  settings[2].policy = SolverPolicy::Warped;
  settings[3].policy = SolverPolicy::WarpedCG;
  settings[4] = settings[1];
  settings[4].contact_patch = 1;
  for (const SolverSettings& solver : settings) {
    const Mesh mesh = make_beam(2.0, 0.4, 0.4, 6, 1, 1, 1);
    const Model m = build_model(mesh, swing_scene(solver));
    State st; Workspace ws;
    init_state(m, st, ws);
    const int held = m.ndof() - 1;  // a grasp row on the last DOF, holding it where it is
    for (int k = 0; k < 8; ++k) {  // the beam has turned since the lagged factor's frame
      ws.contacts.clear();
      const double p[3] = {0, 0, 0}, d[3] = {0, 0, 1};
      ws.contacts.begin_row(RowKind::Grasp, 0.0, 0, p, d, 0.0, -1);
      ws.contacts.add(held, 1.0);
      step(m, st, ws);
    }
    EXPECT_EQ(ws.work.patch_dof.empty(), solver.contact_patch == 0) << policy_name(solver.policy);
    const int n = m.ndof(), k = 3;
    const std::vector<double> B = test::random_vector(n * k, 5);
    std::vector<double> X(B.size()), one(n), inplace = B;
    apply_factor_inverse_multi(m, ws, k, B.data(), X.data());
    apply_factor_inverse_multi(m, ws, k, inplace.data(), inplace.data());
    EXPECT_EQ(inplace, X) << policy_name(solver.policy) << ": in place";
    for (int c = 0; c < k; ++c) {
      apply_factor_inverse(m, ws, B.data() + static_cast<size_t>(c) * n, one.data());
      std::vector<double> col(X.begin() + static_cast<size_t>(c) * n, X.begin() + static_cast<size_t>(c + 1) * n);
      EXPECT_LT(test::rel_diff(col, one), 1e-12) << policy_name(solver.policy) << " column " << c;
    }
  }
}

// Parallel fused assembly equals the serial reference (assemble_internal +
// update_rotations) for tet4, tet10 and tet10SR, for 1, 2 and 3 workers, with
// the frozen-rotation and the consistent tangent (its rotation term: dense
// rank-1 updates per point in the parallel path, block passes in the serial
// one; per element for tet10SR).
TEST(SolverPolicies, ParallelAssemblyMatchesSerial) {
  for (int order : {1, 2})
    for (RotationMode rot : {RotationMode::PerPoint, RotationMode::Single})
    for (bool consistent : {false, true}) {
      if (order == 1 && rot == RotationMode::Single) continue;
      const Mesh mesh = make_beam(2.0, 0.5, 0.4, 7, 3, 2, 1);
      Scene scene = test::basic_scene(order, MaterialModel::Corotated, rot);
      scene.consistent_tangent = consistent;
      const Model m = build_model(mesh, scene);
      std::vector<double> u(m.ndof());
      for (int n = 0; n < m.nnode; ++n) {  // a bend plus a twist: large, varied rotations
        const double x = m.X[3 * n], y = m.X[3 * n + 1], z = m.X[3 * n + 2];
        u[3 * n] = -0.3 * x * z + 0.01 * std::sin(7 * y);
        u[3 * n + 1] = 0.4 * x * z - 0.02 * y;
        u[3 * n + 2] = 0.5 * x * x - 0.4 * x * y + 0.01 * std::cos(5 * z);
      }
      std::vector<double> R0 = identity_rotations(m.nrot), f0(m.ndof()), K0(m.nnz());
      std::vector<double> Rs = R0;
      update_rotations(m, u.data(), Rs.data());
      assemble_internal(m, u.data(), Rs.data(), f0.data(), K0.data());
      double fn = 0, kn = 0;
      for (double v : f0) fn = std::max(fn, std::abs(v));
      for (double v : K0) kn = std::max(kn, std::abs(v));
      for (int threads : {1, 2, 3}) {
        ThreadPool pool(threads);
        AssemblyPlan plan = make_assembly_plan(m, threads);
        if (threads > 1) {
          EXPECT_GT(plan.nseparators(), 0);
        }
        std::vector<double> R = R0, f(m.ndof()), K(m.nnz());
        assemble_corotated(m, plan, pool, u.data(), R.data(), f.data(), K.data());
        double df = 0, dk = 0, dr = 0;
        for (int d = 0; d < m.ndof(); ++d) df = std::max(df, std::abs(f[d] - f0[d]));
        for (int k = 0; k < m.nnz(); ++k) dk = std::max(dk, std::abs(K[k] - K0[k]));
        for (size_t k = 0; k < R.size(); ++k) dr = std::max(dr, std::abs(R[k] - Rs[k]));
        EXPECT_LT(df, 1e-14 * fn) << "order " << order << " threads " << threads;
        EXPECT_LT(dk, 1e-14 * kn) << "order " << order << " threads " << threads;
        EXPECT_LT(dr, 1e-14) << "order " << order << " threads " << threads;
        // Matrix-free K v and the parallel sym_matvec agree with the assembled K.
        std::vector<double> v(m.ndof()), y1(m.ndof()), y2(m.ndof()), y3(m.ndof());
        for (int d = 0; d < m.ndof(); ++d) v[d] = std::cos(0.3 * d);
        sym_matvec(m, K0.data(), v.data(), y1.data());
        stiffness_matvec(m, plan, pool, R.data(), v.data(), y2.data());
        sym_matvec_parallel(m, plan, pool, K0.data(), v.data(), y3.data());
        // The matrix-free product is the frozen-R R K0 R^T: the assembled K
        // equals it with the frozen-rotation tangent.
        if (!consistent) {
          EXPECT_LT(test::rel_diff(y2, y1), 1e-13);
        }
        EXPECT_LT(test::rel_diff(y3, y1), 1e-14);
        // The same product fused into the assembly's pass (the step's damping
        // force), with the rotations that pass extracts.
        std::vector<double> Rv = R0, fv(m.ndof()), Kv(m.ndof(), 1.0);
        assemble_corotated(m, plan, pool, u.data(), Rv.data(), fv.data(), nullptr, nullptr, v.data(), Kv.data());
        EXPECT_LT(test::rel_diff(Kv, y2), 1e-14) << "order " << order << " threads " << threads;
      }
    }
}

// ThreadPool::set_active(1) (the workers stood down while a late background
// factorization needs their CPU, lagged_refresh): the stepping thread takes
// the plan's other blocks and ranges in turn, and every result keeps its bits.
TEST(SolverPolicies, StoodDownWorkersGiveTheSameBits) {
  const Mesh mesh = make_beam(2.0, 0.5, 0.4, 7, 3, 2, 1);
  Scene scene = test::basic_scene(2, MaterialModel::Corotated, RotationMode::PerPoint);
  scene.consistent_tangent = true;
  const Model m = build_model(mesh, scene);
  std::vector<double> u(m.ndof()), v(m.ndof());
  for (int n = 0; n < m.nnode; ++n) {  // a bend plus a twist
    const double x = m.X[3 * n], y = m.X[3 * n + 1], z = m.X[3 * n + 2];
    u[3 * n] = -0.3 * x * z + 0.01 * std::sin(7 * y);
    u[3 * n + 1] = 0.4 * x * z - 0.02 * y;
    u[3 * n + 2] = 0.5 * x * x - 0.4 * x * y;
  }
  for (int d = 0; d < m.ndof(); ++d) v[d] = std::cos(0.3 * d);
  for (int threads : {2, 3}) {
    ThreadPool pool(threads);
    AssemblyPlan plan = make_assembly_plan(m, threads);
    ASSERT_GT(plan.nseparators(), 0);
    struct Out {
      std::vector<double> R, f, K, fv, y;
      RotationChange rc;
    } out[2];
    for (int active : {threads, 1}) {
      pool.set_active(active);
      ASSERT_EQ(pool.active(), active);
      Out& o = out[active == 1];
      o.R = identity_rotations(m.nrot);
      o.f.assign(m.ndof(), 0.0);
      o.K.assign(m.nnz(), 0.0);
      o.fv.assign(m.ndof(), 0.0);
      o.y.assign(m.ndof(), 0.0);
      assemble_corotated(m, plan, pool, u.data(), o.R.data(), o.f.data(), o.K.data(), nullptr, v.data(), o.fv.data());
      sym_matvec_parallel(m, plan, pool, o.K.data(), v.data(), o.y.data());
      std::vector<double> x = u;
      for (double& w : x) w *= 1.1;
      o.rc = rotation_change(m, plan, pool, x.data(), o.R.data(), 0.01, 1e-4);
    }
    EXPECT_EQ(pool.size(), threads);
    const Out &a = out[0], &b = out[1];
    EXPECT_EQ(a.R, b.R) << threads << " workers";
    EXPECT_EQ(a.f, b.f) << threads << " workers";
    EXPECT_EQ(a.K, b.K) << threads << " workers";
    EXPECT_EQ(a.fv, b.fv) << threads << " workers";
    EXPECT_EQ(a.y, b.y) << threads << " workers";
    EXPECT_GT(a.rc.max, 0.0);
    EXPECT_EQ(a.rc.max, b.rc.max);
    EXPECT_EQ(a.rc.rms, b.rc.rms);
    EXPECT_EQ(a.rc.above, b.rc.above);
  }
}

}  // namespace
}  // namespace incise
