// Precomputation of the frozen Model: quadrature, rotation slots, sparse
// pattern and scatter map, mass, rest stiffness, loads, constraints.
#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

#include <Eigen/Core>

#include "engine/fem/assemble.h"
#include "engine/fem/element.h"
#include "engine/fem/polar.h"
#include "engine/util/error.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/model/model.h"
#include "engine/model/front_enrichment.h"

namespace incise {

namespace {

// The pieces of element e: with no layout, the whole element as one piece
// with no enrichment.
struct PieceView {
  const int* enr = nullptr;      // (npe) enriched DOF node per element node, -1 none; null = none
  const double* rst = nullptr;   // (nsub, 4, 3) sub-tetrahedra; null = the element itself
  int nsub = 1;
};

std::vector<PieceView> pieces_of(const Model& m, int e) {
  std::vector<PieceView> out;
  if (!m.has_cuts()) return {PieceView{}};
  const CutLayout& L = m.cuts;
  const int npe = m.mesh.npe();
  for (int P = L.elem_piece_ptr[e]; P < L.elem_piece_ptr[e + 1]; ++P) {
    PieceView v;
    v.enr = &L.piece_enr[static_cast<size_t>(P) * npe];
    if (L.elem_split[e]) {  // a whole element keeps rst = null: integrated (and its mass reused) as one
      v.rst = &L.subtet_rst[static_cast<size_t>(L.piece_subtet_ptr[P]) * 12];
      v.nsub = L.piece_subtet_ptr[P + 1] - L.piece_subtet_ptr[P];
    }
    out.push_back(v);
  }
  return out;
}

const double kRefTet[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};

// Whether element e has the same pieces in m's layout as in base's (none
// there = one whole piece): same enrichment, split flag and sub-tetrahedra,
// so its integration data can be copied from base (a cut rebuild redoes
// only the elements the new cut touched).
bool same_pieces(const Model& m, const Model& base, int e) {
  const CutLayout& L = m.cuts;
  const CutLayout& B = base.cuts;
  if (!same_piece_regions(m, base, e) || element_has_branch(m, e) || element_has_branch(base, e)) return false;
  const bool split = m.has_cuts() && L.elem_split[e], bsplit = base.has_cuts() && B.elem_split[e];
  if (split != bsplit) return false;
  if (!split) return true;
  const int p0 = L.elem_piece_ptr[e], np = L.elem_piece_ptr[e + 1] - p0, b0 = B.elem_piece_ptr[e];
  for (int k = 0; k < np; ++k) {
    const int s0 = L.piece_subtet_ptr[p0 + k], ns = L.piece_subtet_ptr[p0 + k + 1] - s0;
    const int t0 = B.piece_subtet_ptr[b0 + k], nt = B.piece_subtet_ptr[b0 + k + 1] - t0;
    if (ns != nt || !std::equal(L.subtet_rst.begin() + 12 * static_cast<size_t>(s0),
                                L.subtet_rst.begin() + 12 * static_cast<size_t>(s0 + ns),
                                B.subtet_rst.begin() + 12 * static_cast<size_t>(t0)))
      return false;
  }
  return true;
}

}  // namespace

bool same_piece_regions(const Model& m, const Model& base, int e) {
  const int npe = m.mesh.npe();
  const CutLayout& L = m.cuts;
  const CutLayout& B = base.cuts;
  const int p0 = m.has_cuts() ? L.elem_piece_ptr[e] : 0, np = m.has_cuts() ? L.elem_piece_ptr[e + 1] - p0 : 1;
  const int b0 = base.has_cuts() ? B.elem_piece_ptr[e] : 0, nb = base.has_cuts() ? B.elem_piece_ptr[e + 1] - b0 : 1;
  if (np != nb) return false;
  // Enriched DOF nodes may be renumbered between layouts: the element's
  // integration data depend only on which (piece, node) pairs share one, so
  // the ids must correspond one to one within the element.
  int xs[64], ys[64], nmap = 0;
  for (int k = 0; k < np; ++k)
    for (int a = 0; a < npe; ++a) {
      const int x = m.has_cuts() ? L.piece_enr[static_cast<size_t>(p0 + k) * npe + a] : -1;
      const int y = base.has_cuts() ? B.piece_enr[static_cast<size_t>(b0 + k) * npe + a] : -1;
      if ((x < 0) != (y < 0)) return false;
      if (x < 0) continue;
      int j = 0;
      while (j < nmap && xs[j] != x && ys[j] != y) ++j;
      if (j < nmap && (xs[j] != x || ys[j] != y)) return false;
      if (j == nmap) {
        if (nmap == 64) return false;
        xs[nmap] = x, ys[nmap++] = y;
      }
    }
  return true;
}

double mean_element_size(const Model& m) {
  double v = 0;
  for (int e = 0; e < m.nelem; ++e) v += m.elem_volume[e];
  return std::cbrt(v / std::max(1, m.nelem));
}

// Slots are numbered element by element: a count per element, summed.
std::vector<int> element_slot_ptr(const Model& m) {
  std::vector<int> ptr(m.nelem + 1, 0);
  for (int r = 0; r < m.nrot; ++r) ++ptr[m.rot_elem[r] + 1];
  for (int e = 0; e < m.nelem; ++e) ptr[e + 1] += ptr[e];
  return ptr;
}

namespace {

// Work arrays of build_elements, sized once for all elements.
struct ElementWork {
  std::vector<double> Xe;     // (npe, 3) the element's node positions
  std::vector<double> grad;   // (npe, 3) shape function gradients at a point
  std::vector<double> gmask;  // (n, 3) gradients spread over the element's n DOF nodes
  std::vector<int> local;     // (n) DOF nodes of the element
  // Front enrichment of the element being integrated (empty: none): local
  // index j of each branch DOF node, its element node a, function k, and
  // F_k at that node.
  std::vector<int> branch_j, branch_a, branch_k;
  std::vector<double> branch_F0;
  double node_phi[10] = {0}, node_psi[10] = {0}, N[10] = {0};
  std::vector<char> anchored;  // (npiece of m.cuts) anchored_pieces: the pieces that may get extension points
};

// Reserves m's per-element arrays for about base's sizes: no regrowth copies
// of these (MB-sized) arrays. With headroom, and only where the capacity is
// short of base's size: storage taken from a spare model (take_storage) two
// cuts older than base then serves as it is.
void reserve_like_base(Model& m, const Model& base, std::vector<int>& slot_src) {
  const auto room = [](auto& v, size_t n) {
    if (v.capacity() < n) v.reserve(n + n / 8 + 64);
  };
  room(m.elem_dof_node, base.elem_dof_node.size());
  room(m.qp_weight, base.qp_weight.size());
  room(m.qp_grad, base.qp_grad.size());
  room(m.qp_grad_ptr, base.qp_grad_ptr.size());
  room(m.qp_rot, base.qp_rot.size());
  room(m.qp_extension, base.qp_extension.size());
  room(m.rot_elem, base.rot_elem.size());
  room(slot_src, base.rot_elem.size());
  room(m.rot_grad, base.rot_grad.size());
  room(m.rot_grad_ptr, base.rot_grad_ptr.size());
}

// The element's DOF nodes into `local` and m.elem_dof_node: its nodes, then
// the enriched DOF nodes its pieces use ([preprint] eq. (45): appended).
void add_element_dof_nodes(Model& m, const int* nodes, const std::vector<PieceView>& pieces, std::vector<int>& local) {
  const int npe = m.mesh.npe();
  local.assign(nodes, nodes + npe);
  for (const PieceView& P : pieces)
    for (int a = 0; P.enr && a < npe; ++a)
      if (P.enr[a] >= 0 && std::find(local.begin() + npe, local.end(), P.enr[a]) == local.end())
        local.push_back(P.enr[a]);
  if (m.cuts.has_branch())  // then the branch DOF nodes of its nodes (front enrichment)
    for (int a = 0; a < npe; ++a)
      for (int k = 0; m.cuts.node_branch[nodes[a]] >= 0 && k < kBranchFunctions; ++k)
        local.push_back(m.cuts.node_branch[nodes[a]] + k);
  m.elem_dof_node.insert(m.elem_dof_node.end(), local.begin(), local.end());
  m.elem_dof_ptr.push_back(static_cast<int>(m.elem_dof_node.size()));
}

// Model::rot_body from the cut layout's bodies. A split element has one slot
// per piece, in piece order; any other element's slots (one, or one per
// cubature point) are all in its one piece.
void label_slot_bodies(Model& m) {
  m.rot_body.clear();
  m.nbody = m.has_cuts() ? m.cuts.bodies : 1;
  if (m.nbody <= 1 || m.cuts.piece_body.empty()) {
    m.nbody = 1;
    return;
  }
  m.rot_body.resize(m.nrot);
  const std::vector<int> slot_ptr = element_slot_ptr(m);
  for (int e = 0; e < m.nelem; ++e) {
    const int p0 = m.cuts.elem_piece_ptr[e], np = m.cuts.elem_piece_ptr[e + 1] - p0;
    const int ns = slot_ptr[e + 1] - slot_ptr[e];
    if (np > 1 && ns != np) throw Error("internal: element " + std::to_string(e) + " has " + std::to_string(np) +
                                        " pieces but " + std::to_string(ns) + " rotation slots");
    for (int k = 0; k < ns; ++k) m.rot_body[slot_ptr[e] + k] = m.cuts.piece_body[p0 + (np > 1 ? k : 0)];
  }
}

// Element e's rotation slots, points and volume copied from B, whose pieces
// of e are the same (base_slot: B's element_slot_ptr).
void copy_element_from_base(Model& m, const Model& B, int e, const std::vector<int>& base_slot,
                            std::vector<int>& slot_src) {
  const int shift = static_cast<int>(m.rot_elem.size()) - base_slot[e];  // new slot id - base slot id
  for (int r = base_slot[e]; r < base_slot[e + 1]; ++r) {
    m.rot_elem.push_back(e);
    slot_src.push_back(r);
    m.rot_grad.insert(m.rot_grad.end(), B.rot_grad.begin() + B.rot_grad_ptr[r], B.rot_grad.begin() + B.rot_grad_ptr[r + 1]);
    m.rot_grad_ptr.push_back(static_cast<int>(m.rot_grad.size()));
  }
  for (int q = B.elem_qp_ptr[e]; q < B.elem_qp_ptr[e + 1]; ++q) {
    m.qp_weight.push_back(B.qp_weight[q]);
    m.qp_grad.insert(m.qp_grad.end(), B.qp_grad.begin() + B.qp_grad_ptr[q], B.qp_grad.begin() + B.qp_grad_ptr[q + 1]);
    m.qp_grad_ptr.push_back(static_cast<int>(m.qp_grad.size()));
    m.qp_rot.push_back(B.qp_rot[q] + shift);
    m.qp_extension.push_back(B.qp_extension[q]);
  }
  m.elem_qp_ptr.push_back(static_cast<int>(m.qp_weight.size()));
  m.elem_volume[e] = B.elem_volume[e];
}

// Gradients g (npe, 3) spread over the element's DOF nodes `local` for piece
// P: node a's, and its enriched DOF node's where P has one ([preprint] eq.
// (42) with Psi = 1 in the piece's region, 0 elsewhere).
void spread_gradients(int npe, const std::vector<int>& local, const PieceView& P, const double* g,
                      std::vector<double>& gmask) {
  gmask.assign(3 * local.size(), 0.0);
  for (int a = 0; a < npe; ++a)
    for (int d = 0; d < 3; ++d) gmask[3 * a + d] = g[3 * a + d];
  for (int a = 0; P.enr && a < npe; ++a)
    if (P.enr[a] >= 0) {
      const int j = static_cast<int>(std::find(local.begin() + npe, local.end(), P.enr[a]) - local.begin());
      for (int d = 0; d < 3; ++d) gmask[3 * j + d] = g[3 * a + d];
    }
}

// Element e's branch DOF nodes into w (branch_j, branch_a, branch_k,
// branch_F0) and the level sets at its nodes; none without front enrichment.
void prepare_branch(const Model& m, int e, ElementWork& w) {
  w.branch_j.clear();
  w.branch_a.clear();
  w.branch_k.clear();
  w.branch_F0.clear();
  if (!element_has_branch(m, e)) return;
  const int npe = m.mesh.npe();
  front_node_values(m, e, w.node_phi, w.node_psi);
  std::vector<int> owner, fk;
  branch_owners(m, w.local.data(), static_cast<int>(w.local.size()), owner, fk);
  for (int j = npe; j < static_cast<int>(w.local.size()); ++j)
    if (owner[j] >= 0) {
      w.branch_j.push_back(j);
      w.branch_a.push_back(owner[j]);
      w.branch_k.push_back(fk[j]);
      w.branch_F0.push_back(branch_function(w.node_phi[owner[j]], w.node_psi[owner[j]]).F[fk[j]]);
    }
}

// The branch DOF nodes' gradients at local point r (w.grad: the element's
// shape gradients there) into w.gmask: grad(N_a (F_k - F_k(x_a))) = grad N_a
// (F_k - F_k(x_a)) + N_a (dF_k/dphi grad phi + dF_k/dpsi grad psi).
void add_branch_gradients(int npe, const double* r, ElementWork& w) {
  if (w.branch_j.empty()) return;
  shape_values(npe, r, w.N);
  double phi = 0, psi = 0, gphi[3] = {0, 0, 0}, gpsi[3] = {0, 0, 0};
  for (int a = 0; a < npe; ++a) {
    phi += w.N[a] * w.node_phi[a];
    psi += w.N[a] * w.node_psi[a];
    for (int d = 0; d < 3; ++d) {
      gphi[d] += w.grad[3 * a + d] * w.node_phi[a];
      gpsi[d] += w.grad[3 * a + d] * w.node_psi[a];
    }
  }
  const BranchValue F = branch_function(phi, psi);
  for (size_t i = 0; i < w.branch_j.size(); ++i) {
    const int j = w.branch_j[i], a = w.branch_a[i], k = w.branch_k[i];
    for (int d = 0; d < 3; ++d)
      w.gmask[3 * j + d] = w.grad[3 * a + d] * (F.F[k] - w.branch_F0[i]) +
                           w.N[a] * (F.dphi[k] * gphi[d] + F.dpsi[k] * gpsi[d]);
  }
}

}  // namespace

const Cubature& branch_cubature() {
  static const Cubature c = cubature_duffy(3);
  return c;
}

namespace {

// Piece P's cubature points over its sub-tetrahedra (sub-element integration,
// [preprint] eq. (52)): weights, gradients, the element's volume, and the
// rotation slot of each point: its own (point_rot) or `slot`.
void add_piece_points(Model& m, const Cubature& cub0, int e, const PieceView& P, bool point_rot, int slot,
                      ElementWork& w, std::vector<int>& slot_src) {
  const int npe = m.mesh.npe();
  // Elements with branch DOF nodes near the front line (a corner within
  // kBranchCubatureReach of the element's diameter): the branch functions
  // are not polynomial there (gradients as r^-1/2), see branch_cubature
  // (front_enrichment.h).
  bool near = false;
  if (!w.branch_j.empty()) {
    double rmin = 1e300, diam = 0;
    for (int a = 0; a < 4; ++a) {
      rmin = std::min(rmin, std::hypot(w.node_phi[a], w.node_psi[a]));
      for (int b = a + 1; b < 4; ++b)
        diam = std::max(diam, std::hypot(w.Xe[3 * a] - w.Xe[3 * b], w.Xe[3 * a + 1] - w.Xe[3 * b + 1],
                                         w.Xe[3 * a + 2] - w.Xe[3 * b + 2]));
    }
    near = rmin < kBranchCubatureReach * diam;
  }
  const Cubature& cub = near ? branch_cubature() : cub0;
  for (int sidx = 0; sidx < P.nsub; ++sidx) {
    const double* sub = P.rst ? P.rst + 12 * sidx : kRefTet;
    const double jac = 6.0 * subtet_ref_volume(sub);  // reference tet -> sub-tet
    for (int q = 0; q < cub.npoint(); ++q) {
      double r[3];
      map_to_element(sub, &cub.rst[3 * q], r);
      const double detJ = shape_global_gradients(npe, w.Xe.data(), r, w.grad.data());
      if (!(detJ > 0.0)) {
        std::ostringstream os;
        os << m.mesh.source << ": element " << e << " has a non-positive Jacobian (" << detJ
           << ") at a cubature point: inverted or badly curved";
        throw Error(os.str());
      }
      spread_gradients(npe, w.local, P, w.grad.data(), w.gmask);
      add_branch_gradients(npe, r, w);
      m.qp_weight.push_back(cub.weight[q] * jac * detJ);
      m.elem_volume[e] += cub.weight[q] * jac * detJ;
      m.qp_grad.insert(m.qp_grad.end(), w.gmask.begin(), w.gmask.end());
      m.qp_grad_ptr.push_back(static_cast<int>(m.qp_grad.size()));
      if (point_rot) {
        m.rot_elem.push_back(e);
        slot_src.push_back(-1);
        m.rot_grad.insert(m.rot_grad.end(), w.gmask.begin(), w.gmask.end());
        m.rot_grad_ptr.push_back(static_cast<int>(m.rot_grad.size()));
      }
      m.qp_rot.push_back(point_rot ? static_cast<int>(m.rot_elem.size()) - 1 : slot);
      m.qp_extension.push_back(0);
    }
  }
}

// The gradients of a piece's slot: for a piece of a split element the volume
// average of its points' gradients (points q_first on), else the
// corner-linear gradients gc spread over the DOF nodes.
void add_piece_rotation_gradients(Model& m, int q_first, bool split, const PieceView& P, const double* gc,
                                  ElementWork& w) {
  if (split) {
    const int n = static_cast<int>(w.local.size());
    std::vector<double> avg(3 * n, 0.0);
    double vol = 0.0;
    for (int q = q_first; q < static_cast<int>(m.qp_weight.size()); ++q) {
      for (int k = 0; k < 3 * n; ++k) avg[k] += m.qp_weight[q] * m.qp_grad[m.qp_grad_ptr[q] + k];
      vol += m.qp_weight[q];
    }
    for (double& v : avg) v /= vol;
    m.rot_grad.insert(m.rot_grad.end(), avg.begin(), avg.end());
  } else {
    spread_gradients(m.mesh.npe(), w.local, P, gc, w.gmask);  // mid-edge entries of gc are 0
    m.rot_grad.insert(m.rot_grad.end(), w.gmask.begin(), w.gmask.end());
  }
  m.rot_grad_ptr.push_back(static_cast<int>(m.rot_grad.size()));
}

// A small piece of a tet10 element has modes its own points hardly see:
// within a sliver of relative thickness delta, second-order combinations of
// its DOFs (N_a ~ delta^2, grad N_a ~ delta) have stiffness ~ delta^2 of
// their lumped mass (volume fraction times HRZ), so gravity and the body's
// acceleration drove them as nearly free masses. A loop incision on
// organ_10k passing 6e-4 h from three nodes had such DOFs at 20 m/s after
// 2 s, until their points' rotations flipped and the tissue there flailed;
// a cut 3e-2 h from them did the same (docs/cutting.md, "Small pieces").
// So a piece below kStiffenBelow of its element also integrates its own
// field over the whole element, at the element's 4 points with weight
// Model::cut_stabilization (scene cut_stabilization, 0.1) times its volume
// fraction (full below half of kStiffenBelow, to 0 at it), rotated with the
// piece: every mode keeps at least that share of its mass as stiffness (an
// extension in the spirit of CutFEM's ghost penalty). Rigid motions cost
// nothing; the pieces' own points, volumes and rotations are unchanged.
// 0.01 left the loop incision at up to 17 m/s. tet4 pieces (constant
// gradients: a piece's stiffness is its share of the element's) need none.
constexpr double kStiffenBelow = 0.1;

// (npiece) 1 for the pieces of a body that holds a piece of at least
// kStiffenBelow of its element (or a whole one): a body made of small
// pieces only (a severed fragment) has no larger part its slivers' modes
// could lag behind (gravity moves all its DOFs alike), and with extension
// points such a free corner fragment turned 0.7 rad between Newton
// iterations (0.04-0.1 without). Without body labels (one body): all.
std::vector<char> anchored_pieces(const CutLayout& L) {
  const int np = L.npiece();
  if (L.piece_body.size() != static_cast<size_t>(np)) return std::vector<char>(np, 1);
  std::vector<char> body_large(L.bodies, 0);
  for (int P = 0; P < np; ++P)
    if (L.piece_fraction[P] >= kStiffenBelow) body_large[L.piece_body[P]] = 1;
  std::vector<char> out(np);
  for (int P = 0; P < np; ++P) out[P] = body_large[L.piece_body[P]];
  return out;
}

// The extension points of piece P (above; layout piece `piece`), using
// rotation slot `slot`; none for a large piece, a piece of a fragment
// (anchored_pieces), a tet4 element or one with branch DOF nodes.
void add_piece_extension(Model& m, const PieceView& P, int piece, int slot, ElementWork& w) {
  const int npe = m.mesh.npe();
  if (npe != 10 || !P.rst || !w.branch_j.empty() || !w.anchored[piece]) return;
  const double fraction = m.cuts.piece_fraction[piece];  // as anchored_pieces reads it
  const double weight = m.cut_stabilization * fraction * std::clamp(2.0 * (kStiffenBelow - fraction) / kStiffenBelow, 0.0, 1.0);
  if (!(weight > 0.0)) return;
  const Cubature& cub = cubature_tet4();
  for (int q = 0; q < cub.npoint(); ++q) {
    const double detJ = shape_global_gradients(npe, w.Xe.data(), &cub.rst[3 * q], w.grad.data());
    spread_gradients(npe, w.local, P, w.grad.data(), w.gmask);
    m.qp_weight.push_back(weight * cub.weight[q] * detJ);
    m.qp_grad.insert(m.qp_grad.end(), w.gmask.begin(), w.gmask.end());
    m.qp_grad_ptr.push_back(static_cast<int>(m.qp_grad.size()));
    m.qp_rot.push_back(slot);
    m.qp_extension.push_back(1);
  }
}

// Integrates element e (node ids `nodes`, DOF nodes in w.local): its pieces'
// points and rotation slots. Rotation source: whole elements per cubature
// point (tet10 per_point) or the corner-linear gradient (tet4, tet10SR);
// pieces of a split element one rotation per piece from its volume-averaged
// gradient (one rotation per side, [preprint] eqs. (64)-(71)). A whole element
// that only carries enrichment keeps its per-point rotations, so a cut along
// element faces is exactly the node-duplicated mesh (tests/cutting).
void integrate_element(Model& m, const Cubature& cub, bool per_point, int e, const int* nodes,
                       const std::vector<PieceView>& pieces, ElementWork& w, std::vector<int>& slot_src) {
  const int npe = m.mesh.npe();
  for (int a = 0; a < npe; ++a)
    for (int d = 0; d < 3; ++d) w.Xe[3 * a + d] = m.mesh.X[3 * nodes[a] + d];
  const bool split = m.has_cuts() && m.cuts.elem_split[e];
  const bool point_rot = per_point && !split;
  prepare_branch(m, e, w);
  double gc[30] = {0};  // corner-linear gradients
  if (!per_point && !split) {
    double Xc[12];
    std::copy(w.Xe.begin(), w.Xe.begin() + 12, Xc);
    const double mid[3] = {0.25, 0.25, 0.25};
    shape_global_gradients(4, Xc, mid, gc);
  }
  const int piece0 = m.has_cuts() ? m.cuts.elem_piece_ptr[e] : 0;
  for (size_t k = 0; k < pieces.size(); ++k) {
    const PieceView& P = pieces[k];
    const int q_first = static_cast<int>(m.qp_weight.size());
    if (!point_rot) m.rot_elem.push_back(e), slot_src.push_back(-1);  // the piece's slot; gradients below
    const int slot = static_cast<int>(m.rot_elem.size()) - 1;
    add_piece_points(m, cub, e, P, point_rot, slot, w, slot_src);
    if (!point_rot) add_piece_rotation_gradients(m, q_first, split, P, gc, w);
    if (split) add_piece_extension(m, P, piece0 + static_cast<int>(k), slot, w);
  }
  m.elem_qp_ptr.push_back(static_cast<int>(m.qp_weight.size()));
}

// Per element: DOF nodes (its nodes, then the enriched DOF nodes its pieces
// use), quadrature points over every piece's sub-tetrahedra with the
// gradients of each DOF node's shape function in that piece (an enriched DOF
// node carries N_a in the pieces of its region, 0 elsewhere: [preprint] eqs.
// (42), (44)), and rotation slots: per cubature point (tet10 per_point), else
// one per piece (tet4, tet10SR; one rotation per side, [preprint] eqs.
// (64)-(71)).
//
// With `base` (same mesh and scene), an element whose pieces are unchanged
// copies its DOF nodes, points and slots from base; slot_src (nrot) then gives
// each slot's base slot (-1: integrated here) for build_slot_stiffness.
void build_elements(Model& m, const Scene& scene, const Model* base, std::vector<int>& slot_src) {
  const Mesh& mesh = m.mesh;
  const int npe = mesh.npe();
  const Cubature& cub = npe == 4 ? cubature_tet1() : cubature_tet4();
  const bool per_point = npe == 10 && scene.material.rotation == RotationMode::PerPoint;
  m.nelem = mesh.ntet();
  m.elem_dof_ptr.assign(1, 0);
  m.elem_qp_ptr.assign(1, 0);
  m.qp_grad_ptr.assign(1, 0);
  m.rot_grad_ptr.assign(1, 0);
  m.elem_volume.assign(m.nelem, 0.0);
  ElementWork w;
  w.Xe.resize(3 * npe);
  w.grad.resize(3 * npe);
  slot_src.clear();
  const std::vector<int> base_slot = base ? element_slot_ptr(*base) : std::vector<int>{};
  if (base) reserve_like_base(m, *base, slot_src);
  w.anchored = anchored_pieces(m.cuts);
  // An element copied from base must have had the same extension points:
  // its pieces the same and each as anchored (a fragment severed since
  // loses them).
  const std::vector<char> base_anchored = base ? anchored_pieces(base->cuts) : std::vector<char>{};
  const auto same_anchoring = [&](int e) {
    if (!m.has_cuts() || !m.cuts.elem_split[e]) return true;  // no extension points
    if (!base->has_cuts()) return false;
    const int p0 = m.cuts.elem_piece_ptr[e], b0 = base->cuts.elem_piece_ptr[e];
    for (int k = 0; k < m.cuts.elem_piece_ptr[e + 1] - p0; ++k)
      if (w.anchored[p0 + k] != base_anchored[b0 + k]) return false;
    return true;
  };
  for (int e = 0; e < m.nelem; ++e) {
    const int* nodes = &mesh.tet[static_cast<size_t>(e) * npe];
    const std::vector<PieceView> pieces = pieces_of(m, e);
    add_element_dof_nodes(m, nodes, pieces, w.local);
    if (base && same_pieces(m, *base, e) && same_anchoring(e)) copy_element_from_base(m, *base, e, base_slot, slot_src);
    else integrate_element(m, cub, per_point, e, nodes, pieces, w, slot_src);
  }
  m.nrot = static_cast<int>(m.rot_elem.size());
  label_slot_bodies(m);
}

// Rest stiffness of each piece of a split element (Model::rot_K0): K0 =
// sum_q w (lambda g_a g_b^T + mu g_b g_a^T + mu (g_a . g_b) I) over the
// piece's points (the corotated point stiffness with R = I: [book] eq. (A.38),
// eq. (A.51) at R = I). Split elements hold 12-50 sub-element points per piece and twice the
// DOF nodes of a whole one; rotating K0 per frame costs a tenth of integrating them.
// Pieces of elements with branch DOF nodes (front enrichment: 27 points a
// sub-tetrahedron near the front line) keep K0 over all their DOF nodes.
// A slot with slot_src >= 0 copies base's matrix of that slot.
void build_slot_stiffness(Model& m, const Model* base, const std::vector<int>& slot_src) {
  m.rot_K0_ptr.assign(m.nrot + 1, 0);
  m.rot_K0_partner_ptr.assign(m.nrot + 1, 0);
  m.rot_K0.clear();
  m.rot_K0_partner.clear();
  if (!m.has_cuts()) return;
  const int npe = m.mesh.npe();
  // Per slot: its points' range, and its K0's nodes: npe (over d, with
  // partners) or the element's n (branch DOF nodes; partners -1); 0 = none.
  std::vector<int> first_q(m.nrot, -1), last_q(m.nrot, -1), k_nodes(m.nrot, 0);
  std::vector<int> partner(m.nrot * static_cast<size_t>(npe), -1);
  const std::vector<int> slot_ptr = element_slot_ptr(m);
  for (int e = 0; e < m.nelem; ++e) {
    if (!m.cuts.elem_split[e]) continue;
    const bool branch = element_has_branch(m, e);
    const int b0 = m.elem_dof_ptr[e], n = m.elem_dof_ptr[e + 1] - b0;
    for (int q = m.elem_qp_ptr[e]; q < m.elem_qp_ptr[e + 1]; ++q) {
      const int r = m.qp_rot[q];
      if (first_q[r] < 0) first_q[r] = q;
      last_q[r] = q + 1;
      k_nodes[r] = branch ? n : npe;
    }
    if (branch) continue;
    // A split element's slots are its pieces, in order (build_elements).
    const std::vector<PieceView> pieces = pieces_of(m, e);
    for (size_t p = 0; p < pieces.size() && slot_ptr[e] + static_cast<int>(p) < slot_ptr[e + 1]; ++p)
      for (int a = 0; pieces[p].enr && a < npe; ++a)
        for (int j = npe; j < n && pieces[p].enr[a] >= 0; ++j)
          if (m.elem_dof_node[b0 + j] == pieces[p].enr[a]) partner[(slot_ptr[e] + p) * npe + a] = j;
  }
  const double mu = m.mu, lambda = m.lambda;
  for (int r = 0; r < m.nrot; ++r) {
    const int src = base ? slot_src[r] : -1, k = k_nodes[r];
    if (k == npe && src >= 0 && base->rot_K0_ptr[src + 1] > base->rot_K0_ptr[src]) {
      m.rot_K0.insert(m.rot_K0.end(), base->rot_K0.begin() + base->rot_K0_ptr[src],
                      base->rot_K0.begin() + base->rot_K0_ptr[src + 1]);
    } else if (k > 0) {
      // Z = sum_q w_q vec(G_q) vec(G_q)^T (3 k x 3 k, G_q the point's
      // gradients of the k nodes (k, 3): over d the npe mesh nodes' (a
      // piece's q_a carries the same gradient as u_a), else every DOF
      // node's) as one matrix product, then
      //   K0_ab(i, j) = lambda Z(3a+i, 3b+j) + mu Z(3b+i, 3a+j) + mu delta_ij sum_k Z(3a+k, 3b+k):
      // 5-8x faster than the point-by-point blocks for the 12-50 points of a piece.
      int nq = 0;
      for (int q = first_q[r]; q < last_q[r]; ++q) nq += m.qp_rot[q] == r;
      Eigen::MatrixXd G(nq, 3 * k), Gw(nq, 3 * k);
      for (int q = first_q[r], row = 0; q < last_q[r]; ++q) {
        if (m.qp_rot[q] != r) continue;
        const double* g = &m.qp_grad[m.qp_grad_ptr[q]];
        for (int c = 0; c < 3 * k; ++c) {
          G(row, c) = g[c];
          Gw(row, c) = m.qp_weight[q] * g[c];
        }
        ++row;
      }
      const Eigen::MatrixXd Z = G.transpose() * Gw;
      const size_t at = m.rot_K0.size();
      m.rot_K0.resize(at + 9 * static_cast<size_t>(k * (k + 1) / 2), 0.0);
      double* blk = &m.rot_K0[at];
      for (int a = 0; a < k; ++a)
        for (int b = a; b < k; ++b, blk += 9) {
          const double gg = mu * (Z(3 * a, 3 * b) + Z(3 * a + 1, 3 * b + 1) + Z(3 * a + 2, 3 * b + 2));
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
              blk[3 * i + j] = lambda * Z(3 * a + i, 3 * b + j) + mu * Z(3 * b + i, 3 * a + j) + (i == j ? gg : 0.0);
        }
    }
    if (m.rot_K0.size() > static_cast<size_t>(m.rot_K0_ptr[r])) {
      if (k == npe)
        m.rot_K0_partner.insert(m.rot_K0_partner.end(), partner.begin() + static_cast<size_t>(r) * npe,
                                partner.begin() + static_cast<size_t>(r + 1) * npe);
      else
        m.rot_K0_partner.insert(m.rot_K0_partner.end(), k, -1);
    }
    m.rot_K0_ptr[r + 1] = static_cast<int>(m.rot_K0.size());
    m.rot_K0_partner_ptr[r + 1] = static_cast<int>(m.rot_K0_partner.size());
  }
}

// A face is on the boundary when no other tetrahedron has the same corners;
// the others pair up (Model::tet_face_pair). Also each node's elements.
void build_boundary_faces(Model& m) {
  const Mesh& mesh = m.mesh;
  const int npe = mesh.npe();
  std::vector<std::array<int, 4>> faces;  // sorted corners + (elem * 4 + k)
  faces.reserve(4 * static_cast<size_t>(mesh.ntet()));
  for (int e = 0; e < mesh.ntet(); ++e)
    for (int k = 0; k < 4; ++k) {
      std::array<int, 4> f;
      for (int j = 0, c = 0; j < 4; ++j)
        if (j != k) f[c++] = mesh.tet[static_cast<size_t>(e) * npe + j];
      std::sort(f.begin(), f.begin() + 3);
      f[3] = 4 * e + k;
      faces.push_back(f);
    }
  std::sort(faces.begin(), faces.end());
  m.tet_face_boundary.assign(4 * static_cast<size_t>(mesh.ntet()), 0);
  m.tet_face_pair.clear();
  for (size_t i = 0; i < faces.size();) {
    size_t j = i + 1;
    while (j < faces.size() && std::equal(faces[j].begin(), faces[j].begin() + 3, faces[i].begin())) ++j;
    if (j - i == 1) m.tet_face_boundary[faces[i][3]] = 1;
    for (size_t k = i; k + 1 < j; ++k)  // a conforming mesh has j - i <= 2
      m.tet_face_pair.insert(m.tet_face_pair.end(),
                             {faces[k][3] / 4, faces[k][3] % 4, faces[k + 1][3] / 4, faces[k + 1][3] % 4});
    i = j;
  }
  m.node_elem_ptr.assign(mesh.nnode() + 1, 0);
  for (int node : mesh.tet) ++m.node_elem_ptr[node + 1];
  for (int n = 0; n < mesh.nnode(); ++n) m.node_elem_ptr[n + 1] += m.node_elem_ptr[n];
  m.node_elem.assign(mesh.tet.size(), 0);
  std::vector<int> next(m.node_elem_ptr.begin(), m.node_elem_ptr.end() - 1);
  for (int e = 0; e < mesh.ntet(); ++e)
    for (int a = 0; a < npe; ++a) m.node_elem[next[mesh.tet[static_cast<size_t>(e) * npe + a]]++] = e;
}

// Node-level rows of a run of columns (DOF nodes first .. first + ncol - 1):
// column node c's rows are rows[rp[c - first] .. rp[c - first + 1]), sorted
// and unique.
struct NodeRows {
  std::vector<int> rows, rp;
};

// visit(na, nc) for every pair of DOF nodes na <= nc of an element.
template <class Visit>
void for_each_node_pair(const Model& m, Visit visit) {
  for (int e = 0; e < m.nelem; ++e) {
    const int b = m.elem_dof_ptr[e], n = m.elem_dof_ptr[e + 1] - b;
    for (int a = 0; a < n; ++a)
      for (int c = 0; c < n; ++c) {
        const int na = m.elem_dof_node[b + a], nc = m.elem_dof_node[b + c];
        if (na <= nc) visit(na, nc);
      }
  }
}

// visit(na, nc) for every pair of DOF nodes na <= nc of an element, nc enriched.
template <class Visit>
void for_each_enriched_pair(const Model& m, const std::vector<char>& enriched_elem, Visit visit) {
  const int nstd = m.nnode;
  for (int e = 0; e < m.nelem; ++e) {
    if (!enriched_elem[e]) continue;
    const int b = m.elem_dof_ptr[e], n = m.elem_dof_ptr[e + 1] - b;
    for (int a = 0; a < n; ++a)
      for (int c = 0; c < n; ++c) {
        const int na = m.elem_dof_node[b + a], nc = m.elem_dof_node[b + c];
        if (nc >= nstd && na <= nc) visit(na, nc);
      }
  }
}

// The rows of columns first .. first + ncol - 1 from the node pairs that
// for_each_pair(visit) visits, as a node-level CSR built by counting (a cut
// rebuild redoes this, so it avoids per-node allocations). Every column keeps
// its diagonal block, also a node no element uses (build_constraints fixes those).
template <class Pairs>
NodeRows node_rows(int first, int ncol, Pairs for_each_pair) {
  std::vector<int> cnt(ncol + 1, 1);
  cnt[0] = 0;
  for_each_pair([&](int, int nc) { ++cnt[nc - first + 1]; });
  for (int c = 0; c < ncol; ++c) cnt[c + 1] += cnt[c];
  NodeRows nr;
  std::vector<int>& rows = nr.rows;
  rows.resize(cnt.back());
  std::vector<int> fill(cnt.begin(), cnt.end() - 1);
  for (int c = 0; c < ncol; ++c) rows[fill[c]++] = first + c;
  for_each_pair([&](int na, int nc) { rows[fill[nc - first]++] = na; });
  nr.rp.assign(ncol + 1, 0);
  int w = 0;
  for (int c = 0; c < ncol; ++c) {
    const auto b = rows.begin() + cnt[c], e = rows.begin() + cnt[c + 1];
    std::sort(b, e);
    const int k = static_cast<int>(std::unique(b, e) - b);
    std::copy(b, b + k, rows.begin() + w);  // w <= cnt[c]: moves left only
    nr.rp[c] = w;
    w += k;
    nr.rp[c + 1] = w;
  }
  return nr;
}

// Ap, Ai and diag of the columns of DOF nodes first.. (Ap[3 first] already
// set). Column 3c + j holds, for each row node r of c in order, rows
// 3r..3r+2 (r < c) or 3c..3c+j (r = c, the last one).
void fill_columns(Model& m, const NodeRows& nr, int first) {
  const int ncol = static_cast<int>(nr.rp.size()) - 1;
  for (int c = 0; c < ncol; ++c) {
    const int nrow = nr.rp[c + 1] - nr.rp[c], col = 3 * (first + c);
    for (int j = 0; j < 3; ++j) m.Ap[col + j + 1] = m.Ap[col + j] + 3 * (nrow - 1) + j + 1;
  }
  m.Ai.resize(m.Ap.back());
  for (int c = 0; c < ncol; ++c)
    for (int j = 0; j < 3; ++j) {
      int k = m.Ap[3 * (first + c) + j];
      for (int t = nr.rp[c]; t < nr.rp[c + 1]; ++t) {
        const int last = nr.rows[t] < first + c ? 2 : j;
        for (int i = 0; i <= last; ++i) m.Ai[k++] = 3 * nr.rows[t] + i;
      }
    }
  m.diag.resize(m.ndof());
  for (int d = 0; d < m.ndof(); ++d) m.diag[d] = m.Ap[d + 1] - 1;  // the diagonal ends its column
}

// Elements with an enriched DOF node.
std::vector<char> enriched_elements(const Model& m) {
  std::vector<char> enriched_elem(m.nelem, 0);
  for (int e = 0; e < m.nelem; ++e)
    for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k)
      if (m.elem_dof_node[k] >= m.nnode) enriched_elem[e] = 1;
  return enriched_elem;
}

// Index t of row node na among column node nc's row nodes; nr holds the
// enriched columns.
int row_index_from_base(const Model& m, const NodeRows& nr, int na, int nc) {
  const int nstd = m.nnode;
  if (nc >= nstd) {
    const auto first = nr.rows.begin() + nr.rp[nc - nstd];
    return static_cast<int>(std::lower_bound(first, nr.rows.begin() + nr.rp[nc - nstd + 1], na) - first);
  }
  // A mesh node's column 3 nc lists 3 r for each row node r at stride 3.
  int lo = 0, hi = (m.Ap[3 * nc + 1] - m.Ap[3 * nc] - 1) / 3 + 1;
  while (lo < hi) {
    const int mid = (lo + hi) / 2;
    if (m.Ai[m.Ap[3 * nc] + 3 * mid] < 3 * na) lo = mid + 1;
    else hi = mid;
  }
  return lo;
}

// The scatter of an element with the same DOF nodes as in base and no
// enrichment is copied, the others' are searched. The block loop repeats
// build_scatter's: shared as a template it took ~15% more instructions.
void scatter_from_base(Model& m, const Model& base, const std::vector<char>& enriched_elem, const NodeRows& nr) {
  m.elem_scatter_ptr.assign(1, 0);
  m.elem_scatter_ptr.reserve(m.nelem + 1);
  m.elem_scatter.clear();
  if (m.elem_scatter.capacity() < base.elem_scatter.size())  // (as reserve_like_base)
    m.elem_scatter.reserve(base.elem_scatter.size() + base.elem_scatter.size() / 8);
  for (int e = 0; e < m.nelem; ++e) {
    const int b = m.elem_dof_ptr[e], n = m.elem_dof_ptr[e + 1] - b;
    const bool same = !enriched_elem[e] && base.elem_dof_ptr[e + 1] - base.elem_dof_ptr[e] == n &&
                      std::equal(m.elem_dof_node.begin() + b, m.elem_dof_node.begin() + b + n,
                                 base.elem_dof_node.begin() + base.elem_dof_ptr[e]);
    if (same)
      m.elem_scatter.insert(m.elem_scatter.end(), base.elem_scatter.begin() + base.elem_scatter_ptr[e],
                            base.elem_scatter.begin() + base.elem_scatter_ptr[e + 1]);
    else
      for (int a = 0; a < n; ++a)
        for (int c = a; c < n; ++c) {
          int na = m.elem_dof_node[b + a], nc = m.elem_dof_node[b + c];
          const bool swapped = na > nc;
          if (swapped) std::swap(na, nc);
          const int t = row_index_from_base(m, nr, na, nc);
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
              if (a == c && i > j) {
                m.elem_scatter.push_back(-1);
                continue;
              }
              const int R = swapped ? j : i, C = swapped ? i : j;
              m.elem_scatter.push_back(m.Ap[3 * nc + C] + 3 * t + R);
            }
        }
    m.elem_scatter_ptr.push_back(static_cast<int>(m.elem_scatter.size()));
  }
}

