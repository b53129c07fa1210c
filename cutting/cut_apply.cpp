#include "cutting/cut_apply.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <memory>
#include <thread>

#include "engine/util/headroom.h"
#include "engine/solve/linear_solve.h"
#include "engine/output/probe.h"
#include "engine/dynamics/step.h"
#include "engine/runtime/thread_affinity.h"
#include "engine/runtime/timing.h"

namespace incise {

namespace {

// Whether element e of m lists enriched DOF nodes besides its mesh nodes.
bool enriched(const Model& m, int e) { return m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e] > m.mesh.npe(); }

// Old model's effective value (u, v or a) of node a of element e, in its
// piece P (piece_containing of a point of the new piece; -1: e was whole).
void old_piece_values(const Model& m, const Kinematics& s, int e, int P, int a, double out[9]) {
  const int npe = m.mesh.npe();
  const int i = m.mesh.tet[static_cast<size_t>(e) * npe + a];
  const int q = P >= 0 ? m.cuts.piece_enr[static_cast<size_t>(P) * npe + a] : -1;
  const std::vector<double>* f[3] = {&s.u, &s.v, &s.a};
  for (int k = 0; k < 3; ++k)
    for (int c = 0; c < 3; ++c) out[3 * k + c] = (*f[k])[3 * i + c] + (q >= 0 ? (*f[k])[3 * q + c] : 0.0);
}

// First rotation slot of each element (nelem + 1): slots are numbered element by element.
std::vector<int> slot_ptr(const Model& m) {
  std::vector<int> ptr(m.nelem + 1, 0);
  for (int r = 0; r < m.nrot; ++r) ++ptr[m.rot_elem[r] + 1];
  for (int e = 0; e < m.nelem; ++e) ptr[e + 1] += ptr[e];
  return ptr;
}

// Warm starts for the new model's rotation slots: an element with as many
// slots as before keeps its old rotations (uncut elements, and cut ones whose
// pieces did not change), the others start from the identity. Saves the polar
// iterations of a cold start in the rebuild's force evaluation and the next step.
std::vector<double> carried_rotations(const Model& from, const std::vector<double>& R_from, const Model& to) {
  const std::vector<int> old_ptr = slot_ptr(from), new_ptr = slot_ptr(to);
  std::vector<double> R(9 * static_cast<size_t>(to.nrot), 0.0);
  for (int r = 0; r < to.nrot; ++r) R[9 * r] = R[9 * r + 4] = R[9 * r + 8] = 1.0;
  // Slot k of e is ptr[e] + k (model_build.cpp numbers them element by element).
  for (int e = 0; e < to.nelem && e < from.nelem; ++e) {
    const int n_old = old_ptr[e + 1] - old_ptr[e], n_new = new_ptr[e + 1] - new_ptr[e];
    if (n_old != n_new) continue;
    std::copy(R_from.begin() + 9 * static_cast<size_t>(old_ptr[e]), R_from.begin() + 9 * static_cast<size_t>(old_ptr[e + 1]),
              R.begin() + 9 * static_cast<size_t>(new_ptr[e]));
  }
  return R;
}

// integrator.tangent_reuse across a rebuild: an element whose pieces did not
// change keeps its tangent blocks (same DOF nodes in the same order, same
// slots) and the gradients they were made at, and K of the new pattern is
// their sum. The others get NaN gradients, so their first assembly
// recomputes them (K += blocks - 0). Without this every cut frame assembled
// all elements.
// K is not re-summed from the blocks (3.5 ms at 10k DOF, the scatter's cache
// misses): the mesh nodes' columns of the pattern are the old model's
// (build_pattern_from_base), so they start as the old K (old_K, the sum of
// the old blocks) less the old blocks of the elements that changed; the
// enriched columns, renumbered, get the carried blocks that fall in them.
// Skipped (a full assembly follows) when the last assembly that had kept
// blocks recomputed more than half of the elements: the body moves more than
// theta per frame and little would be kept. (Not the last assembly: after a
// skipped carry it recomputes all.) Every fifth cut in a row carries anyway,
// so the next assembly measures the motion again.
// The blocks stay in their array (see in_place below), the slots' F go to
// the previous cut's spare buffer, and K keeps its buffer: 10k incision,
// 10 MB of copies per cut frame -> 0.5 MB.
// A cut that carries no blocks still hands the old cache's arrays on (valid
// stays false: the next assembly fills them), so the filling assembly reuses
// their pages instead of faulting in 7 MB of new ones (10k incision).
void keep_buffers(TangentCache& old, TangentCache& c, bool with_F) {
  c.Kl = std::move(old.Kl);
  c.spare_Kl = std::move(old.spare_Kl);
  if (with_F) {
    c.F = std::move(old.F);
    c.F.clear();  // the old model's slots: an assembly sizes it anew (capacity kept)
    c.spare_F = std::move(old.spare_F);
  } else {
    c.spare_F = std::move(old.F);
  }
}

void carry_tangent_cache(const Model& from, TangentCache& old, std::vector<double>& old_K, const Model& to,
                         const std::vector<int>& changed, State& s) {
  s.tangent_cache.last_partial = old.last_partial;
  s.tangent_cache.bypass = old.bypass;  // still moving: the new model's assemblies keep no blocks either
  if (old.bypass && old.F.size() == 9 * static_cast<size_t>(from.nrot) && from.nelem == to.nelem) {
    // The bypass's F of the slots the cut left alone, so the next assembly
    // can tell whether the body calmed (during an incision every frame is a
    // cut frame: without them the bypass would never end).
    std::vector<char> fresh(to.nelem, 0);
    for (int e : changed) fresh[e] = 1;
    const std::vector<int> old_ptr = slot_ptr(from), new_ptr = slot_ptr(to);
    std::vector<double>& F = s.tangent_cache.F;
    F = std::move(old.spare_F);
    assign_with_headroom(F, 9 * static_cast<size_t>(to.nrot), std::nan(""));
    for (int e = 0; e < to.nelem; ++e)
      if (!fresh[e] && new_ptr[e + 1] - new_ptr[e] == old_ptr[e + 1] - old_ptr[e])
        std::copy(old.F.begin() + 9 * static_cast<size_t>(old_ptr[e]),
                  old.F.begin() + 9 * static_cast<size_t>(old_ptr[e + 1]), F.begin() + 9 * static_cast<size_t>(new_ptr[e]));
    keep_buffers(old, s.tangent_cache, /*with_F=*/false);
    return;
  }
  if (!old.valid || !(to.tangent_reuse > 0.0) || old.kl_ptr.size() != static_cast<size_t>(from.nelem)) {
    keep_buffers(old, s.tangent_cache, /*with_F=*/true);
    return;
  }
  if ((old.last_partial < 0 || 2 * old.last_partial > from.nelem) && old.skipped_carries < 4) {
    s.tangent_cache.skipped_carries = old.skipped_carries + 1;
    keep_buffers(old, s.tangent_cache, /*with_F=*/true);
    return;
  }
  std::vector<char> fresh(to.nelem, 0);
  for (int e : changed) fresh[e] = 1;
  const std::vector<int> old_ptr = slot_ptr(from), new_ptr = slot_ptr(to);
  const auto old_blocks = [&](int e) { return from.elem_scatter_ptr[e + 1] - from.elem_scatter_ptr[e]; };
  const auto new_blocks = [&](int e) { return to.elem_scatter_ptr[e + 1] - to.elem_scatter_ptr[e]; };
  const auto kept_elem = [&](int e) {
    return e < from.nelem && !fresh[e] && new_blocks(e) == old_blocks(e) &&
           new_ptr[e + 1] - new_ptr[e] == old_ptr[e + 1] - old_ptr[e];
  };
  // In place: an element the cut left alone keeps its blocks where they are
  // (TangentCache::kl_ptr), one it changed reuses its old range when that is
  // large enough and otherwise gets a new one at the end, so nothing is read
  // after something else landed on it. Once the unused ranges would pass
  // half of the used ones, the blocks are compacted into the spare buffer in
  // the new model's order (10k incision: a 7 MB copy every cut frame before).
  // The slots' F (0.5 MB) go to the spare buffer: a cut may renumber slots
  // either way.
  size_t appended = 0, freed = 0;
  bool in_place = from.nelem == to.nelem && old.kl_ptr.size() == static_cast<size_t>(from.nelem);
  for (int e = 0; e < to.nelem && in_place; ++e)
    if (!kept_elem(e) && new_blocks(e) > old_blocks(e)) {
      appended += new_blocks(e);
      freed += old_blocks(e);
    }
  in_place = in_place && 2 * (old.kl_garbage + freed) <= to.elem_scatter.size() &&
             old.Kl.size() + appended <= old.Kl.capacity();  // (a reallocation would copy it all)
  TangentCache& c = s.tangent_cache;
  const size_t old_size = old.Kl.size();
  if (in_place) {
    c.Kl = std::move(old.Kl);
    c.kl_ptr = std::move(old.kl_ptr);
    c.kl_garbage = old.kl_garbage;
    c.spare_Kl = std::move(old.spare_Kl);
    c.Kl.resize(old_size + appended);
  } else {
    c.Kl = std::move(old.spare_Kl);
    const size_t live = to.elem_scatter.size();
    if (c.Kl.capacity() < live + live / 2) c.Kl.reserve(live + live / 2);  // room for the next cuts' grown elements
    c.Kl.resize(live);
    c.kl_ptr.assign(to.elem_scatter_ptr.begin(), to.elem_scatter_ptr.end() - 1);
    c.kl_garbage = 0;
  }
  c.F = std::move(old.spare_F);
  resize_with_headroom(c.F, 9 * static_cast<size_t>(to.nrot));
  const double* src_Kl = in_place ? c.Kl.data() : old.Kl.data();
  // The mesh nodes' columns: positions [0, split) the same in both patterns,
  // so K keeps old_K's buffer (swapped in: no 3 MB copy).
  const int cstd = 3 * to.nnode;
  const bool same_std = from.nnode == to.nnode && from.nelem == to.nelem && old_K.size() == static_cast<size_t>(from.Ap.back()) &&
                        from.Ap.size() > static_cast<size_t>(cstd) && to.Ap.size() > static_cast<size_t>(cstd) &&
                        std::equal(from.Ap.begin(), from.Ap.begin() + cstd + 1, to.Ap.begin());
  const int split = same_std ? to.Ap[cstd] : 0;
  if (same_std) {
    s.K.swap(old_K);  // old_K now holds the other buffer (the caller's next spare)
    resize_with_headroom(s.K, static_cast<size_t>(to.nnz()));
  }
  std::fill(s.K.begin() + split, s.K.end(), 0.0);  // the enriched columns: summed below
  size_t end = old_size;  // next free position at the end of Kl (in place)
  for (int e = 0; e < to.nelem; ++e) {
    const int nb = new_blocks(e), ns = new_ptr[e + 1] - new_ptr[e];
    const int src = e < from.nelem ? (in_place ? c.kl_ptr[e] : old.kl_ptr[e]) : 0;
    if (!kept_elem(e)) {  // recomputed at the next assembly
      if (split > 0 && e < from.nelem) {  // its old blocks leave the kept columns
        const int* sc = &from.elem_scatter[from.elem_scatter_ptr[e]];
        const double* kl = src_Kl + src;
        for (int k = 0; k < old_blocks(e); ++k)
          if (sc[k] >= 0 && sc[k] < split) s.K[sc[k]] -= kl[k];
      }
      if (in_place) {
        if (nb > old_blocks(e)) {
          c.kl_ptr[e] = static_cast<int>(end);
          end += nb;
          c.kl_garbage += old_blocks(e);
        } else {
          c.kl_garbage += old_blocks(e) - nb;
        }
      }
      std::fill_n(c.Kl.begin() + c.kl_ptr[e], nb, 0.0);
      std::fill_n(c.F.begin() + 9 * static_cast<size_t>(new_ptr[e]), 9 * ns, std::nan(""));
      continue;
    }
    double* kl = c.Kl.data() + c.kl_ptr[e];
    if (!in_place) std::copy_n(src_Kl + src, nb, kl);
    std::copy_n(old.F.data() + 9 * static_cast<size_t>(old_ptr[e]), 9 * ns, c.F.data() + 9 * static_cast<size_t>(new_ptr[e]));
    if (split > 0 && to.elem_dof_ptr[e + 1] - to.elem_dof_ptr[e] == to.mesh.npe()) continue;  // all in kept columns
    const int* sc = &to.elem_scatter[to.elem_scatter_ptr[e]];
    for (int k = 0; k < nb; ++k)
      if (sc[k] >= split) s.K[sc[k]] += kl[k];
  }
  c.valid = true;
  if (!in_place) c.spare_Kl = std::move(old.Kl);
  c.spare_F = std::move(old.F);
}

bool same_layout(const Model& m, const CutLayout& L) {
  const CutLayout& O = m.cuts;
  return m.has_cuts() && O.n_enriched == L.n_enriched && O.elem_piece_ptr == L.elem_piece_ptr &&
         O.piece_enr == L.piece_enr && O.subtet_rst == L.subtet_rst && O.elem_face_cut == L.elem_face_cut;
}

// The part of a cut update that reads only the model, mesh and scene (so it
// may run on a helper thread while the current frame steps): the layout of
// the cut surfaces at t_sweep and the next Model built from it.
struct PreparedCut {
  std::vector<double> progress;  // (scene.cuts) what the update applies
  double t_sweep = 0.0;
  int base_version = -1;         // Simulation::model_version it was prepared from
  bool rebuild = false;          // the layout changed: `next` holds the new model
  CutReport report;
  std::unique_ptr<Model> next;
  std::vector<int> changed;      // elements of `next` whose pieces changed
  std::vector<int> map;          // dofnode_map(base, next)
  AssemblyPlan plan;             // make_assembly_plan(next): off the stepping thread when prepared ahead
  double layout_ms = 0.0, model_ms = 0.0;
};

PreparedCut prepare_cut(const Simulation& sim, const std::vector<double>& progress, double t_sweep) {
  PreparedCut p;
  p.progress = progress;
  p.t_sweep = t_sweep;
  p.base_version = sim.model_version;
  std::vector<std::unique_ptr<CutSurface>> owned;
  std::vector<const CutSurface*> surfaces;
  for (size_t k = 0; k < sim.scene.cuts.size(); ++k) {
    if (progress[k] <= 0.0) continue;
    auto s = make_cut_surface(sim.scene.cuts[k], t_sweep);
    if (!s) continue;
    surfaces.push_back(s.get());
    owned.push_back(std::move(s));
  }
  if (surfaces.empty()) return p;
  Stopwatch part;
  CutLayout layout = compute_cut_layout(sim.model, surfaces, &p.report);
  p.layout_ms = part.lap();
  if (same_layout(sim.model, layout) || (!sim.model.has_cuts() && layout.n_enriched == 0 && p.report.cut_elements == 0))
    return p;
  p.next = std::make_unique<Model>(build_model(sim.mesh, sim.scene, &layout, &sim.model));
  for (int e = 0; e < p.next->nelem; ++e)
    if (!same_element_pieces(*p.next, sim.model, e)) p.changed.push_back(e);
  p.map = dofnode_map(sim.model, *p.next);
  p.plan = make_assembly_plan(*p.next, std::max(1, p.next->solver.threads));
  p.rebuild = true;
  p.model_ms = part.lap();
  return p;
}

// Applies a prepared update: the new model, the kinematics and rotations
// carried over, the solver set up for the new pattern, the acceleration.
CutUpdate commit_cut(Simulation& sim, PreparedCut p, Stopwatch& clock) {
  CutUpdate up;
  up.report = p.report;
  up.part_ms[kCutLayout] = p.layout_ms;
  up.part_ms[kCutModel] = p.model_ms;
  sim.cut_progress = p.progress;
  if (!p.rebuild) {
    up.ms = clock.ms();
    return up;
  }
  Stopwatch part;
  Model& next = *p.next;
  Kinematics k = transfer_kinematics(sim.model, {sim.state.u, sim.state.v, sim.state.a}, next);
  const double time = sim.state.time;
  const int frame = sim.state.frame, refactorizations = sim.state.refactorizations;
  const bool carry = solver_carries_over_cuts(next, sim.state);
  std::vector<double> R = carried_rotations(sim.model, sim.state.R, next);
  TangentCache kept = std::move(sim.state.tangent_cache);
  std::vector<double> old_K = std::move(sim.state.K);  // the sum of kept's blocks; its buffer is the next spare
  sim.state.K = std::move(kept.spare_K);
  std::unique_ptr<Model> old_model = std::make_unique<Model>(std::move(sim.model));
  sim.model = std::move(next);
  ++sim.model_version;
  up.part_ms[kCutTransfer] = part.lap();
  if (carry) {  // the lagged factors stay; the new pattern is analyzed off this frame
    size_state(sim.model, sim.state, /*zero=*/false);  // u, v, a, R set below; K by the carry or the next assembly
    prepare_solver(sim.model, sim.state, &p.map, &p.plan);
  } else {
    init_state(sim.model, sim.state, /*consistent_a0=*/false);  // new pattern: symbolic analysis
  }
  carry_tangent_cache(*old_model, kept, old_K, sim.model, p.changed, sim.state);
  sim.retired_model = std::move(old_model);  // freed by the next cut-ahead task, off this thread
  sim.state.tangent_cache.spare_K = std::move(old_K);
  sim.state.R.swap(R);
  sim.state.u.swap(k.u);
  sim.state.v.swap(k.v);
  sim.state.a.swap(k.a);
  sim.state.time = time;
  sim.state.frame = frame;
  up.part_ms[kCutSolverSetup] = part.lap();
  consistent_acceleration_near(sim.model, sim.state, p.changed);
  up.part_ms[kCutAcceleration] = part.lap();
  sim.state.refactorizations = refactorizations;
  up.changed = true;
  up.ms = clock.ms();
  return up;
}

// The next frame's cut update, prepared on a helper thread during this
// frame's step (Simulation::cut_ahead).
struct CutAhead {
  PreparedCut result;
  std::exception_ptr error;
  std::vector<double> progress;
  double t_sweep = 0.0;
  int base_version = -1;
};

// Progress of every cut for a frame at time t whose swept cuts reach t_sweep;
// *changed when it differs from sim.cut_progress.
std::vector<double> progress_at(const Simulation& sim, double t, double t_sweep, bool* changed) {
  std::vector<double> progress = sim.cut_progress;
  *changed = false;
  for (size_t k = 0; k < sim.scene.cuts.size(); ++k) {
    const CutSpec& c = sim.scene.cuts[k];
    double p = -1.0;
    if (c.at_time <= t) {
      p = 1.0;
      if (c.type == CutSpec::Type::Swept && c.duration > 0)
        p = std::clamp((t_sweep - c.at_time) / c.duration, 0.0, 1.0);
    }
    if (p != progress[k]) {
      progress[k] = p;
      *changed = true;
    }
  }
  return progress;
}

// Waits for a helper still running and takes its result when it was prepared
// for exactly this update; otherwise drops it.
bool take_ahead(Simulation& sim, const std::vector<double>& progress, double t_sweep, PreparedCut* out) {
  auto ahead = std::static_pointer_cast<CutAhead>(sim.cut_ahead);
  if (!ahead) return false;
  sim.cut_ahead.reset();
  sim.cut_helper->wait();
  if (ahead->error) std::rethrow_exception(ahead->error);
  if (ahead->base_version != sim.model_version || ahead->progress != progress || ahead->t_sweep != t_sweep) return false;
  *out = std::move(ahead->result);
  return true;
}

}  // namespace

