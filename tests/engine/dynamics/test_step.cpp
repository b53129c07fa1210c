// Newmark average acceleration: energy conservation (undamped, linear),
// monotone decay with Rayleigh damping, prescribed motion followed exactly.
#include <cmath>
#include <cstdio>
#include <functional>

#include <gtest/gtest.h>

#include "engine/util/error.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/dynamics/state.h"
#include "engine/dynamics/step.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

Scene cantilever_scene(MaterialModel mm) {
  Scene s = test::basic_scene(2, mm);
  s.material.young = 1e4;
  s.material.density = 1.0;
  s.gravity = {0, 0, -9.81};
  s.dt = 1.0 / 30.0;
  s.fixed.push_back(test::box_region({-1, -1, -1}, {0, 2, 2}));
  return s;
}

TEST(Newmark, UndampedLinearConservesEnergyOver1000Steps) {
  const Mesh mesh = make_beam(4.0, 0.5, 0.5, 8, 1, 1, 1);
  for (MassKind mk : {MassKind::Lumped, MassKind::Consistent}) {
    Scene s = cantilever_scene(MaterialModel::Linear);
    s.mass = mk;
    const Model m = build_model(mesh, s);
    State st; Workspace ws;
    init_state(m, st, ws);
    const double E0 = total_energy(m, st);
    double scale = 0, drift = 0;
    for (int k = 0; k < 1000; ++k) {
      step(m, st, ws);
      const double E = total_energy(m, st);
      drift = std::max(drift, std::abs(E - E0));
      // the energy that sloshes between kinetic and potential sets the scale
      std::vector<double> Mv(m.ndof());
      mass_matvec(m, st.v.data(), Mv.data());
      double kin = 0;
      for (int d = 0; d < m.ndof(); ++d) kin += 0.5 * st.v[d] * Mv[d];
      scale = std::max(scale, kin);
    }
    EXPECT_GT(scale, 0.0);
    EXPECT_LT(drift / scale, 1e-6) << "drift " << drift << " scale " << scale;
    EXPECT_EQ(ws.refactorizations, 1) << "a linear scene factors once";
  }
}