// build_pattern for a model of the same mesh as `base` (a cut rebuild). The
// columns of mesh nodes only have mesh-node rows, which cuts never change,
// so they are copied; the enriched DOF nodes' columns are built from the
// elements that carry enrichment, and the scatter of an element with the same
// DOF nodes and no enrichment is copied. The result equals build_pattern's
// (Xfem.RebuildFromTheBaseModelEqualsAFreshBuild).
void build_pattern_from_base(Model& m, const Model& base) {
  const int nstd = m.nnode, cstd = 3 * nstd;
  m.Ap.assign(base.Ap.begin(), base.Ap.begin() + cstd + 1);
  // With headroom, as the enriched columns grow cut by cut (a spare's
  // storage, build_model, then serves the next rebuilds too).
  if (m.Ai.capacity() < base.Ai.size()) m.Ai.reserve(base.Ai.size() + base.Ai.size() / 8);
  m.Ai.assign(base.Ai.begin(), base.Ai.begin() + base.Ap[cstd]);
  m.Ap.resize(m.ndof() + 1);
  const std::vector<char> enriched_elem = enriched_elements(m);
  const NodeRows nr = node_rows(nstd, m.ndofnode - nstd,
                                [&](auto visit) { for_each_enriched_pair(m, enriched_elem, visit); });
  fill_columns(m, nr, nstd);
  scatter_from_base(m, base, enriched_elem, nr);
}