void start_cut_ahead(Simulation& sim, double t, double t_sweep) {
  PreparedCut dropped;
  take_ahead(sim, {}, 0.0, &dropped);  // at most one helper
  bool changed = false;
  std::vector<double> progress = progress_at(sim, t, t_sweep, &changed);
  if (!changed) return;
  auto ahead = std::make_shared<CutAhead>();
  ahead->progress = progress;
  ahead->t_sweep = t_sweep;
  ahead->base_version = sim.model_version;
  CutAhead* a = ahead.get();
  const Simulation* s = &sim;
  const bool helper_cpus = sim.model.solver.split_affinity;
  if (!sim.cut_helper || sim.cut_helper->helper_cpus() != helper_cpus)
    sim.cut_helper = std::make_unique<HelperThread>(helper_cpus, HelperThread::Priority::Normal);  // (none running)
  std::shared_ptr<Model> retired = std::move(sim.retired_model);
  sim.cut_helper->run([ahead, a, s, retired]() mutable {  // (ahead: the task keeps its result alive)
    retired.reset();  // the model the last cut replaced (0.2-0.4 ms of frees)
    try {
      a->result = prepare_cut(*s, a->progress, a->t_sweep);
    } catch (...) {
      a->error = std::current_exception();
    }
  });
  sim.cut_ahead = ahead;
}


