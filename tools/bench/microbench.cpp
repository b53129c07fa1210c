// incise_microbench: Google Benchmark micro-benchmarks of the corotated
// assembly (not part of ctest). Per element: rotation extraction (warm-started
// polar), internal force, stiffness blocks and the scatter into the global
// pattern. Also the supernodal forward+back substitution with the double
// factor and with its float and binary16 copies (BM_Substitution), k columns
// at once against k single substitutions (BM_SubstitutionColumns), and one
// numeric factorization by CHOLMOD or in single precision (BM_Factorization).
// Run: build/tools/incise_microbench [--benchmark_filter=...]
#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>
#include <queue>
#include <vector>

#include <Eigen/Geometry>
#include <benchmark/benchmark.h>

#include "cutting/cut_apply.h"
#include "cutting/cut_surface.h"
#include "cutting/xfem_layout.h"
#include "engine/fem/assemble.h"
#include "engine/fem/assemble_parallel.h"
#include "engine/solve/cholmod_solver.h"
#include "engine/mesh/mesh_io.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/model/model.h"
#include "engine/fem/polar.h"
#include "engine/runtime/simulation.h"

namespace {

using namespace incise;

// The tissue of these benchmarks: tet10, nu 0.45, rho 1000, Young's modulus E.
Scene tissue_scene(double young) {
  Scene s;
  s.path = "microbench";
  s.order = 2;
  s.material.young = young;
  s.material.poisson = 0.45;
  s.material.density = 1000;
  return s;
}

// us_per_elem: wall time per element of one iteration (nelem elements).
void count_per_element(benchmark::State& state, int nelem) {
  state.counters["us_per_elem"] = benchmark::Counter(
      static_cast<double>(nelem), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert,
      benchmark::Counter::OneK::kIs1000);
}

struct Setup {
  Model m;
  std::vector<double> u, R, f, K;
  Setup(int order, RotationMode rot, int nx, int ny, int nz, bool consistent = false) {
    Scene s = tissue_scene(1e5);
    s.order = order;
    s.material.rotation = rot;
    s.consistent_tangent = consistent;
    m = build_model(make_beam(0.2, 0.05, 0.05, nx, ny, nz, 1), s);
    u.assign(m.ndof(), 0.0);
    for (int n = 0; n < m.nnode; ++n) {  // a bent and twisted state: rotations far from I
      const double x = m.X[3 * n], y = m.X[3 * n + 1], z = m.X[3 * n + 2];
      u[3 * n] = -2.0 * x * z;
      u[3 * n + 1] = 3.0 * x * z;
      u[3 * n + 2] = 4.0 * x * x - 3.0 * x * y;
    }
    R = identity_rotations(m.nrot);
    f.assign(m.ndof(), 0.0);
    K.assign(m.nnz(), 0.0);
  }
};

// Fused kernel (engine/fem/assemble_parallel.cpp) on `threads` workers; the
// rotations stay warm-started from the previous call, as between frames.
// `consistent`: integrator.tangent "consistent" (the rotation term).
void BM_Fused(benchmark::State& state, int order, RotationMode rot, int threads, bool with_K, bool consistent = false) {
  Setup s(order, rot, 40, 10, 10, consistent);
  ThreadPool pool(threads);
  AssemblyPlan plan = make_assembly_plan(s.m, threads);
  assemble_corotated(s.m, plan, pool, s.u.data(), s.R.data(), s.f.data(), s.K.data());
  for (auto _ : state) {
    assemble_corotated(s.m, plan, pool, s.u.data(), s.R.data(), s.f.data(), with_K ? s.K.data() : nullptr);
    benchmark::DoNotOptimize(s.f.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * s.m.nelem);
  count_per_element(state, s.m.nelem);
  state.counters["elements"] = s.m.nelem;
}

// The serial reference path (update_rotations + assemble_internal), for comparison.
void BM_Reference(benchmark::State& state, int order, RotationMode rot) {
  Setup s(order, rot, 40, 10, 10);
  update_rotations(s.m, s.u.data(), s.R.data());
  for (auto _ : state) {
    update_rotations(s.m, s.u.data(), s.R.data());
    assemble_internal(s.m, s.u.data(), s.R.data(), s.f.data(), s.K.data());
    benchmark::ClobberMemory();
  }
  count_per_element(state, s.m.nelem);
  state.counters["elements"] = s.m.nelem;
}

// One forward+back substitution (CholmodSolver::solve, or solve_copy with
// the float or binary16 copy of L) on the dynamic system matrix K0 + 4/dt^2 M of a tet10
// beam of nx x nyz x nyz cells (0.2 x 0.05 x 0.05 m, swing-beam material,
// clamped at x = 0), as the preconditioner of CG applies it (z = L^-T L^-1 r).
// GBps counts L's bytes read twice, 2 * nnz(L) * sizeof(value), as `incise
// bench` does (with sizeof = 8 for double, 4 for float, 2 for half); GBps_stored counts
// the supernodal blocks as stored (xsize >= nnz(L)).
// The dynamic system matrix K0 + 4/dt^2 M (projected) of a tet10 beam of nx x
// nyz x nyz cells (0.2 x 0.05 x 0.05 m, swing-beam material, clamped at x = 0).
Model dynamic_beam(int nx, int nyz, std::vector<double>& A) {
  Scene sc = tissue_scene(1e5);
  Region clamp;
  clamp.kind = Region::Kind::Box;
  clamp.lo = {-1e-9, -1, -1};
  clamp.hi = {1e-9, 1, 1};
  clamp.json_path = "fixed[0]";
  sc.fixed.push_back(clamp);
  Model m = build_model(make_beam(0.2, 0.05, 0.05, nx, nyz, nyz, 1), sc);
  const int n = m.ndof();
  A = m.K0_csc;
  for (int d = 0; d < n; ++d) A[m.diag[d]] += 4.0 / (m.dt * m.dt) * m.mass_lumped[d];
  for (int k : m.constrained_entries) A[k] = 0.0;
  for (int d = 0; d < n; ++d)
    if (m.constrained[d]) A[m.diag[d]] = 1.0;
  return m;
}

void BM_Substitution(benchmark::State& state, int nx, int nyz, FactorCopy copy, int threads = 1) {
  const bool single = copy != FactorCopy::None;
  std::vector<double> A;
  const Model m = dynamic_beam(nx, nyz, A);
  const int n = m.ndof();
  std::unique_ptr<SubstitutionWorker> worker;  // outlives f (CholmodSolver::set_substitution_worker)
  if (threads > 1) worker = std::make_unique<SubstitutionWorker>();
  CholmodSolver f;
  f.set_factor_copy(copy);
  f.set_substitution_worker(worker.get());
  f.analyze(n, m.Ap, m.Ai);
  f.factorize(A.data());  // the first conversion also allocates (page faults): not counted below
  const double first_factor_ms = f.stats().factor_ms_total, first_convert_ms = f.stats().copy_ms_total;
  for (int k = 0; k < 2; ++k) f.factorize(A.data());
  std::vector<double> b(n), x(n);
  for (int i = 0; i < n; ++i) b[i] = std::sin(0.37 * i);
  for (auto _ : state) {
    if (single)
      f.solve_copy(b.data(), x.data());
    else
      f.solve(b.data(), x.data());
    benchmark::DoNotOptimize(x.data());
    benchmark::ClobberMemory();
  }
  const double value_bytes = copy == FactorCopy::Half ? 2.0 : single ? 4.0 : 8.0;
  const FactorStats& st = f.stats();
  state.counters["dofs"] = n;
  state.counters["nnz_L"] = st.nnz_L;
  state.counters["GBps"] = benchmark::Counter(2.0 * value_bytes * st.nnz_L, benchmark::Counter::kIsIterationInvariantRate,
                                              benchmark::Counter::OneK::kIs1000);
  state.counters["GBps_stored"] = benchmark::Counter(2.0 * value_bytes * st.stored_L,
                                                     benchmark::Counter::kIsIterationInvariantRate,
                                                     benchmark::Counter::OneK::kIs1000);
  state.counters["factor_ms"] = (st.factor_ms_total - first_factor_ms) / 2;
  if (single) state.counters["convert_ms"] = (st.copy_ms_total - first_convert_ms) / 2;
  if (threads > 1) {
    state.counters["top_share"] = f.substitution_split().top_share;
    state.counters["balance"] = f.substitution_split().balance;
  }
}

// k right-hand sides through the float copy (the contact compliance's
// columns): one multi-column substitution (solve_copy_multi) or k single ones
// (solve_copy, one thread). per_column_ms: the time per column.
void BM_SubstitutionColumns(benchmark::State& state, int nx, int nyz, int k, bool multi) {
  std::vector<double> A;
  const Model m = dynamic_beam(nx, nyz, A);
  const int n = m.ndof();
  CholmodSolver f;
  f.set_factor_copy(FactorCopy::Float);
  f.analyze(n, m.Ap, m.Ai);
  f.factorize(A.data());
  std::vector<double> B(static_cast<size_t>(n) * k), X(B.size());
  for (size_t i = 0; i < B.size(); ++i) B[i] = std::sin(0.37 * static_cast<double>(i));
  f.solve_copy_multi(k, B.data(), X.data());  // first call allocates
  for (auto _ : state) {
    if (multi) f.solve_copy_multi(k, B.data(), X.data());
    else
      for (int c = 0; c < k; ++c) f.solve_copy(B.data() + static_cast<size_t>(c) * n, X.data() + static_cast<size_t>(c) * n);
    benchmark::DoNotOptimize(X.data());
    benchmark::ClobberMemory();
  }
  state.counters["dofs"] = n;
  state.counters["per_column_ms"] = benchmark::Counter(k / 1e3, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

// One numeric factorization of the dynamic beam system (see dynamic_beam):
// CHOLMOD in double plus the float copy the lagged policy substitutes with
// (`cholmod`), or the single-precision factorization straight into that copy
// (`single`, engine/solve/single_factor.h), both on CHOLMOD's METIS/AMD analysis.
// GFLOPs: CHOLMOD's flop count of the factorization per second.
void BM_Factorization(benchmark::State& state, int nx, int nyz, bool single) {
  std::vector<double> A;
  const Model m = dynamic_beam(nx, nyz, A);
  CholmodSolver f;
  f.set_factor_copy(FactorCopy::Float);
  f.set_single_factorization(single);
  f.analyze(m.ndof(), m.Ap, m.Ai);
  f.factorize(A.data());  // first call allocates
  for (auto _ : state) {
    f.factorize(A.data());
    benchmark::ClobberMemory();
  }
  state.counters["dofs"] = m.ndof();
  state.counters["nnz_L"] = f.stats().nnz_L;
  state.counters["GFLOPs"] = benchmark::Counter(f.stats().flops, benchmark::Counter::kIsIterationInvariantRate,
                                                benchmark::Counter::OneK::kIs1000);
  if (f.stats().single_fallbacks) state.SkipWithError("a float pivot was not positive");
}

// extract_rotation warm-started as between frames: F = Rt S with Rt turned
// from the warm start R0 by `angle` radians about a fixed axis and a 10%
// stretch S; a pool of 1024 such F (each call starts from its R0).
constexpr int kRotationPool = 1024;
struct RotationPool {
  std::vector<double> F, R0;  // (kRotationPool, 9) column-major each
};
RotationPool rotation_pool(double angle) {
  RotationPool p{std::vector<double>(9 * kRotationPool), std::vector<double>(9 * kRotationPool)};
  for (int k = 0; k < kRotationPool; ++k) {
    const Eigen::Vector3d axis =
        Eigen::Vector3d(std::sin(k), std::cos(1.3 * k), 0.5 + 0.1 * k / kRotationPool).normalized();
    Eigen::Map<Eigen::Matrix3d> Fk(&p.F[9 * k]), R0k(&p.R0[9 * k]);
    R0k = Eigen::AngleAxisd(0.3 + k * 0.002, Eigen::Vector3d(0.2, std::sin(0.7 * k), 1.0).normalized()).toRotationMatrix();
    Eigen::Matrix3d S;
    S << 1.1, 0.03, -0.02, 0.03, 0.95, 0.04, -0.02, 0.04, 1.02;
    Fk = Eigen::AngleAxisd(angle, axis).toRotationMatrix() * R0k * S;
  }
  return p;
}

void set_rotation_counters(benchmark::State& state) {
  state.SetItemsProcessed(state.iterations() * kRotationPool);
  state.counters["ns_per_call"] =
      benchmark::Counter(kRotationPool, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert,
                         benchmark::Counter::OneK::kIs1000);
}

void BM_ExtractRotation(benchmark::State& state, double angle) {
  const RotationPool pool = rotation_pool(angle);
  std::vector<Eigen::Matrix3d> F(kRotationPool), R0(kRotationPool), R(kRotationPool);
  for (int k = 0; k < kRotationPool; ++k) {
    F[k] = Eigen::Map<const Eigen::Matrix3d>(&pool.F[9 * k]);
    R0[k] = Eigen::Map<const Eigen::Matrix3d>(&pool.R0[9 * k]);
  }
  long iters = 0;
  for (auto _ : state) {
    for (int k = 0; k < kRotationPool; ++k) {
      R[k] = R0[k];
      iters += extract_rotation(F[k], R[k]);
    }
    benchmark::DoNotOptimize(R.data());
    benchmark::ClobberMemory();
  }
  set_rotation_counters(state);
  state.counters["newton_steps"] = static_cast<double>(iters) / (static_cast<double>(state.iterations()) * kRotationPool);
}

// The same pool, four at a time (extract_rotations: the lanes side by side,
// as the assembly gives it a tet10's four points).
void BM_ExtractRotations(benchmark::State& state, double angle) {
  const RotationPool pool = rotation_pool(angle);
  std::vector<double> R(9 * kRotationPool);
  for (auto _ : state) {
    R = pool.R0;
    for (int k = 0; k < kRotationPool; k += 4) extract_rotations(4, &pool.F[9 * k], &R[9 * k]);
    benchmark::DoNotOptimize(R.data());
    benchmark::ClobberMemory();
  }
  set_rotation_counters(state);
}

// The organ mesh of the real-time scenes (assets/meshes/organ_10k.msh, 1,832
// tet10, consistent tangent) as read, and with `renumber` its nodes in
// breadth-first order from the first node and its elements sorted by their
// smallest node: how much of the per-element cost is the scatter's cache misses.
// `cold`: 64 MB streamed through the caches before each assembly (untimed);
// `reuse`: integrator.tangent_reuse (0.4: every element keeps its blocks,
// the forces and rotations alone).
void BM_Organ(benchmark::State& state, bool renumber, bool cold = false, double reuse = 0.0, bool moving = false) {
  Mesh mesh = read_mesh(INCISE_SOURCE_DIR "/assets/meshes/organ_10k.msh");
  if (renumber) {
    const int nn = mesh.nnode(), npe = mesh.npe(), ne = mesh.ntet();
    std::vector<std::vector<int>> adj(nn);
    for (int e = 0; e < ne; ++e)
      for (int a = 0; a < npe; ++a)
        for (int b = 0; b < npe; ++b)
          if (a != b) adj[mesh.tet[npe * e + a]].push_back(mesh.tet[npe * e + b]);
    std::vector<int> order, seen(nn, 0);
    for (int s0 = 0; s0 < nn; ++s0) {
      if (seen[s0]) continue;
      std::queue<int> q;
      q.push(s0);
      seen[s0] = 1;
      while (!q.empty()) {
        const int v = q.front();
        q.pop();
        order.push_back(v);
        for (int w : adj[v])
          if (!seen[w]) seen[w] = 1, q.push(w);
      }
    }
    std::vector<int> inv(nn);
    for (int k = 0; k < nn; ++k) inv[order[k]] = k;
    Mesh out = mesh;
    for (int k = 0; k < nn; ++k)
      for (int d = 0; d < 3; ++d) out.X[3 * k + d] = mesh.X[3 * order[k] + d];
    std::vector<int> perm(ne);
    std::iota(perm.begin(), perm.end(), 0);
    auto key = [&](int e) {
      int lo = nn;
      for (int a = 0; a < npe; ++a) lo = std::min(lo, inv[mesh.tet[npe * e + a]]);
      return lo;
    };
    std::sort(perm.begin(), perm.end(), [&](int a, int b) { return key(a) < key(b); });
    for (int k = 0; k < ne; ++k)
      for (int a = 0; a < npe; ++a) out.tet[npe * k + a] = inv[mesh.tet[npe * perm[k] + a]];
    mesh = out;
  }
  Scene s = tissue_scene(3e4);
  s.material.rotation = RotationMode::PerPoint;
  s.consistent_tangent = true;
  Model m = build_model(mesh, s);
  std::vector<double> u(m.ndof(), 0.0), R = identity_rotations(m.nrot), f(m.ndof()), K(m.nnz());
  for (int n = 0; n < m.nnode; ++n) {  // a bent state, rotations far from I
    const double x = m.X[3 * n], y = m.X[3 * n + 1], z = m.X[3 * n + 2];
    u[3 * n] = -2.0 * x * z;
    u[3 * n + 1] = 3.0 * x * z;
    u[3 * n + 2] = 4.0 * x * x - 3.0 * x * y;
  }
  ThreadPool pool(1);
  AssemblyPlan plan = make_assembly_plan(m, 1);
  TangentCache cache;
  cache.theta = reuse;
  assemble_corotated(m, plan, pool, u.data(), R.data(), f.data(), K.data(), &cache);
  std::vector<double> evict(cold ? (64 << 20) / sizeof(double) : 0, 1.0);
  std::vector<double> u_moved = u;
  for (double& x : u_moved) x *= 1.001;
  bool flip = false;
  for (auto _ : state) {
    if (moving) flip = !flip;  // every slot's F moves by ~1e-3 (more than theta): all blocks recomputed
    if (cold) {  // as in a frame, where the solves have evicted the model and K from the caches
      state.PauseTiming();
      for (double& x : evict) x += 1.0;
      benchmark::DoNotOptimize(evict.data());
      state.ResumeTiming();
    }
    assemble_corotated(m, plan, pool, flip ? u_moved.data() : u.data(), R.data(), f.data(), K.data(), &cache);
    benchmark::ClobberMemory();
  }
  count_per_element(state, m.nelem);
}

// The cut-ahead helper's work in one incision frame (cutting/cut_apply.cpp,
// prepare_cut): the X-FEM layout of the swept cut one frame further, and the
// next Model built from the current one. assets/scenes/organ_incision.json
// (10k DOF) with the cut advanced to `t_mid` seconds; CPU time per frame the
// helper takes from the background factorization's core.
void BM_CutRebuild(benchmark::State& state, double t_mid) {
  auto sim = load_simulation(INCISE_SOURCE_DIR "/assets/scenes/organ_incision.json");
  const double dt = sim->model.dt;
  for (double t = dt; t <= t_mid + 1e-12; t += dt) update_cuts(*sim, t, t);
  const double t1 = t_mid + dt;
  double layout_ms = 0, model_ms = 0;
  for (auto _ : state) {
    std::vector<std::unique_ptr<CutSurface>> owned;
    std::vector<const CutSurface*> surfaces;
    for (const CutSpec& spec : sim->scene.cuts)
      if (auto s = make_cut_surface(spec, t1)) surfaces.push_back(s.get()), owned.push_back(std::move(s));
    Stopwatch clock;
    const CutLayout layout = compute_cut_layout(sim->model, surfaces, nullptr);
    layout_ms += clock.lap();
    const Model next = build_model(sim->mesh, sim->scene, &layout, &sim->model);
    model_ms += clock.lap();
    benchmark::DoNotOptimize(next.nnz());
  }
  state.counters["layout_ms"] = layout_ms / static_cast<double>(state.iterations());
  state.counters["model_ms"] = model_ms / static_cast<double>(state.iterations());
  state.counters["enriched_dof"] = sim->model.ndof() - 3 * sim->model.nnode;
}

// Assembly of the incision's Model with the cut advanced to 1.0 s (split
// elements assemble from their pieces' rest stiffness, Model::rot_K0), one
// worker, warm-started rotations: forces, rotations and the tangent
// (`with_K`), or forces and rotations alone. us_per_elem over all elements;
// split_elements counts the condensed ones.
void BM_CutAssembly(benchmark::State& state, bool with_K) {
  auto sim = load_simulation(INCISE_SOURCE_DIR "/assets/scenes/organ_incision.json");
  const double dt = sim->model.dt;
  for (double t = dt; t <= 1.0 + 1e-12; t += dt) update_cuts(*sim, t, t);
  const Model& m = sim->model;
  std::vector<double> u(m.ndof(), 0.0), R = identity_rotations(m.nrot), f(m.ndof()), K(m.nnz());
  for (int n = 0; n < m.ndofnode; ++n) {  // a bent state, rotations far from I; enriched DOFs move too
    const double x = m.X[3 * n], y = m.X[3 * n + 1], z = m.X[3 * n + 2];
    u[3 * n] = -2.0 * x * z + (n >= m.nnode ? 1e-3 : 0.0);
    u[3 * n + 1] = 3.0 * x * z;
    u[3 * n + 2] = 4.0 * x * x - 3.0 * x * y;
  }
  ThreadPool pool(1);
  AssemblyPlan plan = make_assembly_plan(m, 1);
  assemble_corotated(m, plan, pool, u.data(), R.data(), f.data(), with_K ? K.data() : nullptr);
  for (auto _ : state) {
    assemble_corotated(m, plan, pool, u.data(), R.data(), f.data(), with_K ? K.data() : nullptr);
    benchmark::ClobberMemory();
  }
  count_per_element(state, m.nelem);
  state.counters["split_elements"] = static_cast<double>(std::count(plan.elem_condensed.begin(), plan.elem_condensed.end(), 1));
  int enriched_whole = 0;  // whole elements with enriched DOF nodes (integrated point by point)
  for (int e = 0; e < m.nelem; ++e)
    enriched_whole += !plan.elem_condensed[e] && m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e] > m.mesh.npe();
  state.counters["enriched_whole"] = enriched_whole;
}

// One product with the symmetric upper-triangle matrix (sym_matvec_parallel
// on one worker, as CG does once per iteration): the incision's Model with
// the cut advanced to 1.0 s (10.7k DOF, enriched columns included), K0 as
// the matrix. `cold`: 64 MB streamed through the caches first (untimed), as
// after a frame's substitutions.
void BM_SymMatvec(benchmark::State& state, bool cold) {
  auto sim = load_simulation(INCISE_SOURCE_DIR "/assets/scenes/organ_incision.json");
  const double dt = sim->model.dt;
  for (double t = dt; t <= 1.0 + 1e-12; t += dt) update_cuts(*sim, t, t);
  const Model& m = sim->model;
  const std::vector<double> A = rest_stiffness(m);
  std::vector<double> x(m.ndof()), y(m.ndof());
  for (int d = 0; d < m.ndof(); ++d) x[d] = std::sin(0.37 * d);
  ThreadPool pool(1);
  AssemblyPlan plan = make_assembly_plan(m, 1);
  std::vector<double> evict(cold ? (64 << 20) / sizeof(double) : 0, 1.0);
  for (auto _ : state) {
    if (cold) {
      state.PauseTiming();
      for (double& v : evict) v += 1.0;
      benchmark::DoNotOptimize(evict.data());
      state.ResumeTiming();
    }
    sym_matvec_parallel(m, plan, pool, A.data(), x.data(), y.data());
    benchmark::ClobberMemory();
  }
  state.counters["nnz"] = m.nnz();
  state.counters["GB/s"] = benchmark::Counter(12.0 * m.nnz() * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
}

}  // namespace

BENCHMARK_CAPTURE(BM_Reference, tet4, 1, RotationMode::PerPoint)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CutAssembly, forces, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_CutAssembly, with_tangent, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_SymMatvec, warm, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_SymMatvec, cold, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Reference, tet10, 2, RotationMode::PerPoint)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Fused, tet4_1thread, 1, RotationMode::PerPoint, 1, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet4_2threads, 1, RotationMode::PerPoint, 2, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet4_force_only_1thread, 1, RotationMode::PerPoint, 1, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet10_1thread, 2, RotationMode::PerPoint, 1, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet4_consistent_1thread, 1, RotationMode::PerPoint, 1, true, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet10_consistent_1thread, 2, RotationMode::PerPoint, 1, true, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet10_2threads, 2, RotationMode::PerPoint, 2, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet10SR_1thread, 2, RotationMode::Single, 1, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet10_force_only_1thread, 2, RotationMode::PerPoint, 1, false)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_CAPTURE(BM_Organ, as_read, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Organ, renumbered, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Organ, cold_cache, false, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Organ, every_tangent_kept, false, true, 0.4)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Organ, moving_no_cache, false, true, 0.0, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Organ, moving_cache_all_recomputed, false, true, 1e-6, true)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_CAPTURE(BM_Substitution, beam10k_double, 20, 4, FactorCopy::None)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam10k_single, 20, 4, FactorCopy::Float)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam10k_half, 20, 4, FactorCopy::Half)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam20k_double, 28, 5, FactorCopy::None)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam20k_single, 28, 5, FactorCopy::Float)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam20k_half, 28, 5, FactorCopy::Half)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam10k_double_2threads, 20, 4, FactorCopy::None, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam10k_single_2threads, 20, 4, FactorCopy::Float, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam10k_half_2threads, 20, 4, FactorCopy::Half, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam20k_double_2threads, 28, 5, FactorCopy::None, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam20k_single_2threads, 28, 5, FactorCopy::Float, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Substitution, beam20k_half_2threads, 28, 5, FactorCopy::Half, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_SubstitutionColumns, beam20k_16_single, 28, 5, 16, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_SubstitutionColumns, beam20k_16_multi, 28, 5, 16, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_SubstitutionColumns, beam20k_4_single, 28, 5, 4, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_SubstitutionColumns, beam20k_4_multi, 28, 5, 4, true)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_CAPTURE(BM_Factorization, beam10k_cholmod, 20, 4, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Factorization, beam10k_single, 20, 4, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Factorization, beam20k_cholmod, 28, 5, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Factorization, beam20k_single, 28, 5, true)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_CAPTURE(BM_CutRebuild, incision_1s, 1.0)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_CAPTURE(BM_ExtractRotation, angle_1e-3, 1e-3);
BENCHMARK_CAPTURE(BM_ExtractRotation, angle_3e-2, 3e-2);
BENCHMARK_CAPTURE(BM_ExtractRotation, angle_0_5, 0.5);
BENCHMARK_CAPTURE(BM_ExtractRotations, angle_1e-3, 1e-3);
BENCHMARK_CAPTURE(BM_ExtractRotations, angle_3e-2, 3e-2);
BENCHMARK_CAPTURE(BM_ExtractRotations, angle_0_5, 0.5);

BENCHMARK_MAIN();
