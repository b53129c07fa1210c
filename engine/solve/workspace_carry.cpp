#include "engine/solve/workspace_carry.h"

#include <algorithm>
#include <cmath>

#include "engine/solve/linear_solve.h"
#include "engine/util/headroom.h"

namespace incise {

namespace {

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
// The blocks stay in their array (place_blocks), the slots' F go to
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

// Which elements keep their blocks across the cut: those it left alone with
// the same blocks and slots.
struct KeptElements {
  const Model& from;
  const Model& to;
  std::vector<char> fresh;         // (to.nelem) the cut changed it
  std::vector<int> old_ptr, new_ptr;  // element_slot_ptr of each model
  KeptElements(const Model& f, const Model& t, const std::vector<int>& changed)
      : from(f), to(t), fresh(t.nelem, 0), old_ptr(element_slot_ptr(f)), new_ptr(element_slot_ptr(t)) {
    for (int e : changed) fresh[e] = 1;
  }
  int old_blocks(int e) const { return from.elem_scatter_ptr[e + 1] - from.elem_scatter_ptr[e]; }
  int new_blocks(int e) const { return to.elem_scatter_ptr[e + 1] - to.elem_scatter_ptr[e]; }
  int old_slots(int e) const { return old_ptr[e + 1] - old_ptr[e]; }
  int new_slots(int e) const { return new_ptr[e + 1] - new_ptr[e]; }
  bool kept(int e) const {
    return e < from.nelem && !fresh[e] && new_blocks(e) == old_blocks(e) && new_slots(e) == old_slots(e);
  }
};

// The bypass's F of the slots the cut left alone, so the next assembly can
// tell whether the body calmed (during an incision every frame is a cut
// frame: without them the bypass would never end).
void carry_bypass(const KeptElements& k, TangentCache& old, TangentCache& c) {
  std::vector<double>& F = c.F;
  F = std::move(old.spare_F);
  assign_with_headroom(F, 9 * static_cast<size_t>(k.to.nrot), std::nan(""));
  for (int e = 0; e < k.to.nelem; ++e)
    if (!k.fresh[e] && k.new_slots(e) == k.old_slots(e))
      std::copy(old.F.begin() + 9 * static_cast<size_t>(k.old_ptr[e]), old.F.begin() + 9 * static_cast<size_t>(k.old_ptr[e + 1]),
                F.begin() + 9 * static_cast<size_t>(k.new_ptr[e]));
  keep_buffers(old, c, /*with_F=*/false);
}

// Where the carried blocks go. In place: an element the cut left alone keeps
// its blocks where they are (TangentCache::kl_ptr), one it changed reuses
// its old range when that is large enough and otherwise gets a new one at
// the end, so nothing is read after something else landed on it. Once the
// unused ranges would pass half of the used ones, the blocks are compacted
// into the spare buffer in the new model's order (10k incision: a 7 MB copy
// every cut frame before). The slots' F (0.5 MB) go to the spare buffer: a
// cut may renumber slots either way. Returns whether in place.
bool place_blocks(const KeptElements& k, TangentCache& old, TangentCache& c) {
  const Model& to = k.to;
  size_t appended = 0, freed = 0;
  bool in_place = k.from.nelem == to.nelem && old.kl_ptr.size() == static_cast<size_t>(k.from.nelem);
  for (int e = 0; e < to.nelem && in_place; ++e)
    if (!k.kept(e) && k.new_blocks(e) > k.old_blocks(e)) {
      appended += k.new_blocks(e);
      freed += k.old_blocks(e);
    }
  in_place = in_place && 2 * (old.kl_garbage + freed) <= to.elem_scatter.size() &&
             old.Kl.size() + appended <= old.Kl.capacity();  // (a reallocation would copy it all)
  if (in_place) {
    const size_t old_size = old.Kl.size();
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
  return in_place;
}

// The mesh nodes' columns: positions [0, split) the same in both patterns,
// so K keeps old_K's buffer (swapped in: no 3 MB copy). Returns split (0:
// the patterns differ there, K is summed anew). The enriched columns are zeroed.
int keep_mesh_columns(const Model& from, const Model& to, std::vector<double>& old_K, std::vector<double>& K) {
  const int cstd = 3 * to.nnode;
  const bool same_std = from.nnode == to.nnode && from.nelem == to.nelem && old_K.size() == static_cast<size_t>(from.Ap.back()) &&
                        from.Ap.size() > static_cast<size_t>(cstd) && to.Ap.size() > static_cast<size_t>(cstd) &&
                        std::equal(from.Ap.begin(), from.Ap.begin() + cstd + 1, to.Ap.begin());
  const int split = same_std ? to.Ap[cstd] : 0;
  if (same_std) {
    K.swap(old_K);  // old_K now holds the other buffer (the caller's next spare)
    resize_with_headroom(K, static_cast<size_t>(to.nnz()));
  }
  std::fill(K.begin() + split, K.end(), 0.0);  // the enriched columns: summed by carry_blocks
  return split;
}

// Per element: a kept one's blocks and F stay (copied when not in place) and
// its blocks in enriched columns are summed into K; a changed one's old
// blocks leave K's kept columns, its new range is zeroed and its F set to
// NaN, so the next assembly recomputes it (K += blocks - 0).
void carry_blocks(const KeptElements& k, TangentCache& old, bool in_place, size_t old_size, int split,
                  TangentCache& c, std::vector<double>& K) {
  const Model& from = k.from;
  const Model& to = k.to;
  const double* src_Kl = in_place ? c.Kl.data() : old.Kl.data();
  size_t end = old_size;  // next free position at the end of Kl (in place)
  for (int e = 0; e < to.nelem; ++e) {
    const int nb = k.new_blocks(e), ns = k.new_slots(e);
    const int src = e < from.nelem ? (in_place ? c.kl_ptr[e] : old.kl_ptr[e]) : 0;
    if (!k.kept(e)) {
      if (split > 0 && e < from.nelem) {  // its old blocks leave the kept columns
        const int* sc = &from.elem_scatter[from.elem_scatter_ptr[e]];
        const double* kl = src_Kl + src;
        for (int b = 0; b < k.old_blocks(e); ++b)
          if (sc[b] >= 0 && sc[b] < split) K[sc[b]] -= kl[b];
      }
      if (in_place) {
        if (nb > k.old_blocks(e)) {
          c.kl_ptr[e] = static_cast<int>(end);
          end += nb;
          c.kl_garbage += k.old_blocks(e);
        } else {
          c.kl_garbage += k.old_blocks(e) - nb;
        }
      }
      std::fill_n(c.Kl.begin() + c.kl_ptr[e], nb, 0.0);
      std::fill_n(c.F.begin() + 9 * static_cast<size_t>(k.new_ptr[e]), 9 * ns, std::nan(""));
      continue;
    }
    double* kl = c.Kl.data() + c.kl_ptr[e];
    if (!in_place) std::copy_n(src_Kl + src, nb, kl);
    std::copy_n(old.F.data() + 9 * static_cast<size_t>(k.old_ptr[e]), 9 * ns, c.F.data() + 9 * static_cast<size_t>(k.new_ptr[e]));
    if (split > 0 && to.elem_dof_ptr[e + 1] - to.elem_dof_ptr[e] == to.mesh.npe()) continue;  // all in kept columns
    const int* sc = &to.elem_scatter[to.elem_scatter_ptr[e]];
    for (int b = 0; b < nb; ++b)
      if (sc[b] >= split) K[sc[b]] += kl[b];
  }
}

// integrator.tangent_reuse across a rebuild (see the comment above keep_buffers).
void carry_tangent_cache(const Model& from, TangentCache& old, std::vector<double>& old_K, const Model& to,
                         const std::vector<int>& changed, Workspace& ws) {
  TangentCache& c = ws.tangent_cache;
  c.last_partial = old.last_partial;
  c.bypass = old.bypass;  // still moving: the new model's assemblies keep no blocks either
  if (old.bypass && old.F.size() == 9 * static_cast<size_t>(from.nrot) && from.nelem == to.nelem) {
    carry_bypass(KeptElements(from, to, changed), old, c);
    return;
  }
  if (!old.valid || !(to.tangent_reuse > 0.0) || old.kl_ptr.size() != static_cast<size_t>(from.nelem)) {
    keep_buffers(old, c, /*with_F=*/true);
    return;
  }
  if ((old.last_partial < 0 || 2 * old.last_partial > from.nelem) && old.skipped_carries < 4) {
    c.skipped_carries = old.skipped_carries + 1;
    keep_buffers(old, c, /*with_F=*/true);
    return;
  }
  const KeptElements k(from, to, changed);
  const size_t old_size = old.Kl.size();
  const bool in_place = place_blocks(k, old, c);
  const int split = keep_mesh_columns(from, to, old_K, ws.K);
  carry_blocks(k, old, in_place, old_size, split, c, ws.K);
  c.valid = true;
  if (!in_place) c.spare_Kl = std::move(old.Kl);
  c.spare_F = std::move(old.F);
}

}  // namespace

void carry_workspace_over_cut(const Model& from, const Model& to, const std::vector<int>& dofnode_map,
                              const std::vector<int>& changed, AssemblyPlan* plan, int frame, Workspace& ws) {
  const bool carry = solver_carries_over_cuts(to, ws);
  const int refactorizations = ws.refactorizations;
  TangentCache kept = std::move(ws.tangent_cache);
  std::vector<double> old_K = std::move(ws.K);  // the sum of kept's blocks; its buffer is the next spare
  ws.K = std::move(kept.spare_K);
  if (carry) {  // the lagged factors stay; the new pattern is analyzed off this frame
    size_workspace(to, ws, /*zero=*/false);  // K: the carry below or the next assembly fills it
    prepare_solver(to, ws, frame, &dofnode_map, plan);
  } else {
    size_workspace(to, ws);
    prepare_solver(to, ws, frame, nullptr, plan);  // new pattern: symbolic analysis
  }
  carry_tangent_cache(from, kept, old_K, to, changed, ws);
  ws.tangent_cache.spare_K = std::move(old_K);
  ws.refactorizations = refactorizations;
  carry_contact_rows(from, dofnode_map, ws.contacts);
}

void carry_contact_rows(const Model& from, const std::vector<int>& dofnode_map, ContactRows& rows) {
  if (rows.nrow() == 0) return;
  // Old DOF node -> the new one carrying its field (mesh nodes keep their
  // ids); an old enriched node whose piece the cut split goes to the first
  // new piece that carries it, an approximation for this one frame only
  // (the next frame's collision maps its contacts on the new model).
  std::vector<int> to_new(from.ndofnode, -1);
  for (int q = static_cast<int>(dofnode_map.size()) - 1; q >= 0; --q)
    if (dofnode_map[q] >= 0) to_new[dofnode_map[q]] = q;
  // Entries whose DOF node vanished are dropped, compacting in place.
  int w = 0;
  for (int i = 0; i < rows.nrow(); ++i) {
    const int begin = rows.ptr[i], end = rows.ptr[i + 1];
    rows.ptr[i] = w;
    for (int k = begin; k < end; ++k) {
      const int d = rows.dof[k], node = d / 3 < from.ndofnode ? to_new[d / 3] : -1;
      if (node < 0) continue;
      rows.dof[w] = 3 * node + d % 3;
      rows.coef[w++] = rows.coef[k];
    }
  }
  rows.ptr[rows.nrow()] = w;
  rows.dof.resize(w);
  rows.coef.resize(w);
}

}  // namespace incise