std::vector<int> dofnode_map(const Model& from, const Model& to) {
  std::vector<int> map(to.ndofnode, -1);
  for (int i = 0; i < to.nnode; ++i) map[i] = i;
  if (!to.has_cuts()) return map;
  const CutLayout& L = to.cuts;
  const int npe = to.mesh.npe();
  for (int e = 0; e < to.nelem; ++e) {
    if (!enriched(to, e)) continue;  // only mesh nodes: mapped to themselves above
    for (int P = L.elem_piece_ptr[e]; P < L.elem_piece_ptr[e + 1]; ++P) {
      const double* v = &L.subtet_rst[12 * static_cast<size_t>(L.piece_subtet_ptr[P])];
      const double rst[3] = {0.25 * (v[0] + v[3] + v[6] + v[9]), 0.25 * (v[1] + v[4] + v[7] + v[10]),
                             0.25 * (v[2] + v[5] + v[8] + v[11])};
      const int Q = from.has_cuts() ? piece_containing(from, e, rst) : -1;
      for (int a = 0; a < npe; ++a) {
        const int q = L.piece_enr[static_cast<size_t>(P) * npe + a];
        if (q < 0 || map[q] >= 0) continue;
        const int oq = Q >= 0 ? from.cuts.piece_enr[static_cast<size_t>(Q) * npe + a] : -1;
        if (oq >= 0) map[q] = oq;
      }
    }
  }
  return map;
}