// A run-away motion that never becomes NaN (issue 24's soak: a tiny cut
// piece reached 1e22 m/s with finite numbers) is stopped like NaN: at more
// than kDivergedSpeed (1e6) body lengths a second, naming the DOF.
TEST(Newmark, MotionFasterThanAMillionBodyLengthsASecondIsStopped) {
  const Mesh mesh = make_beam(4.0, 0.5, 0.5, 8, 1, 1, 1);
  const Model m = build_model(mesh, cantilever_scene(MaterialModel::Linear));
  State st;
  Workspace ws;
  init_state(m, st, ws);
  const double length = std::sqrt(4.0 * 4.0 + 0.5 * 0.5 + 0.5 * 0.5);
  st.v[17] = -0.99 * kDivergedSpeed * length;
  EXPECT_NO_THROW(check_motion_bounded(m, st));
  st.v[17] = -1.01 * kDivergedSpeed * length;
  try {
    check_motion_bounded(m, st);
    ADD_FAILURE() << "no error";
  } catch (const NumericalError& e) {
    EXPECT_EQ(e.dof, 17);
    EXPECT_NE(std::string(e.what()).find("the motion diverged at frame 0 (t = 0): DOF 17 moves at"), std::string::npos)
        << e.what();
    // Under `exact` without cuts it does not blame CG or a cut piece.
    EXPECT_EQ(std::string(e.what()).find("cut piece"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find("CG"), std::string::npos) << e.what();
  }
}

TEST(Newmark, RayleighDampedEnergyDecaysMonotonically) {
  // Released from rest under gravity: E = T + U_el - f.u obeys dE/dt = -v'Dv <= 0
  // and settles at the static value -f.u_static / 2 (linear).
  const Mesh mesh = make_beam(4.0, 0.5, 0.5, 8, 1, 1, 1);
  for (MaterialModel mm : {MaterialModel::Linear, MaterialModel::Corotated}) {
    Scene s = cantilever_scene(mm);
    s.material.rayleigh_mass = 2.0;
    s.material.rayleigh_stiffness = 0.01;
    const Model m = build_model(mesh, s);
    State st; Workspace ws;
    init_state(m, st, ws);
    double prev = total_energy(m, st);
    for (int k = 0; k < 600; ++k) {
      step(m, st, ws);
      const double E = total_energy(m, st);
      EXPECT_LE(E, prev + 1e-12 * std::abs(prev)) << "step " << k;
      prev = E;
    }
    double fu = 0;
    for (int d = 0; d < m.ndof(); ++d) fu += m.f_gravity[d] * st.u[d];
    EXPECT_LT(prev, 0.0);
    if (mm == MaterialModel::Linear) {
      EXPECT_NEAR(prev / (-0.5 * fu), 1.0, 1e-3);
    }
  }
}

TEST(Newmark, PrescribedRampIsFollowedExactly) {
  const Mesh mesh = make_beam(2.0, 0.5, 0.5, 4, 1, 1, 1);
  Scene s = cantilever_scene(MaterialModel::Corotated);
  Prescribed p;
  p.region = test::box_region({2, -1, -1}, {3, 2, 2}, "prescribed[0]");
  p.active = {false, false, true};
  p.displacement = {0, 0, 0.3};
  p.ramp = 0.5;
  s.prescribed.push_back(p);
  const Model m = build_model(mesh, s);
  State st; Workspace ws;
  init_state(m, st, ws);
  for (int k = 0; k < 30; ++k) {
    step(m, st, ws);
    const double expect = 0.3 * std::min(1.0, st.time / 0.5);
    for (const auto& pd : m.prescribed) ASSERT_NEAR(st.u[pd.dof], expect, 1e-14);
    for (int d : m.fixed_dofs) ASSERT_EQ(st.u[d], 0.0);
    // Their velocity is the ramp's (0.6 while it runs, 0 after), not Newmark's
    // 2/dt Delta - v, which would alternate 0, 1.2 and then flip sign forever.
    const double v_expect = st.time < 0.5 - 1e-9 ? 0.6 : 0.0;
    for (const auto& pd : m.prescribed) ASSERT_NEAR(st.v[pd.dof], v_expect, 1e-12) << "t " << st.time;
  }
}

// integrator.predictor: after a sudden push the trapezoidal rule leaves the
// free DOFs' velocity alternating (v1 = 2/dt Delta - v on stiff, damped
// modes), so dt v starts Newton off by that alternation; the last increment
// does not. Both converge to the same steps (a tight rotation tolerance and
// enough iterations); here the increment needs fewer iterations to get
// there (82 against 95). How much it saves depends on the motion: on this
// beam over ramps of 1-9 frames, Rayleigh stiffness 0.002-0.05 and rotation
// tolerances 1e-2-1e-5 it saved iterations in 18 of 24 converged cases and
// cost up to 7% more in the other 6.
TEST(Newmark, IncrementPredictorConvergesToTheSameStepsInFewerIterations) {
  const Mesh mesh = make_beam(2.0, 0.5, 0.5, 4, 1, 1, 1);
  Scene s = cantilever_scene(MaterialModel::Corotated);
  s.material.rayleigh_stiffness = 0.05;
  Prescribed p;
  p.region = test::box_region({2, -1, -1}, {3, 2, 2}, "prescribed[0]");
  p.active = {false, false, true};
  p.displacement = {0, 0, 0.5};
  p.ramp = 0.3;  // nine frames, then held
  s.prescribed.push_back(p);
  s.newton_iterations = 1;
  s.max_newton_iterations = 40;
  s.rotation_tolerance = 1e-5;
  std::vector<double> u[2];
  int iterations[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    s.increment_predictor = k == 1;
    const Model m = build_model(mesh, s);
    State st;
    Workspace ws;
    init_state(m, st, ws);
    for (int f = 0; f < 30; ++f) {
      step(m, st, ws);
      iterations[k] += ws.timing.newton;
      ASSERT_LT(ws.timing.newton, s.max_newton_iterations) << "frame " << f << ": Newton converged";
    }
    u[k] = st.u;
  }
  std::printf("[ Newton iterations over 30 frames: velocity predictor %d, increment %d; rel. difference %.2g ]\n",
              iterations[0], iterations[1], test::rel_diff(u[1], u[0]));
  EXPECT_LT(test::rel_diff(u[1], u[0]), 1e-6);  // the same steps
  EXPECT_LT(iterations[1], iterations[0]);
}

TEST(Newmark, GammaAboveOneHalfDampsAndOneHalfConserves) {
  // Undamped linear cantilever, stiff enough that omega dt >> 1 for its
  // modes, released under gravity. gamma = 1/2 (beta 1/4) conserves the energy
  // (test above); gamma = 0.6 with beta = (gamma + 1/2)^2 / 4 damps the high
  // frequencies: over steps 240-300 the largest kinetic energy is 5e-10 of
  // what gamma = 1/2 keeps (measured); asserted below 1e-3.
  const Mesh mesh = make_beam(4.0, 0.5, 0.5, 8, 1, 1, 1);
  double late_kinetic[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    Scene s = cantilever_scene(MaterialModel::Linear);
    s.material.young = 1e6;  // stiff: omega dt >> 1 for most modes, where the damping acts
    s.newmark_gamma = k == 0 ? 0.5 : 0.6;
    s.newmark_beta = 0.25 * (s.newmark_gamma + 0.5) * (s.newmark_gamma + 0.5);
    const Model m = build_model(mesh, s);
    State st; Workspace ws;
    init_state(m, st, ws);
    for (int f = 0; f < 300; ++f) {
      step(m, st, ws);
      if (f < 240) continue;  // the last 60 steps (2 s, several periods)
      std::vector<double> Mv(m.ndof());
      mass_matvec(m, st.v.data(), Mv.data());
      double kin = 0;
      for (int d = 0; d < m.ndof(); ++d) kin += 0.5 * st.v[d] * Mv[d];
      late_kinetic[k] = std::max(late_kinetic[k], kin);
    }
  }
  EXPECT_GT(late_kinetic[0], 0.0);
  std::printf("late kinetic energy, gamma 0.6 / gamma 0.5: %.3g\n", late_kinetic[1] / late_kinetic[0]);
  EXPECT_LT(late_kinetic[1], 1e-3 * late_kinetic[0]) << late_kinetic[1] << " vs " << late_kinetic[0];
}

// A recovery step (State::recovery, after a capped Newton iteration or a
// severing cut) is backward Euler in Newmark's form: on one degree of
// freedom m x'' + k x = f with the coefficients integrate() uses,
// - it ignores the carried acceleration, which an unconverged step leaves
//   inconsistent: from rest at equilibrium with a = 1e6 it stays there, where
//   the trapezoidal rule moves;
// - it is L-stable: at omega dt = 1e3 one step leaves 1e-3 of the amplitude
//   (1 / sqrt(1 + (omega dt)^2); the trapezoidal rule keeps it all);
// - it is first order: in free fall v is exact and x is g dt^2 / 2 low.
TEST(Newmark, RecoveryStepIsBackwardEuler) {
  const Model m = build_model(make_beam(1.0, 0.5, 0.5, 2, 1, 1, 1), cantilever_scene(MaterialModel::Corotated));
  const double dt = m.dt;
  struct Dof {
    double x, v, a;
  };
  // One step from y under f with stiffness k (unit mass): r = f - k (x + D) - a1(D) = 0.
  auto step1 = [](const NewmarkCoefficients& c, Dof y, double k, double f) {
    const double D = (f - k * y.x - c.a_v * y.v - c.a_a * y.a) / (c.a_d + k);
    return Dof{y.x + D, c.v_d * D + c.v_v * y.v + c.v_a * y.a, c.a_d * D + c.a_v * y.v + c.a_a * y.a};
  };
  const NewmarkCoefficients be = newmark_coefficients(m, true), tr = newmark_coefficients(m, false);
  const double k = 4.0 / (dt * dt), f = 2.0;
  const Dof rest{f / k, 0.0, 1e6};
  const Dof r_be = step1(be, rest, k, f), r_tr = step1(tr, rest, k, f);
  EXPECT_DOUBLE_EQ(r_be.x, rest.x);
  EXPECT_NEAR(r_be.v, 0.0, 1e-15);
  EXPECT_GT(std::abs(r_tr.x - rest.x), 1e-3 * rest.x);
  const double stiff = 1e6 / (dt * dt);  // omega dt = 1e3
  const auto amplitude = [&](const Dof& y) { return std::hypot(y.x, y.v / std::sqrt(stiff)); };
  const Dof y0{1.0, 0.0, -stiff};
  EXPECT_LT(amplitude(step1(be, y0, stiff, 0.0)), 1.01e-3 * amplitude(y0));  // 1 / sqrt(1 + (omega dt)^2)
  EXPECT_NEAR(amplitude(step1(tr, y0, stiff, 0.0)), amplitude(y0), 1e-9);
  const double g = 9.81;
  const Dof fall = step1(be, Dof{0.0, 1.0, g}, 0.0, g);
  EXPECT_NEAR(fall.v, 1.0 + g * dt, 1e-12);
  EXPECT_NEAR(fall.x, dt + 0.5 * g * dt * dt + 0.5 * g * dt * dt, 1e-12);
  EXPECT_NEAR(fall.a, g, 1e-9);
}

TEST(Newmark, UnstableNewmarkParametersAreRejected) {
  Scene s = cantilever_scene(MaterialModel::Linear);
  s.newmark_gamma = 0.6;  // beta left at 1/4 < gamma / 2: conditionally stable only
  try {
    build_model(make_beam(1.0, 0.5, 0.5, 2, 1, 1, 1), s);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("newmark_beta >= newmark_gamma / 2"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

TEST(Newmark, NaNInTheStateStopsTheStepWithAMessage) {
  const Mesh mesh = make_beam(2.0, 0.5, 0.5, 4, 1, 1, 1);
  for (MaterialModel mm : {MaterialModel::Linear, MaterialModel::Corotated}) {
    const Model m = build_model(mesh, cantilever_scene(mm));
    State st; Workspace ws;
    init_state(m, st, ws);
    step(m, st, ws);
    st.u[3 * (m.nnode - 1) + 1] = std::nan("");
    try {
      step(m, st, ws);
      FAIL() << "expected an error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("non-finite"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

// The adaptive check adds iterations only when rotations move within a step,
// and each added iteration brings the step closer to the converged one.
TEST(Newmark, AdaptiveIterationsApproachTheConvergedStep) {
  const Mesh mesh = make_beam(4.0, 0.5, 0.5, 8, 1, 1, 1);
  auto run = [&](int iters, double tol) {
    Scene s = cantilever_scene(MaterialModel::Corotated);
    s.material.young = 2e3;  // soft: large, fast rotations
    s.newton_iterations = iters;
    s.max_newton_iterations = 4;
    s.rotation_tolerance = tol;
    const Model m = build_model(mesh, s);
    State st; Workspace ws;
    init_state(m, st, ws);
    int total = 0;
    for (int k = 0; k < 20; ++k) {
      step(m, st, ws);
      total += ws.newton_iterations_done;
    }
    return std::make_pair(st.u, total);
  };
  const auto ref = run(8, 0.0);     // 8 iterations every step: converged
  const auto one = run(1, 0.0);     // one linearised solve
  const auto adapt = run(1, 0.002);  // adaptive, tight tolerance
  auto diff = [&](const std::vector<double>& a) {
    double e = 0, n = 0;
    for (size_t d = 0; d < a.size(); ++d) e += (a[d] - ref.first[d]) * (a[d] - ref.first[d]), n += ref.first[d] * ref.first[d];
    return std::sqrt(e / n);
  };
  EXPECT_EQ(one.second, 20);
  EXPECT_GT(adapt.second, 20);
  EXPECT_LE(adapt.second, 80);
  EXPECT_LT(diff(adapt.first), 0.5 * diff(one.first));
  std::printf("rel. L2 vs converged after 20 steps: one solve %.2e, adaptive %.2e (%d solves)\n", diff(one.first),
              diff(adapt.first), adapt.second);
}

// A soft cantilever (Young's modulus E: large, fast rotations) with
// Rayleigh stiffness damping b, stepped `steps` times; `each` sees every
// step's Workspace. Returns the final displacement.
std::vector<double> run_soft_cantilever(Scene s, double E, double b, int steps,
                                        const std::function<void(const Workspace&)>& each) {
  const Mesh mesh = make_beam(4.0, 0.5, 0.5, 8, 1, 1, 1);
  s.material.young = E;
  s.material.rayleigh_stiffness = b;
  const Model m = build_model(mesh, s);
  State st;
  Workspace ws;
  init_state(m, st, ws);
  for (int k = 0; k < steps; ++k) {
    step(m, st, ws);
    each(ws);
  }
  return st.u;
}

// integrator.line_search: a very soft cantilever (E = 300 Pa) at dt = 0.1 s
// swings so far within a step that Newton (rotation test at 1e-6 rad, 30
// iterations) runs to its cap in 8 of 30 steps; taking back halfway the
// iterations that raise the residual, fewer steps reach the cap and the run
// takes fewer iterations.
TEST(Newmark, LineSearchConvergesStepsWhoseNewtonDoesNot) {
  struct Run {
    int capped = 0, iterations = 0, halvings = 0;
  };
  auto run = [&](bool line_search) {
    Scene s = cantilever_scene(MaterialModel::Corotated);
    s.dt = 0.1;
    s.material.poisson = 0.3;
    s.max_newton_iterations = 30;
    s.rotation_tolerance = 1e-6;
    s.line_search = line_search;
    s.recovery_steps = false;  // Newmark's rule in every step: recovery steps after capped ones change the counts
    Run r;
    run_soft_cantilever(s, 300.0, 0.0, 30, [&](const Workspace& ws) {
      r.iterations += ws.timing.newton;
      r.capped += ws.timing.newton >= 30;
      r.halvings += ws.timing.line_search_halvings;
    });
    return r;
  };
  const Run plain = run(false), searched = run(true);
  ASSERT_GE(plain.capped, 1) << "the test needs steps whose plain Newton does not converge";
  EXPECT_EQ(plain.halvings, 0);
  EXPECT_GE(searched.halvings, 1);
  EXPECT_LT(searched.capped, plain.capped);
  EXPECT_LT(searched.iterations, plain.iterations);
  std::printf("steps at the cap %d -> %d, iterations %d -> %d (%d halvings)\n", plain.capped, searched.capped,
              plain.iterations, searched.iterations, searched.halvings);
}

// integrator.residual_tolerance: Newton goes on while the relative residual
// at an iteration's start is above it (the rotation test off here), so each
// step ends one iteration after its residual fell below the tolerance, and
// the steps are the converged ones: those of a run to a 1e-12 rotation
// change, to 1e-9.
TEST(Newmark, ResidualToleranceIteratesToAConvergedStep) {
  auto run = [&](double rot_tol, double res_tol, std::vector<double>* last) {
    Scene s = cantilever_scene(MaterialModel::Corotated);
    s.max_newton_iterations = 40;
    s.rotation_tolerance = rot_tol;
    s.residual_tolerance = res_tol;
    int k = 0;
    return run_soft_cantilever(s, 2e3, 0.01, 20, [&](const Workspace& ws) {
      EXPECT_LT(ws.timing.newton, 40) << "step " << k++;
      if (last) last->push_back(ws.last_residual);
    });
  };
  std::vector<double> residuals;
  const std::vector<double> by_residual = run(0.0, 1e-10, &residuals), by_rotation = run(1e-12, 0.0, nullptr);
  for (size_t k = 0; k < residuals.size(); ++k) EXPECT_LE(residuals[k], 1e-10) << "step " << k;
  EXPECT_LT(test::rel_diff(by_residual, by_rotation), 1e-9);
  const std::vector<double> loose = run(0.1, 0.0, nullptr);
  EXPECT_GT(test::rel_diff(loose, by_rotation), 1e-6) << "the default stop is not the converged step";
}

// The Rayleigh stiffness damping is b R K0 R^T v (this iterate's rotations),
// not the assembled tangent: converged to a 1e-10 residual, the steps of a
// damped soft cantilever are the same whichever tangent Newton uses and
// whether it keeps element tangents (before, the consistent tangent's
// rotation term and the kept blocks were in the damping term and moved the
// converged steps).
TEST(Newmark, ConvergedStepsDoNotDependOnTheTangent) {
  auto run = [&](bool consistent, double reuse) {
    Scene s = cantilever_scene(MaterialModel::Corotated);
    s.consistent_tangent = consistent;
    s.tangent_reuse = reuse;
    s.max_newton_iterations = 60;
    s.rotation_tolerance = 0.0;
    s.residual_tolerance = 1e-10;
    return run_soft_cantilever(s, 2e3, 0.05, 20, [&](const Workspace& ws) { EXPECT_LT(ws.timing.newton, 60); });
  };
  const std::vector<double> frozen = run(false, 0.0), consistent = run(true, 0.0), kept = run(true, 1e-2);
  EXPECT_LT(test::rel_diff(consistent, frozen), 1e-8);
  EXPECT_LT(test::rel_diff(kept, frozen), 1e-8);
  std::printf("consistent vs frozen %.2e, kept tangents vs frozen %.2e\n", test::rel_diff(consistent, frozen),
              test::rel_diff(kept, frozen));
}

}  // namespace
}  // namespace incise