// Scatter: entry (3r + i, 3c + j), r <= c, sits at Ap[3c + j] + 3 t + i with
// t the index of r among c's row nodes: one search per node pair.
void build_scatter(Model& m, const NodeRows& nr) {
  m.elem_scatter_ptr.assign(1, 0);
  m.elem_scatter.clear();
  for (int e = 0; e < m.nelem; ++e) {
    const int b = m.elem_dof_ptr[e], n = m.elem_dof_ptr[e + 1] - b;
    for (int a = 0; a < n; ++a)
      for (int c = a; c < n; ++c) {
        int na = m.elem_dof_node[b + a], nc = m.elem_dof_node[b + c];
        const bool swapped = na > nc;
        if (swapped) std::swap(na, nc);
        const auto first = nr.rows.begin() + nr.rp[nc];
        const int t = static_cast<int>(std::lower_bound(first, nr.rows.begin() + nr.rp[nc + 1], na) - first);
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            if (a == c && i > j) {
              m.elem_scatter.push_back(-1);  // the symmetric twin is added once
              continue;
            }
            // the local block (a, c) entry (i, j) is the global (3 na + i, 3 nc + j), transposed when swapped
            const int R = swapped ? j : i, C = swapped ? i : j;
            m.elem_scatter.push_back(m.Ap[3 * nc + C] + 3 * t + R);
          }
      }
    m.elem_scatter_ptr.push_back(static_cast<int>(m.elem_scatter.size()));
  }
}