Kinematics transfer_kinematics(const Model& from, const Kinematics& os, const Model& to) {
  Kinematics ns;
  const int n = to.ndof(), nstd = 3 * to.nnode, npe = to.mesh.npe();
  ns.u.assign(os.u.begin(), os.u.begin() + nstd);
  ns.v.assign(os.v.begin(), os.v.begin() + nstd);
  ns.a.assign(os.a.begin(), os.a.begin() + nstd);
  for (auto* f : {&ns.u, &ns.v, &ns.a}) f->resize(n, 0.0);
  if (!to.has_cuts()) return ns;
  const CutLayout& L = to.cuts;
  std::vector<int> old_piece(L.elem_piece_ptr.back(), -2);  // (pieces of `to`) -2: not looked up yet
  // Two passes: home values (standard DOFs) first, then enriched = old - home.
  // An element without enrichment in either model has the old nodal values,
  // copied above: only the elements near the cuts are visited.
  for (int pass = 0; pass < 2; ++pass)
    for (int e = 0; e < to.nelem; ++e) {
      if (!enriched(to, e) && !enriched(from, e)) continue;
      for (int P = L.elem_piece_ptr[e]; P < L.elem_piece_ptr[e + 1]; ++P) {
        // a point inside the piece: the centroid of its first sub-tetrahedron
        const double* v = &L.subtet_rst[12 * static_cast<size_t>(L.piece_subtet_ptr[P])];
        const double rst[3] = {0.25 * (v[0] + v[3] + v[6] + v[9]), 0.25 * (v[1] + v[4] + v[7] + v[10]),
                               0.25 * (v[2] + v[5] + v[8] + v[11])};
        // The old piece holding it, once per piece for both passes (a point
        // location over the old sub-tetrahedra; looked up per node and pass
        // it took 1.8 ms of a 10k incision's cut frame).
        if (old_piece[P] == -2) old_piece[P] = piece_containing(from, e, rst);
        const int Q = old_piece[P];
        for (int a = 0; a < npe; ++a) {
          const int q = L.piece_enr[static_cast<size_t>(P) * npe + a];
          if ((pass == 0) != (q < 0)) continue;
          double val[9];
          old_piece_values(from, os, e, Q, a, val);
          const int i = to.mesh.tet[static_cast<size_t>(e) * npe + a];
          std::vector<double>* f[3] = {&ns.u, &ns.v, &ns.a};
          for (int k = 0; k < 3; ++k)
            for (int c = 0; c < 3; ++c) {
              if (q < 0) (*f[k])[3 * i + c] = val[3 * k + c];
              else (*f[k])[3 * q + c] = val[3 * k + c] - (*f[k])[3 * i + c];
            }
        }
      }
    }
  return ns;
}

CutUpdate update_cuts(Simulation& sim, double t, double t_sweep) {
  Stopwatch clock;
  bool changed = false;
  const std::vector<double> progress = progress_at(sim, t, t_sweep, &changed);
  PreparedCut p;
  const bool ahead = take_ahead(sim, progress, t_sweep, &p);
  if (!changed) return {};
  if (!ahead) p = prepare_cut(sim, progress, t_sweep);
  CutUpdate up = commit_cut(sim, std::move(p), clock);
  up.ahead = ahead;
  return up;
}

CutUpdate apply_all_cuts(Simulation& sim) {
  std::vector<double> progress(sim.scene.cuts.size(), 1.0);
  double t_end = 0.0;
  for (const CutSpec& c : sim.scene.cuts) t_end = std::max(t_end, c.at_time + c.duration);
  PreparedCut dropped;
  take_ahead(sim, {}, 0.0, &dropped);
  Stopwatch clock;
  return commit_cut(sim, prepare_cut(sim, progress, t_end), clock);
}

}  // namespace incise
