#pragma once
// Fused, parallel corotated assembly: rotation extraction, internal forces and
// the tangent in one pass over the elements, on the workers of a ThreadPool.
//
// Race freedom without atomics or per-thread copies of K: the elements are
// split into one contiguous block per worker; an element whose DOF nodes are
// touched by one block only is "interior" and is assembled by its block's
// worker; the others ("separators", a thin layer between blocks) are greedily
// coloured so no two elements of a colour share a DOF node, and each colour is
// split over the workers with a barrier between colours. With one worker the
// plan is the element order of the serial reference (assemble_internal).
// Results equal the serial reference up to the order of floating-point sums
// (verified in tests/engine/test_assemble_parallel.cpp).
#include <vector>

#include "engine/model/model.h"
#include "engine/runtime/thread_pool.h"

namespace incise {

struct AssemblyPlan {
  int nthreads = 1;
  std::vector<int> elem_rot_ptr;  // (nelem + 1) into elem_rot
  std::vector<int> elem_rot;      // rotation slots of each element
  std::vector<int> block_ptr;     // (nthreads + 1) into block_elem
  std::vector<int> block_elem;    // interior elements of each worker, in element order
  std::vector<int> color_ptr;     // (ncolor + 1) into color_elem
  std::vector<int> color_elem;    // separator elements grouped by colour
  int max_elem_nodes = 0;         // largest element (DOF nodes)
  std::vector<char> qp_own_rot;   // (nqp) 1 where the point's rotation slot is its own (rotation_stiffness.h)
  std::vector<char> qp_slot_F;    // (nqp) 1 where the point's F is its slot's (one point, same gradients): computed once
  int max_elem_slots = 0;         // most rotation slots of one element
  std::vector<double> slot_volume;  // (nrot) the volume of the slot's points (sum of their qp_weight, extension points not)
  std::vector<double> slot_weight;  // (nrot) shared_slot_weights: > 0 where a shared slot gets the rotation term
  bool exact_rotation_term = false;  // the term unprojected (rotation_stiffness.h, `exact`): the static solve's Newton
  std::vector<char> elem_condensed;  // (nelem) 1 where every slot of the element has a rest stiffness (Model::rot_K0)
  std::vector<std::vector<double>> scratch;  // (nthreads) per-worker work space
  std::vector<std::vector<double>> matvec_buf;  // (nthreads) per-worker partial y of sym_matvec
  std::vector<std::vector<double>> body_sums;   // (nthreads) (nbody, 3) rotation_change's per-body sums
  std::vector<int> matvec_col_ptr;  // (nthreads + 1) column ranges of about equal nnz
  int ncolors() const { return static_cast<int>(color_ptr.size()) - 1; }
  int nseparators() const { return static_cast<int>(color_elem.size()); }
};

// The plan for this model and worker count (done once per Model version).
AssemblyPlan make_assembly_plan(const Model& model, int nthreads);

// integrator.tangent_reuse: each element's tangent blocks as last assembled
// and the deformation gradients of its rotation slots then. While every slot's
// F stays within `theta` (largest entry of F - F_then), the element's blocks
// stay in K untouched; otherwise K gains (new - kept) and the kept blocks are
// replaced. K must then hold exactly the sum of the kept blocks between calls
// (the caller leaves it alone); `valid` false (new model, first frame) makes
// the next call a full assembly that fills the cache. See `bypass` below.
struct TangentCache {
  double theta = 0.0;
  bool valid = false;
  std::vector<double> Kl;  // blocks of each element (Model::elem_scatter's order), at kl_ptr
  // (nelem) where each element's blocks start in Kl: elem_scatter_ptr when an
  // assembly fills the cache; a cut's carry leaves the elements it did not
  // change where they are and puts the ones that grew at the end
  // (cut_apply.cpp), so Kl may hold unused entries (kl_garbage).
  std::vector<int> kl_ptr;
  std::size_t kl_garbage = 0;
  const double* blocks(int e) const { return &Kl[kl_ptr[e]]; }
  std::vector<double> F;   // (nrot, 9) each slot's F - I when its element's blocks were made
  int updated = 0;         // elements whose blocks the last call recomputed (all, when it was a full assembly)
  int last_partial = -1;   // `updated` of the last call that had a valid cache (-1: none yet); kept across cuts
  int skipped_carries = 0; // cuts in a row whose carry was skipped (cut_apply.cpp); kept across cuts
  // While nearly every element moves past theta (more than 9/10 recomputed),
  // keeping blocks only adds memory traffic (measured on the organ mesh:
  // +1.5 us per tet10 element when all are recomputed, 7.0-8.3 against
  // 5.3-7.1 us): `bypass` makes the next calls full assemblies that keep no
  // blocks and only note each slot's F, counting the elements whose slots
  // all moved less than theta since the last call (`would_keep`). Once a
  // tenth would have been kept, the next call fills the cache again.
  bool bypass = false;
  int would_keep = 0;
  std::vector<double> spare_Kl, spare_F;  // the previous model's arrays, reused by a cut's carry (cut_apply.cpp)
  std::vector<double> spare_K;            // the previous model's K, reused as the next one's (cut_apply.cpp)
};

// R (nrot, 9): warm start in, the rotation of every slot out (identity for the
// linear model); f_int (ndof) and K (nnz, skipped when null) overwritten, or,
// with a valid `cache` (theta > 0), updated element by element (TangentCache).
// With fv (ndof): fv = R K0 R^T v with the rotations extracted here, in the
// same pass (stiffness_matvec's product; the damping force of a step).
// Returns the number of SVD fallbacks of the rotation extraction.
int assemble_corotated(const Model& model, AssemblyPlan& plan, ThreadPool& pool, const double* u, double* R,
                       double* f_int, double* K, TangentCache* cache = nullptr, const double* v = nullptr,
                       double* fv = nullptr);

// Serial, over `elems` only, accumulating (nothing is zeroed): f_int += the
// elements' internal forces at u (their rotation slots updated in R, warm
// started), and, when v is given, Kv += their R K0 R^T v. For a cut rebuild's
// consistent acceleration near the elements the cut changed.
// The angles between the slot rotations R and the rotations of the
// configuration u (rotation_angle_to: one Newton step, not a full
// extraction): the largest over every slot, and their root mean square
// weighted by the slots' volumes. An angle that is NaN is not counted, nor a
// slot where u inverts the element (det F <= 0). On the pool's workers; R is
// not changed.
struct RotationChange {
  double max = 0.0;     // rad
  double rms = 0.0;     // rad, sqrt(sum_r V_r a_r^2 / sum_r V_r)
  double volume = 0.0;  // of the slots counted
  double above = 0.0;   // of the slots whose angle is above the threshold
  // Per body (Model::rot_body; the whole tissue while it is one): the largest
  // of the bodies' RMS and of their shares of volume above the threshold,
  // over the bodies of at least `small` of the counted volume, and over the
  // others (small pieces a cut severed).
  double body_rms = 0.0;    // rad
  double body_above = 0.0;  // fraction of that body's counted volume
  double small_rms = 0.0, small_above = 0.0;
};
RotationChange rotation_change(const Model& model, AssemblyPlan& plan, ThreadPool& pool, const double* u, const double* R,
                               double threshold, double small = 0.0);

// Forces (and with v, K v) of the elements `elems` only, on the calling thread.
void element_subset_forces(const Model& model, AssemblyPlan& plan, const std::vector<int>& elems, const double* u,
                           double* R, double* f_int, const double* v, double* Kv);

// y = K(R) v without forming K: per point f_a = w R (mu (S + S^T) + lambda tr(S) I) g_a with
// S = R^T sum_b v_b (x) g_b, which is R K0 R^T v element by element: the
// frozen-R tangent, without the rotation term assemble_corotated adds where
// a point owns its rotation (rotation_stiffness.h).
void stiffness_matvec(const Model& model, AssemblyPlan& plan, ThreadPool& pool, const double* R, const double* v,
                      double* y);

// y = A x for a symmetric matrix stored as the pattern's upper triangle, on the
// pool's workers (same result as sym_matvec up to the order of sums).
void sym_matvec_parallel(const Model& model, AssemblyPlan& plan, ThreadPool& pool, const double* A, const double* x,
                         double* y);
void sym_matvec_parallel(const Model& model, AssemblyPlan& plan, ThreadPool& pool, const float* A, const double* x,
                         double* y);

}  // namespace incise