// Upper triangle at DOF-node level: rows(c) = DOF nodes r <= c sharing an element.
void build_pattern(Model& m) {
  const NodeRows nr = node_rows(0, m.ndofnode, [&](auto visit) { for_each_node_pair(m, visit); });
  m.Ap.assign(m.ndof() + 1, 0);
  fill_columns(m, nr, 0);
  build_scatter(m, nr);
}

// Work arrays of build_mass, sized once for all elements.
struct MassWork {
  const Mesh& mesh;
  double rho;
  Cubature cub;  // rho N_a N_b det J: degree 2p in the shape functions plus 3 for a curved tet10 map
  std::vector<double> Xe, N, grad;  // (npe, 3), (npe), (npe, 3)
  std::vector<double> Me, Mp;       // (npe, npe) the element's and a piece's rho int N_a N_b
  std::vector<double> hrz;          // (npe) the element's HRZ lumped masses
  double hrz_scale = 1.0;           // rho V / tr Me: HRZ's factor on the consistent diagonal
  MassWork(const Mesh& mesh_, double rho_) : mesh(mesh_), rho(rho_), cub(cubature_duffy(mesh_.npe() == 4 ? 2 : 7)) {
    const int npe = mesh.npe();
    Xe.resize(3 * npe), N.resize(npe), grad.resize(3 * npe), Me.resize(npe * npe), Mp.resize(npe * npe);
    hrz.resize(npe);
  }
};

