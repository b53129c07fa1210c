// integrator.tangent_reuse (TangentCache, engine/fem/assemble_parallel.h): K stays
// the sum of the kept element blocks after incremental updates, the internal
// forces are never approximated, a reused element is one whose F moved less
// than theta, and the trajectory approaches the full-assembly one as theta
// shrinks (off at 0).
#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "engine/fem/assemble_parallel.h"
#include "engine/fem/polar.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/dynamics/step.h"
#include "engine/solve/linear_solve.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

// test::swing_scene with the consistent tangent (damping through K): elements
// move at very different rates.
Scene swing(double theta) {
  Scene s = test::swing_scene();
  s.consistent_tangent = true;
  s.tangent_reuse = theta;
  return s;
}

const Mesh& beam_mesh() {
  static const Mesh mesh = make_beam(2.0, 0.4, 0.4, 8, 2, 2, 1);
  return mesh;
}

std::vector<double> run(double theta, int frames, int* min_updates = nullptr) {
  const Model m = build_model(beam_mesh(), swing(theta));
  State st; Workspace ws;
  init_state(m, st, ws);
  int least = m.nelem;
  for (int k = 0; k < frames; ++k) {
    step(m, st, ws);
    if (k > 0) least = std::min(least, ws.timing.tangent_updates);
  }
  if (min_updates) *min_updates = least;
  return st.u;
}

TEST(TangentReuse, KIsTheSumOfTheKeptBlocksAndForcesAreExact) {
  const Model m = build_model(beam_mesh(), swing(0.1));
  State st; Workspace ws;
  init_state(m, st, ws);
  for (int k = 0; k < 6; ++k) step(m, st, ws);
  const TangentCache& c = ws.tangent_cache;
  ASSERT_TRUE(c.valid);
  EXPECT_LT(c.updated, m.nelem) << "theta 0.1 should keep some element's blocks";
  // K re-summed from the kept blocks.
  std::vector<double> K(m.nnz(), 0.0);
  const int npe = m.elem_dof_ptr[1] - m.elem_dof_ptr[0];
  for (int e = 0; e < m.nelem; ++e) {
    const int n = m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e];
    ASSERT_EQ(n, npe);
    const int nb = 9 * n * (n + 1) / 2;
    for (int k = 0; k < nb; ++k) {
      const int pos = m.elem_scatter[m.elem_scatter_ptr[e] + k];
      if (pos >= 0) K[pos] += c.blocks(e)[k];
    }
  }
  EXPECT_LT(test::rel_diff(ws.K, K), 1e-12);
  // Forces at the current state: a full assembly gives the same f_int bit for
  // bit up to summation order (the cache only skips tangent blocks).
  State fresh; Workspace fresh_ws;
  init_state(m, fresh, fresh_ws);
  fresh.R = st.R;
  std::vector<double> f_cached(m.ndof()), f_full(m.ndof()), Kfull(m.nnz());
  TangentCache cache = ws.tangent_cache;
  std::vector<double> R1 = st.R, R2 = st.R, Kc = ws.K;
  AssemblyPlan plan = make_assembly_plan(m, 1);
  ThreadPool pool(1);
  assemble_corotated(m, plan, pool, st.u.data(), R1.data(), f_cached.data(), Kc.data(), &cache);
  assemble_corotated(m, plan, pool, st.u.data(), R2.data(), f_full.data(), Kfull.data());
  EXPECT_LT(test::rel_diff(f_cached, f_full), 1e-14);
  // And the cached K differs from the full one by at most the kept blocks' lag.
  EXPECT_GT(test::rel_diff(Kc, Kfull), 0.0);
  EXPECT_LT(test::rel_diff(Kc, Kfull), 0.2);
}

TEST(TangentReuse, TrajectoryConvergesToTheFullAssemblyAsThetaShrinks) {
  const int frames = 30;
  const std::vector<double> ref = run(0.0, frames);
  double prev = 1e300;
  for (double theta : {3e-2, 1e-2, 3e-3, 1e-3}) {
    int least = 0;
    const double err = test::rel_diff(run(theta, frames, &least), ref);
    std::printf("[ theta %.0e: rel. error %.3g after %d frames, fewest element updates in a frame %d ]\n", theta, err,
                frames, least);
    EXPECT_LT(err, prev * 1.5 + 1e-12) << theta;  // shrinking, allowing for non-monotone noise
    prev = std::min(prev, err);
  }
  EXPECT_LT(prev, 1e-3);
  int least = -1;
  run(0.0, 5, &least);
  EXPECT_EQ(least, build_model(beam_mesh(), swing(0.0)).nelem) << "off: every element every frame";
}

