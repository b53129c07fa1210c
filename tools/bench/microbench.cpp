// incise_microbench: Google Benchmark micro-benchmarks of the corotated
// assembly (not part of ctest). Per element: rotation extraction (warm-started
// polar), internal force, stiffness blocks and the scatter into the global
// pattern. Run: build/tools/incise_microbench [--benchmark_filter=...]
#include <cmath>
#include <vector>

#include <benchmark/benchmark.h>

#include "engine/assemble.h"
#include "engine/assemble_parallel.h"
#include "engine/mesh_tools.h"
#include "engine/model.h"

namespace {

using namespace incise;

struct Setup {
  Model m;
  std::vector<double> u, R, f, K;
  Setup(int order, RotationMode rot, int nx, int ny, int nz) {
    Scene s;
    s.path = "microbench";
    s.order = order;
    s.material.young = 1e5;
    s.material.poisson = 0.45;
    s.material.density = 1000;
    s.material.rotation = rot;
    m = build_model(make_beam(0.2, 0.05, 0.05, nx, ny, nz, 1), s);
    u.assign(m.ndof(), 0.0);
    for (int n = 0; n < m.nnode; ++n) {  // a bent and twisted state: rotations far from I
      const double x = m.X[3 * n], y = m.X[3 * n + 1], z = m.X[3 * n + 2];
      u[3 * n] = -2.0 * x * z;
      u[3 * n + 1] = 3.0 * x * z;
      u[3 * n + 2] = 4.0 * x * x - 3.0 * x * y;
    }
    R.assign(9 * m.nrot, 0.0);
    for (int r = 0; r < m.nrot; ++r) R[9 * r] = R[9 * r + 4] = R[9 * r + 8] = 1.0;
    f.assign(m.ndof(), 0.0);
    K.assign(m.nnz(), 0.0);
  }
};

// Fused kernel (engine/assemble_parallel.cpp) on `threads` workers; the
// rotations stay warm-started from the previous call, as between frames.
void BM_Fused(benchmark::State& state, int order, RotationMode rot, int threads, bool with_K) {
  Setup s(order, rot, 40, 10, 10);
  ThreadPool pool(threads);
  AssemblyPlan plan = make_assembly_plan(s.m, threads);
  assemble_corotated(s.m, plan, pool, s.u.data(), s.R.data(), s.f.data(), s.K.data());
  for (auto _ : state) {
    assemble_corotated(s.m, plan, pool, s.u.data(), s.R.data(), s.f.data(), with_K ? s.K.data() : nullptr);
    benchmark::DoNotOptimize(s.f.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * s.m.nelem);
  state.counters["us_per_elem"] = benchmark::Counter(
      static_cast<double>(s.m.nelem), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert,
      benchmark::Counter::OneK::kIs1000);
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
  state.counters["us_per_elem"] = benchmark::Counter(
      static_cast<double>(s.m.nelem), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert,
      benchmark::Counter::OneK::kIs1000);
  state.counters["elements"] = s.m.nelem;
}

}  // namespace

BENCHMARK_CAPTURE(BM_Reference, tet4, 1, RotationMode::PerPoint)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Reference, tet10, 2, RotationMode::PerPoint)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Fused, tet4_1thread, 1, RotationMode::PerPoint, 1, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet4_2threads, 1, RotationMode::PerPoint, 2, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet4_force_only_1thread, 1, RotationMode::PerPoint, 1, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet10_1thread, 2, RotationMode::PerPoint, 1, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet10_2threads, 2, RotationMode::PerPoint, 2, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet10SR_1thread, 2, RotationMode::Single, 1, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Fused, tet10_force_only_1thread, 2, RotationMode::PerPoint, 1, false)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