// M (npe, npe) += rho wq N N^T at one point. -O2 vectorizes a loop only when
// it needs no run-time check: N and M are distinct (restrict) and npe is
// even (Mesh::npe() is 4 or 10, seen where this is inlined).
inline void add_point_mass(int npe, double rho, double wq, const double* __restrict N, double* __restrict M) {
  for (int a = 0; a < npe; ++a)
    for (int b = 0; b < npe; ++b) M[a * npe + b] += rho * wq * N[a] * N[b];
}

// out (npe, npe) = rho int N_a N_b over nsub sub-tets `subs` (null: the whole
// element) of the element at w.Xe: sub-element integration, [preprint] eq. (52).
void integrate_mass(const double* subs, int nsub, MassWork& w, std::vector<double>& out) {
  const int npe = w.mesh.npe();
  const Cubature& cub = w.cub;
  std::fill(out.begin(), out.end(), 0.0);
  for (int k = 0; k < nsub; ++k) {
    const double* sub = subs ? subs + 12 * k : kRefTet;
    const double jac = 6.0 * subtet_ref_volume(sub);
    for (int q = 0; q < cub.npoint(); ++q) {
      double r[3];
      map_to_element(sub, &cub.rst[3 * q], r);
      const double wq = cub.weight[q] * jac * shape_global_gradients(npe, w.Xe.data(), r, w.grad.data());
      shape_values(npe, r, w.N.data());
      add_point_mass(npe, w.rho, wq, w.N.data(), out.data());
    }
  }
}

// Element e's whole mass matrix into w.Me (the model's cache m.elem_mass when
// `reuse`, else integrated and cached) and its HRZ diagonal into w.hrz:
// rho V Me_aa / tr Me.
void element_mass(Model& m, int e, bool reuse, MassWork& w) {
  const int npe = w.mesh.npe();
  double* Mcache = &m.elem_mass[static_cast<size_t>(e) * npe * npe];
  if (!reuse) {
    integrate_mass(nullptr, 1, w, w.Me);
    std::copy(w.Me.begin(), w.Me.end(), Mcache);
  } else {
    std::copy(Mcache, Mcache + npe * npe, w.Me.begin());
  }
  double vol = 0.0;  // rho V = sum of the entries (partition of unity)
  for (double v : w.Me) vol += v;
  vol /= w.rho;
  double trace = 0.0;
  for (int a = 0; a < npe; ++a) trace += w.Me[a * npe + a];
  for (int a = 0; a < npe; ++a) w.hrz[a] = w.rho * vol * w.Me[a * npe + a] / trace;
  w.hrz_scale = w.rho * vol / trace;
}