TEST(TangentReuse, NewModelStartsWithAFullAssembly) {
  Scene sc = swing(0.4);
  sc.rotation_tolerance = 0.0;  // one linearised solve per frame: one assembly
  const Model m = build_model(beam_mesh(), sc);
  State st; Workspace ws;
  init_state(m, st, ws);
  step(m, st, ws);
  EXPECT_EQ(ws.timing.tangent_updates, m.nelem);
  step(m, st, ws);
  EXPECT_LT(ws.timing.tangent_updates, m.nelem / 2) << "theta 0.4 keeps most elements' blocks";
  ASSERT_TRUE(ws.tangent_cache.valid);
  internal_forces(m, st, ws, st.u.data(), /*tangent=*/true);  // as a static solve assembles: K rebuilt whole
  EXPECT_FALSE(ws.tangent_cache.valid) << "K is no longer the sum of the kept blocks";
  step(m, st, ws);
  EXPECT_EQ(ws.timing.tangent_updates, m.nelem) << "so the next step assembles every element";
  size_workspace(m, ws);  // what a cut's rebuild does (carry_workspace_over_cut)
  EXPECT_FALSE(ws.tangent_cache.valid);
}

// The dynamic matrix is formed only when K changed (form_dynamic_matrix):
// after every step A is exactly what forming it from the step's last K gives,
// and the steps whose assemblies kept every element's blocks did not form it.
TEST(TangentReuse, TheDynamicMatrixIsFormedAgainOnlyWhenKChanged) {
  Scene sc = swing(0.4);
  const Model m = build_model(beam_mesh(), sc);
  State st; Workspace ws;
  init_state(m, st, ws);
  int skipped = 0;
  for (int k = 0; k < 70; ++k) {  // from about frame 45 on the beam is calm
    const std::uint64_t before = ws.K_generation;
    step(m, st, ws);
    if (ws.timing.tangent_updates == 0) {
      EXPECT_EQ(ws.K_generation, before) << "frame " << k << ": no block recomputed, K unchanged";
      ++skipped;
    }
    const std::vector<double> kept_A = ws.A;
    ws.A_generation = 0;  // form it anew from the same K
    form_dynamic_matrix(m, st, ws, ws.K.data());
    ASSERT_EQ(ws.A, kept_A) << "frame " << k;
  }
  EXPECT_GT(skipped, 5) << "theta 0.4 keeps every element in the calm frames";
}

// While (nearly) every element moves past theta the cache is bypassed: full
// assemblies that keep no blocks (K and forces exactly a plain full
// assembly's), noting F to see when a tenth of the elements would be kept
// again; then one filling assembly, and blocks are kept as before.
TEST(TangentReuse, BypassedWhileEveryElementMovesAndBackWhenStill) {
  const Model m = build_model(beam_mesh(), swing(1e-6));
  AssemblyPlan plan = make_assembly_plan(m, 1);
  ThreadPool pool(1);
  TangentCache cache;
  cache.theta = 1e-6;
  std::vector<double> u(m.ndof()), R = identity_rotations(m.nrot), Rfull, f(m.ndof()), ffull(m.ndof());
  std::vector<double> K(m.nnz()), Kfull(m.nnz());
  auto bend = [&](double amount) {  // every element's F changes with `amount`
    for (int n = 0; n < m.nnode; ++n) {
      const double x = m.X[3 * n];
      u[3 * n + 1] = amount * x * x;
      u[3 * n + 2] = -0.5 * amount * x * x * x;
    }
  };
  auto assemble = [&] {
    assemble_corotated(m, plan, pool, u.data(), R.data(), f.data(), K.data(), &cache);
    Rfull = R;
    assemble_corotated(m, plan, pool, u.data(), Rfull.data(), ffull.data(), Kfull.data());
  };
  bend(0.01);
  assemble();  // fills
  EXPECT_TRUE(cache.valid);
  EXPECT_FALSE(cache.bypass);
  bend(0.02);
  assemble();  // every element recomputed from kept blocks: bypass from the next call
  EXPECT_EQ(cache.updated, m.nelem);
  EXPECT_TRUE(cache.bypass);
  EXPECT_FALSE(cache.valid);
  bend(0.03);
  assemble();  // bypassed, still moving
  EXPECT_TRUE(cache.bypass);
  EXPECT_EQ(cache.would_keep, 0);
  EXPECT_EQ(cache.updated, m.nelem);
  EXPECT_LT(test::rel_diff(K, Kfull), 1e-14);
  EXPECT_LT(test::rel_diff(f, ffull), 1e-14);
  assemble();  // the same configuration: every element would have been kept
  EXPECT_EQ(cache.would_keep, m.nelem);
  EXPECT_FALSE(cache.bypass);
  EXPECT_LT(test::rel_diff(K, Kfull), 1e-14);
  assemble();  // fills again
  EXPECT_TRUE(cache.valid);
  EXPECT_EQ(cache.updated, m.nelem);
  assemble();  // kept: nothing recomputed, K still the full one
  EXPECT_EQ(cache.updated, 0);
  EXPECT_TRUE(cache.valid);
  EXPECT_LT(test::rel_diff(K, Kfull), 1e-12);
}

}  // namespace
}  // namespace incise
