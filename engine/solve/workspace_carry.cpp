#include "engine/solve/workspace_carry.h"

#include <algorithm>
#include <cmath>

#include "engine/solve/linear_solve.h"
#include "engine/util/headroom.h"

namespace incise {

namespace {

// First rotation slot of each element (nelem + 1): slots are numbered element by element.
std::vector<int> slot_ptr(const Model& m) {
  std::vector<int> ptr(m.nelem + 1, 0);
  for (int r = 0; r < m.nrot; ++r) ++ptr[m.rot_elem[r] + 1];
  for (int e = 0; e < m.nelem; ++e) ptr[e + 1] += ptr[e];
  return ptr;
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
                         const std::vector<int>& changed, Workspace& ws) {
  ws.tangent_cache.last_partial = old.last_partial;
  ws.tangent_cache.bypass = old.bypass;  // still moving: the new model's assemblies keep no blocks either
  if (old.bypass && old.F.size() == 9 * static_cast<size_t>(from.nrot) && from.nelem == to.nelem) {
    // The bypass's F of the slots the cut left alone, so the next assembly
    // can tell whether the body calmed (during an incision every frame is a
    // cut frame: without them the bypass would never end).
    std::vector<char> fresh(to.nelem, 0);
    for (int e : changed) fresh[e] = 1;
    const std::vector<int> old_ptr = slot_ptr(from), new_ptr = slot_ptr(to);
    std::vector<double>& F = ws.tangent_cache.F;
    F = std::move(old.spare_F);
    assign_with_headroom(F, 9 * static_cast<size_t>(to.nrot), std::nan(""));
    for (int e = 0; e < to.nelem; ++e)
      if (!fresh[e] && new_ptr[e + 1] - new_ptr[e] == old_ptr[e + 1] - old_ptr[e])
        std::copy(old.F.begin() + 9 * static_cast<size_t>(old_ptr[e]),
                  old.F.begin() + 9 * static_cast<size_t>(old_ptr[e + 1]), F.begin() + 9 * static_cast<size_t>(new_ptr[e]));
    keep_buffers(old, ws.tangent_cache, /*with_F=*/false);
    return;
  }
  if (!old.valid || !(to.tangent_reuse > 0.0) || old.kl_ptr.size() != static_cast<size_t>(from.nelem)) {
    keep_buffers(old, ws.tangent_cache, /*with_F=*/true);
    return;
  }
  if ((old.last_partial < 0 || 2 * old.last_partial > from.nelem) && old.skipped_carries < 4) {
    ws.tangent_cache.skipped_carries = old.skipped_carries + 1;
    keep_buffers(old, ws.tangent_cache, /*with_F=*/true);
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
  TangentCache& c = ws.tangent_cache;
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
    ws.K.swap(old_K);  // old_K now holds the other buffer (the caller's next spare)
    resize_with_headroom(ws.K, static_cast<size_t>(to.nnz()));
  }
  std::fill(ws.K.begin() + split, ws.K.end(), 0.0);  // the enriched columns: summed below
  size_t end = old_size;  // next free position at the end of Kl (in place)
  for (int e = 0; e < to.nelem; ++e) {
    const int nb = new_blocks(e), ns = new_ptr[e + 1] - new_ptr[e];
    const int src = e < from.nelem ? (in_place ? c.kl_ptr[e] : old.kl_ptr[e]) : 0;
    if (!kept_elem(e)) {  // recomputed at the next assembly
      if (split > 0 && e < from.nelem) {  // its old blocks leave the kept columns
        const int* sc = &from.elem_scatter[from.elem_scatter_ptr[e]];
        const double* kl = src_Kl + src;
        for (int k = 0; k < old_blocks(e); ++k)
          if (sc[k] >= 0 && sc[k] < split) ws.K[sc[k]] -= kl[k];
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
      if (sc[k] >= split) ws.K[sc[k]] += kl[k];
  }
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
}

}  // namespace incise