// Adds value to the (i, j) entries (i, j: local DOF nodes of an element with n
// of them and scatter sc) of every component of m.mass_csc.
inline void add_mass_entry(Model& m, const int* sc, int n, int i, int j, double value) {
  if (i > j) std::swap(i, j);
  const int blk = i * n - i * (i - 1) / 2 + (j - i);  // index of block (i, j), i <= j
  for (int c = 0; c < 3; ++c) m.mass_csc[sc[9 * blk + 4 * c]] += value;
}

// Piece P's mass in element e. The lumped masses (frac * HRZ) go to
// mass_lumped in both modes (reported, and used by lumped-mass policies); the
// sparse matrix gets the lumped u-q couplings or the consistent piece matrix
// over d_a = u_a + q, mapped to (u, q).
void add_piece_mass(Model& m, int e, const PieceView& P, bool lumped, bool sparse, MassWork& w) {
  const int npe = w.mesh.npe();
  const int* nodes = &m.mesh.tet[static_cast<size_t>(e) * npe];
  const int b0 = m.elem_dof_ptr[e], n = m.elem_dof_ptr[e + 1] - b0;
  const int* sc = &m.elem_scatter[m.elem_scatter_ptr[e]];
  const bool whole = P.rst == nullptr;
  double frac = 1.0;
  if (!whole) {
    frac = 0.0;
    for (int k = 0; k < P.nsub; ++k) frac += 6.0 * subtet_ref_volume(P.rst + 12 * k);
  }
  if (m.mass_kind == MassKind::Consistent) {
    if (whole) w.Mp = w.Me;
    else integrate_mass(P.rst, P.nsub, w, w.Mp);
  }
  // local DOF indices of d_a: u_a (index a) and, if enriched, q (index j)
  int lq[10];
  for (int a = 0; a < npe; ++a) {
    lq[a] = -1;
    if (P.enr && P.enr[a] >= 0)
      for (int j = npe; j < n; ++j)
        if (m.elem_dof_node[b0 + j] == P.enr[a]) lq[a] = j;
  }
  for (int a = 0; a < npe; ++a) {
    const double ma = frac * w.hrz[a];
    if (!lumped)
      for (int d = 0; d < 3; ++d) m.mass_lumped[3 * nodes[a] + d] += ma;
    if (lq[a] >= 0)
      for (int d = 0; d < 3; ++d) m.mass_lumped[3 * P.enr[a] + d] += ma;
    if (lumped) {
      if (sparse && lq[a] >= 0) {
        add_mass_entry(m, sc, n, a, lq[a], ma);
        add_mass_entry(m, sc, n, lq[a], lq[a], ma);
      }
      continue;
    }
    for (int b = a; b < npe; ++b) {
      const double v = w.Mp[a * npe + b];
      const int ia[2] = {a, lq[a]}, ib[2] = {b, lq[b]};
      for (int x : ia)
        for (int y : ib) {
          if (x < 0 || y < 0) continue;
          // (a, b) and (b, a) both map here when a != b; the block is
          // symmetric, so add once per unordered pair of local indices.
          if (a == b && x > y) continue;
          add_mass_entry(m, sc, n, x, y, v);
        }
    }
  }
}

// The mass of element e's branch DOF nodes (front enrichment): rho int v_i
// v_j over its pieces, v the DOF node's function in the piece (N_a; N_a for
// the piece's enriched DOF node at a; N_a (F - F_a) for a branch DOF node).
// Consistent: every pair with a branch DOF node (the others are
// add_piece_mass's). Lumped: the branch diagonal times HRZ's factor rho V /
// tr Me (the element's standard nodes get the same factor), no coupling, so
// M g with g on the standard DOFs leaves the branch DOFs unloaded
// (build_gravity). mass_lumped gets the branch diagonal either way.
void add_branch_mass(Model& m, int e, MassWork& w) {
  const int npe = w.mesh.npe();
  const int b0 = m.elem_dof_ptr[e], n = m.elem_dof_ptr[e + 1] - b0;
  const int* local = &m.elem_dof_node[b0];
  const int* sc = &m.elem_scatter[m.elem_scatter_ptr[e]];
  double node_phi[10], node_psi[10];
  front_node_values(m, e, node_phi, node_psi);
  std::vector<int> owner, fk;  // element node and function of each branch DOF node
  branch_owners(m, local, n, owner, fk);
  const bool lumped = m.mass_kind == MassKind::Lumped;
  std::vector<double> F0(n, 0.0), v(n), M(static_cast<size_t>(n) * n, 0.0);
  for (int j = npe; j < n; ++j)
    if (owner[j] >= 0) F0[j] = branch_function(node_phi[owner[j]], node_psi[owner[j]]).F[fk[j]];
  for (const PieceView& P : pieces_of(m, e))
    for (int k = 0; k < P.nsub; ++k) {
      const double* sub = P.rst ? P.rst + 12 * k : kRefTet;
      const double jac = 6.0 * subtet_ref_volume(sub);
      for (int q = 0; q < w.cub.npoint(); ++q) {
        double r[3];
        map_to_element(sub, &w.cub.rst[3 * q], r);
        const double wq = w.cub.weight[q] * jac * shape_global_gradients(npe, w.Xe.data(), r, w.grad.data());
        shape_values(npe, r, w.N.data());
        double phi = 0, psi = 0;
        for (int a = 0; a < npe; ++a) phi += w.N[a] * node_phi[a], psi += w.N[a] * node_psi[a];
        const BranchValue F = branch_function(phi, psi);
        std::fill(v.begin(), v.end(), 0.0);
        for (int a = 0; a < npe; ++a) {
          v[a] = w.N[a];
          for (int j = npe; P.enr && P.enr[a] >= 0 && j < n; ++j)
            if (local[j] == P.enr[a]) v[j] = w.N[a];
        }
        for (int j = npe; j < n; ++j)
          if (owner[j] >= 0) v[j] = w.N[owner[j]] * (F.F[fk[j]] - F0[j]);
        if (lumped) {  // the branch DOFs' diagonal only (the same sums as the pair loop's)
          for (int i = npe; i < n; ++i)
            if (owner[i] >= 0) M[static_cast<size_t>(i) * n + i] += w.rho * wq * v[i] * v[i];
          continue;
        }
        for (int i = 0; i < n; ++i)
          for (int j = i; j < n; ++j)
            if (owner[i] >= 0 || owner[j] >= 0) M[static_cast<size_t>(i) * n + j] += w.rho * wq * v[i] * v[j];
      }
    }
  for (int i = 0; i < n; ++i)
    for (int j = i; j < n; ++j)
      if ((owner[i] >= 0 || owner[j] >= 0) && !lumped) add_mass_entry(m, sc, n, i, j, M[static_cast<size_t>(i) * n + j]);
  for (int j = npe; j < n; ++j) {
    if (owner[j] < 0) continue;
    const double mb = (lumped ? w.hrz_scale : 1.0) * M[static_cast<size_t>(j) * n + j];
    for (int d = 0; d < 3; ++d) m.mass_lumped[3 * local[j] + d] += mb;
    if (lumped) add_mass_entry(m, sc, n, j, j, mb);
  }
}

// Lumped with enrichment: the standard block is diagonal (add_mass_entry(a,
// a) never happens), so the off-diagonal nonzeros are the u-q couplings in
// the enriched columns, and the diagonal is mass_lumped (the same sums in the
// same order). Products with M then cost O(ndof) instead of a pass over the
// whole pattern.
void collect_mass_couplings(Model& m, bool lumped_sparse) {
  m.mass_coupling.clear();
  m.mass_coupling_col.clear();
  if (!lumped_sparse) return;
  for (int c = 3 * m.nnode; c < m.ndof(); ++c)
    for (int k = m.Ap[c]; k < m.diag[c]; ++k)
      if (m.mass_csc[k] != 0.0) {
        m.mass_coupling.push_back(k);
        m.mass_coupling_col.push_back(c);
      }
}

// Gravity load f = M g with g on the standard DOFs only: the field u = g t^2/2,
// q = 0 is exact free fall for every piece.
void build_gravity(Model& m, const Scene& scene) {
  for (int d = 0; d < 3; ++d) m.gravity[d] = scene.gravity[d];
  m.f_gravity.assign(m.ndof(), 0.0);
  if (m.mass_kind == MassKind::Lumped) {
    // Lumped with enrichment, M couples only u_a and q of the same node and
    // component with M_uq = M_qq = m_q (add_piece_mass), so M g (g on the u's)
    // is m_q g on q and the u's own diagonal (every piece's share) times g:
    // mass_lumped times g on every DOF, the DOF's component of g.
    for (int d = 0; d < m.ndof(); ++d) m.f_gravity[d] = m.mass_lumped[d] * scene.gravity[d % 3];
    // Branch DOFs (front enrichment) have no coupling: M g is 0 there.
    for (int i = 0; m.cuts.has_branch() && i < m.nnode; ++i)
      for (int k = 0; m.cuts.node_branch[i] >= 0 && k < kBranchFunctions; ++k)
        for (int d = 0; d < 3; ++d) m.f_gravity[3 * (m.cuts.node_branch[i] + k) + d] = 0.0;
  } else {  // consistent: the sparse product
    std::vector<double> g(m.ndof(), 0.0);
    for (int d = 0; d < 3 * m.nnode; ++d) g[d] = scene.gravity[d % 3];
    sym_matvec(m, m.mass_csc.data(), g.data(), m.f_gravity.data());
  }
}

// Mass per piece in the "piece DOF" space d_a = u_a + q_enr(a) (the
// displacement of node a as the piece sees it, [preprint] eq. (66)), then
// mapped to (u, q): consistent M_ab = int_P rho N_a N_b ([preprint] eqs.
// (77)-(80)), or lumped: the element's HRZ diagonal (positive for tet10, where
// row sums give -1/20 rho V at corners) times the piece's volume fraction.
// Lumping per piece and mapping keeps the coupling M(u_a, q) = M(q, q) =
// m_a^P: the diagonal is the X-FEM lumping of [preprint] eqs. (81)-(82) with
// Psi = chi_region, the coupling makes a separated piece fall freely at
// exactly g. Without enrichment the lumped mass is diagonal.
void build_mass(Model& m, const Scene& scene, const Model* base) {
  const Mesh& mesh = m.mesh;
  const int npe = mesh.npe();
  MassWork w(mesh, scene.material.density);
  const bool enriched = m.ndofnode > m.nnode;
  const bool sparse = m.mass_kind == MassKind::Consistent || enriched;
  m.mass_lumped.assign(m.ndof(), 0.0);
  if (sparse && m.mass_csc.capacity() < static_cast<size_t>(m.nnz())) m.mass_csc.reserve(m.nnz() + m.nnz() / 8);
  if (sparse) m.mass_csc.assign(m.nnz(), 0.0);
  const bool reuse = base && base->elem_mass.size() == static_cast<size_t>(m.nelem) * npe * npe;
  if (reuse) m.elem_mass = base->elem_mass;
  else m.elem_mass.assign(static_cast<size_t>(m.nelem) * npe * npe, 0.0);
  const bool lumped = m.mass_kind == MassKind::Lumped;
  // Lumped: a mesh node's own DOFs get the element's whole HRZ mass (the
  // pieces' shares sum to it), so they are the uncut mesh's, whatever the
  // cuts: a rebuild copies them from base and visits only the elements that
  // carry enrichment (the q DOFs and their couplings). Same sums, in the same
  // order, as a fresh build.
  const int nstd = 3 * m.nnode;
  const bool incremental = lumped && reuse && base->mass_kind == MassKind::Lumped && base->nnode == m.nnode &&
                           base->mass_lumped.size() >= static_cast<size_t>(nstd);
  if (incremental) std::copy(base->mass_lumped.begin(), base->mass_lumped.begin() + nstd, m.mass_lumped.begin());
  for (int e = 0; e < m.nelem; ++e) {
    const int* nodes = &mesh.tet[static_cast<size_t>(e) * npe];
    if (incremental && m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e] == npe) continue;  // no enrichment
    for (int a = 0; a < npe; ++a)
      for (int d = 0; d < 3; ++d) w.Xe[3 * a + d] = mesh.X[3 * nodes[a] + d];
    element_mass(m, e, reuse, w);
    if (lumped && !incremental) {  // the mesh nodes' own DOFs: the whole element's HRZ mass
      const int n = m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e];
      for (int a = 0; a < npe; ++a) {
        for (int d = 0; d < 3; ++d) m.mass_lumped[3 * nodes[a] + d] += w.hrz[a];
        if (sparse) add_mass_entry(m, &m.elem_scatter[m.elem_scatter_ptr[e]], n, a, a, w.hrz[a]);
      }
    }
    for (const PieceView& P : pieces_of(m, e)) add_piece_mass(m, e, P, lumped, sparse, w);
    if (element_has_branch(m, e)) add_branch_mass(m, e, w);
  }
  if (incremental && sparse)
    for (int d = 0; d < nstd; ++d) m.mass_csc[m.diag[d]] = m.mass_lumped[d];
  collect_mass_couplings(m, lumped && sparse);
  build_gravity(m, scene);
}

void build_constraints(Model& m, const Scene& scene, const Model* base) {
  // A rebuild (same mesh, base's standard columns copied by
  // build_pattern_from_base): the regions select mesh nodes only, so the
  // standard DOFs' flags, the prescribed list and the constrained entries of
  // the standard columns are base's; only the enriched columns are scanned.
  const int nstd = 3 * m.nnode;
  if (base && base->nnode == m.nnode && base->constrained.size() >= static_cast<size_t>(nstd) &&
      base->Ap.size() > static_cast<size_t>(nstd) && base->Ap[nstd] == m.Ap[nstd]) {
    m.constrained.assign(m.ndof(), 0);
    std::copy(base->constrained.begin(), base->constrained.begin() + nstd, m.constrained.begin());
    m.prescribed = base->prescribed;
    m.fixed_dofs.clear();
    for (int d : base->fixed_dofs)
      if (d < nstd) m.fixed_dofs.push_back(d);
    std::vector<char> used(m.ndofnode, 0);
    for (int node : m.elem_dof_node) used[node] = 1;
    for (int node = m.nnode; node < m.ndofnode; ++node)
      if (!used[node])
        for (int i = 0; i < 3; ++i) m.constrained[3 * node + i] = 1, m.fixed_dofs.push_back(3 * node + i);
    m.constrained_entries.clear();
    for (int k : base->constrained_entries) {
      if (k >= m.Ap[nstd]) break;  // base's list is in column order
      m.constrained_entries.push_back(k);
    }
    for (int c = nstd; c < m.ndof(); ++c)
      for (int k = m.Ap[c]; k < m.Ap[c + 1]; ++k)
        if (m.Ai[k] != c && (m.constrained[m.Ai[k]] || m.constrained[c])) m.constrained_entries.push_back(k);
    return;
  }
  m.constrained.assign(m.ndof(), 0);
  std::vector<double> value(m.ndof(), 0.0), ramp(m.ndof(), 0.0);
  std::vector<char> is_prescribed(m.ndof(), 0);
  for (const Region& r : scene.fixed)
    for (int n : select_nodes(m.mesh, r, scene.path))
      for (int i = 0; i < 3; ++i) m.constrained[3 * n + i] = 1;
  // A prescribed component overrides a fixed one on the same node (documented).
  for (const Prescribed& p : scene.prescribed)
    for (int n : select_nodes(m.mesh, p.region, scene.path))
      for (int i = 0; i < 3; ++i)
        if (p.active[i]) {
          m.constrained[3 * n + i] = 1;
          is_prescribed[3 * n + i] = 1;
          value[3 * n + i] = p.displacement[i];
          ramp[3 * n + i] = p.ramp;
        }
  m.fixed_dofs.clear();
  m.prescribed.clear();
  for (int d = 0; d < m.ndof(); ++d) {
    if (is_prescribed[d]) m.prescribed.push_back({d, value[d], ramp[d]});
    else if (m.constrained[d]) m.fixed_dofs.push_back(d);
  }
  // A node no element uses has no mass or stiffness: it is held fixed.
  std::vector<char> used(m.ndofnode, 0);
  for (int node : m.elem_dof_node) used[node] = 1;
  for (int node = 0; node < m.ndofnode; ++node)
    if (!used[node])
      for (int i = 0; i < 3; ++i)
        if (!m.constrained[3 * node + i]) m.constrained[3 * node + i] = 1, m.fixed_dofs.push_back(3 * node + i);
  std::sort(m.fixed_dofs.begin(), m.fixed_dofs.end());
  m.constrained_entries.clear();
  for (int c = 0; c < m.ndof(); ++c)
    for (int k = m.Ap[c]; k < m.Ap[c + 1]; ++k)
      if (m.Ai[k] != c && (m.constrained[m.Ai[k]] || m.constrained[c])) m.constrained_entries.push_back(k);
}

// The storage of spare's large arrays (MB-sized at 20k DOF), emptied: each
// is then filled as a new one would be, in pages already touched. Every
// array here is written from empty by the build.
void take_storage(Model& m, Model& spare) {
  const auto take = [](auto& to, auto& from) {
    to.swap(from);
    to.clear();
  };
  take(m.Ai, spare.Ai);
  take(m.elem_scatter, spare.elem_scatter);
  take(m.mass_csc, spare.mass_csc);
  take(m.elem_mass, spare.elem_mass);
  take(m.qp_grad, spare.qp_grad);
  take(m.qp_weight, spare.qp_weight);
  take(m.qp_grad_ptr, spare.qp_grad_ptr);
  take(m.qp_rot, spare.qp_rot);
  take(m.rot_grad, spare.rot_grad);
  take(m.rot_grad_ptr, spare.rot_grad_ptr);
  take(m.rot_elem, spare.rot_elem);
  take(m.elem_dof_node, spare.elem_dof_node);
}

}  // namespace

// The static solve's gravity load. Lumped with enrichment, f_gravity puts
// frac * HRZ mass * g on each Heaviside-enriched DOF node q: right for
// dynamics (exact free fall, masses proportional to the pieces' volumes), but
// where q's node's function nearly vanishes in q's region (the far nodes of a
// sliver: a cut 1e-4 h or less past a node layer) that load drives a
// near-null stiffness mode (energy of order (thickness)^3 against a load of
// order thickness): the static Newton stalled at a relative residual of 9e-5
// (offsets 1e-4 and 1e-6 h), or its tangent lost positive definiteness
// (1e-7 h). Such a q, whose region's consistent diagonal mass rho int N_a^2
// is below kSliverMass of the lumped one's share (frac * rho int_e N_a^2;
// about 1e-2 (thickness / h)^2 for a sliver, 1e-4 for one of 0.1 h, of order
// 1 for a piece N_a does not vanish in), gets the consistent load
// rho g int N_a over the pieces that use it ([book] eq. (3.34), the body
// force term), which leaves such a mode unloaded. Other q keep f_gravity's, so `initial: "static"` still starts a
// cut body at rest under the dynamics' load. Consistent mass, or no
// enrichment: f_gravity.
std::vector<double> static_gravity_load(const Model& m) {
  std::vector<double> f = m.f_gravity;
  if (m.mass_kind != MassKind::Lumped || m.ndofnode == m.nnode || !m.has_cuts()) return f;
  const Mesh& mesh = m.mesh;
  const int npe = mesh.npe();
  // Per DOF node (enriched ones used): rho int N_a^2 over q's pieces, frac *
  // rho int_e N_a^2 over them, and rho int N_a over them.
  std::vector<double> diag(m.ndofnode, 0.0), share(m.ndofnode, 0.0), load(m.ndofnode, 0.0);
  MassWork w(mesh, m.material.density);
  for (int e = 0; e < m.nelem; ++e) {
    if (m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e] == npe) continue;  // no enrichment
    const int* nodes = &mesh.tet[static_cast<size_t>(e) * npe];
    for (int b = 0; b < npe; ++b)
      for (int d = 0; d < 3; ++d) w.Xe[3 * b + d] = mesh.X[3 * nodes[b] + d];
    const double* Me = &m.elem_mass[static_cast<size_t>(e) * npe * npe];
    const std::vector<PieceView> pieces = pieces_of(m, e);
    for (int k = 0; k < static_cast<int>(pieces.size()); ++k) {
      const PieceView& P = pieces[k];
      if (!P.enr) continue;
      if (P.rst) integrate_mass(P.rst, P.nsub, w, w.Mp);
      else std::copy_n(Me, npe * npe, w.Mp.begin());
      const double frac = m.cuts.piece_fraction[m.cuts.elem_piece_ptr[e] + k];
      for (int a = 0; a < npe; ++a) {
        const int q = P.enr[a];
        if (q < 0) continue;
        diag[q] += w.Mp[a * npe + a];
        share[q] += frac * Me[a * npe + a];
        for (int b = 0; b < npe; ++b) load[q] += w.Mp[a * npe + b];  // row sum: partition of unity
      }
    }
  }
  for (int q = m.nnode; q < m.ndofnode; ++q)
    if (share[q] > 0.0 && diag[q] < kSliverMass * share[q])
      for (int d = 0; d < 3; ++d) f[3 * q + d] = load[q] * m.gravity[d];
  return f;
}

std::vector<int> select_nodes(const Mesh& mesh, const Region& region, const std::string& scene_path) {
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (int n = 0; n < mesh.nnode(); ++n)
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], mesh.X[3 * n + d]);
      hi[d] = std::max(hi[d], mesh.X[3 * n + d]);
    }
  const double tol = 1e-9 * std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                      (hi[2] - lo[2]) * (hi[2] - lo[2]));
  std::vector<int> out;
  if (region.kind == Region::Kind::Nodes) {
    for (int n : region.nodes) {
      if (n < 0 || n >= mesh.nnode()) {
        std::ostringstream os;
        os << scene_path << ": " << region.json_path << ".nodes: node " << n << " is out of range; the mesh has "
           << mesh.nnode() << " nodes (0-based ids 0.." << mesh.nnode() - 1 << ")";
        throw Error(os.str());
      }
      out.push_back(n);
    }
  } else {
    const double nn = std::sqrt(region.normal[0] * region.normal[0] + region.normal[1] * region.normal[1] +
                                region.normal[2] * region.normal[2]);
    for (int n = 0; n < mesh.nnode(); ++n) {
      const double* x = &mesh.X[3 * n];
      bool in = true;
      if (region.kind == Region::Kind::Box) {
        for (int d = 0; d < 3; ++d) in = in && x[d] >= region.lo[d] - tol && x[d] <= region.hi[d] + tol;
      } else {
        double s = 0.0;
        for (int d = 0; d < 3; ++d) s += (x[d] - region.point[d]) * region.normal[d] / nn;
        in = s <= tol;
      }
      if (in) out.push_back(n);
    }
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  if (out.empty())
    throw Error(scene_path + ": " + region.json_path + ": selects no mesh node; check the region against the mesh's bounding box");
  return out;
}

Model build_model(const Mesh& mesh_in, const Scene& scene, const CutLayout* cuts, const Model* base, Model* spare) {
  Model m;
  if (spare) take_storage(m, *spare);
  if (base) {
    m.mesh = base->mesh;  // checked and raised already
  } else {
    check_mesh(mesh_in);
    // Order 1 on a tet10 mesh takes its corner nodes (incise study sweeps the
    // order over one mesh file); order 2 on a tet4 mesh adds mid-edge nodes.
    m.mesh = scene.order == 2 ? raise_to_tet10(mesh_in) : lower_to_tet4(mesh_in);
  }
  m.material = scene.material;
  const double E = scene.material.young, nu = scene.material.poisson;
  m.mu = E / (2.0 * (1.0 + nu));
  m.lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  m.mass_kind = scene.mass;
  m.dt = scene.dt;
  m.newton_iterations = scene.newton_iterations;
  m.max_newton_iterations = std::max(scene.max_newton_iterations, scene.newton_iterations);
  m.rotation_tolerance = scene.rotation_tolerance;
  m.rotation_fraction = scene.rotation_fraction;
  m.rotation_rms = scene.rotation_rms;
  m.line_search = scene.line_search;
  m.residual_tolerance = scene.residual_tolerance;
  m.newmark_gamma = scene.newmark_gamma;
  m.newmark_beta = scene.newmark_beta;
  m.recovery_steps = scene.recovery_steps;
  m.consistent_tangent = scene.consistent_tangent;
  m.increment_predictor = scene.increment_predictor;
  m.tangent_reuse = scene.tangent_reuse;
  m.cut_stabilization = scene.cut_stabilization;
  if (!(m.newmark_gamma >= 0.5 && m.newmark_beta >= 0.5 * m.newmark_gamma))
    throw Error(scene.path + ": integrator: newmark_gamma must be >= 0.5 and newmark_beta >= newmark_gamma / 2 (got " +
                std::to_string(m.newmark_gamma) + ", " + std::to_string(m.newmark_beta) + ")");
  m.solver = scene.solver;
  m.nnode = m.ndofnode = m.mesh.nnode();
  m.X = m.mesh.X;
  {
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (size_t i = 0; i < m.X.size(); ++i) {
      lo[i % 3] = std::min(lo[i % 3], m.X[i]);
      hi[i % 3] = std::max(hi[i % 3], m.X[i]);
    }
    m.body_length = m.X.empty() ? 0.0 : std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  }
  if (cuts && cuts->npiece() > 0) {
    m.cuts = *cuts;
    m.ndofnode += cuts->n_enriched;
    m.X.resize(3 * static_cast<size_t>(m.ndofnode), 0.0);  // enriched DOF nodes: X = 0 (no rest position, [preprint] eq. (66))
  }
  // base's per-element data is reusable when it was built for the same mesh and rotation mode.
  const Model* same = base && base->nelem == m.mesh.ntet() && base->nnode == m.nnode &&
                              base->material.rotation == m.material.rotation && base->mu == m.mu &&
                              base->lambda == m.lambda
                          ? base
                          : nullptr;
  std::vector<int> slot_src;
  build_elements(m, scene, same, slot_src);
  build_slot_stiffness(m, same, slot_src);
  if (base) {
    m.tet_face_boundary = base->tet_face_boundary;
    m.tet_face_pair = base->tet_face_pair;
    m.node_elem_ptr = base->node_elem_ptr;
    m.node_elem = base->node_elem;
  } else {
    build_boundary_faces(m);
  }
  if (base && base->nnode == m.nnode && base->nelem == m.nelem) build_pattern_from_base(m, *base);
  else build_pattern(m);
  build_mass(m, scene, base);
  if (!base || model_needs_rest_stiffness(m)) m.K0_csc = rest_stiffness(m);
  build_constraints(m, scene, base && base->nnode == m.nnode && base->nelem == m.nelem ? base : nullptr);
  return m;
}

NewmarkCoefficients newmark_coefficients(const Model& m, bool recovery) {
  NewmarkCoefficients c;
  if (recovery) {
    // Backward Euler: x1 = x + dt v1, v1 = v + dt a1, so a1 = (Delta - dt v) /
    // dt^2 and v1 = Delta / dt (Newmark's gamma = beta = 1 without the carried
    // acceleration, which an unconverged step leaves inconsistent: on a
    // sliver's tiny-mass DOFs 7e3 m/s^2 after a cut, which a Newmark step with
    // gamma = 1, beta = 9/16 turned into 27 m/s through v1's dt (1 - gamma /
    // (2 beta)) a term). L-stable: no high frequency survives it.
    const double dt = m.dt;
    c.a_d = 1.0 / (dt * dt);
    c.a_v = -1.0 / dt;
    c.a_a = 0.0;
    c.v_d = 1.0 / dt;
    c.v_v = 0.0;
    c.v_a = 0.0;
  } else {
    const double dt = m.dt, b = m.newmark_beta, g = m.newmark_gamma;
    c.a_d = 1.0 / (b * dt * dt);
    c.a_v = -1.0 / (b * dt);
    c.a_a = 1.0 - 0.5 / b;
    // v1 = v + dt ((1 - gamma) a + gamma a1)
    c.v_d = g / (b * dt);
    c.v_v = 1.0 - g / b;
    c.v_a = dt * (1.0 - 0.5 * g / b);
  }
  c.cM = c.a_d + m.material.rayleigh_mass * c.v_d;
  c.cK = 1.0 + m.material.rayleigh_stiffness * c.v_d;
  return c;
}

std::vector<double> rest_stiffness(const Model& m) {
  std::vector<double> K0(m.nnz(), 0.0), u(m.ndof(), 0.0), f(m.ndof());
  const std::vector<double> R = identity_rotations(m.nrot);
  assemble_internal(m, u.data(), R.data(), f.data(), K0.data());
  return K0;
}

bool same_element_pieces(const Model& m, const Model& base, int e) { return same_pieces(m, base, e); }

bool model_needs_rest_stiffness(const Model& m) {
  return m.material.model == MaterialModel::Linear || m.solver.policy == SolverPolicy::Warped ||
         m.solver.policy == SolverPolicy::WarpedCG;
}

}  // namespace incise
