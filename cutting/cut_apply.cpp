#include "cutting/cut_apply.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <memory>
#include <thread>

#include <Eigen/Dense>
#include <Eigen/Sparse>

#include "engine/fem/element.h"
#include "engine/fem/polar.h"
#include "engine/model/front_enrichment.h"
#include "engine/solve/workspace_carry.h"
#include "engine/output/probe.h"
#include "engine/dynamics/step.h"
#include "engine/runtime/thread_affinity.h"
#include "engine/runtime/timing.h"

namespace incise {

namespace {

// Whether element e of m lists enriched DOF nodes besides its mesh nodes.
bool enriched(const Model& m, int e) { return m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e] > m.mesh.npe(); }

// Old model's effective values (u, v, a and, nf = 4, du) of node a of
// element e, in its piece P (piece_containing of a point of the new piece;
// -1: e was whole). side (+1, -1; 0: none): with front enrichment, add the
// old branch DOFs' part on that side of the cut, (F(x_a) - F_a) b, which is
// not 0 at a node on the cut behind the front (F_a is taken on the + side).
void old_piece_values(const Model& m, const State& s, int e, int P, int a, int nf, int side, double out[12]) {
  const int npe = m.mesh.npe();
  const int i = m.mesh.tet[static_cast<size_t>(e) * npe + a];
  const int q = P >= 0 ? m.cuts.piece_enr[static_cast<size_t>(P) * npe + a] : -1;
  const std::vector<double>* f[4] = {&s.u, &s.v, &s.a, &s.du};
  for (int k = 0; k < nf; ++k)
    for (int c = 0; c < 3; ++c) out[3 * k + c] = (*f[k])[3 * i + c] + (q >= 0 ? (*f[k])[3 * q + c] : 0.0);
  if (side == 0 || !element_has_branch(m, e)) return;
  double N[10] = {0};
  N[a] = 1.0;
  for (int k = 0; k < nf; ++k) add_branch_field(m, e, N, side, f[k]->data(), out + 3 * k);
}

// Warm starts for the new model's rotation slots: an element with as many
// slots as before keeps its old rotations (uncut elements, and cut ones whose
// pieces did not change), the others start from the identity. Saves the polar
// iterations of a cold start in the rebuild's force evaluation and the next step.
std::vector<double> carried_rotations(const Model& from, const std::vector<double>& R_from, const Model& to) {
  const std::vector<int> old_ptr = element_slot_ptr(from), new_ptr = element_slot_ptr(to);
  std::vector<double> R = identity_rotations(to.nrot);
  // Slot k of e is ptr[e] + k (model_build.cpp numbers them element by element).
  for (int e = 0; e < to.nelem && e < from.nelem; ++e) {
    const int n_old = old_ptr[e + 1] - old_ptr[e], n_new = new_ptr[e + 1] - new_ptr[e];
    if (n_old != n_new) continue;
    std::copy(R_from.begin() + 9 * static_cast<size_t>(old_ptr[e]), R_from.begin() + 9 * static_cast<size_t>(old_ptr[e + 1]),
              R.begin() + 9 * static_cast<size_t>(new_ptr[e]));
  }
  return R;
}

bool same_layout(const Model& m, const CutLayout& L) {
  const CutLayout& O = m.cuts;
  return m.has_cuts() && O.n_enriched == L.n_enriched && O.elem_piece_ptr == L.elem_piece_ptr &&
         O.piece_enr == L.piece_enr && O.subtet_rst == L.subtet_rst && O.elem_face_cut == L.elem_face_cut &&
         O.node_branch == L.node_branch && O.front_phi == L.front_phi && O.front_psi == L.front_psi;
}

// The part of a cut update that reads only the model, mesh and scene (so it
// may run on a helper thread while the current frame steps): the layout of
// the cut surfaces at t_sweep and the next Model built from it.
struct PreparedCut {
  std::vector<double> progress;  // (scene.cuts) what the update applies
  size_t swept = 0;              // instrument-swept triangles it includes (State::swept_tool.size())
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

// swept, swept_tool: the instruments' swept triangles the update includes
// (State::swept, swept_tool; the cut-ahead helper passes its own copy: it
// must not read the State the stages change).
PreparedCut prepare_cut(const Simulation& sim, const std::vector<double>& progress, double t_sweep,
                        const std::vector<double>& swept, const std::vector<double>& swept_tool) {
  PreparedCut p;
  p.progress = progress;
  p.swept = swept_tool.size();
  p.t_sweep = t_sweep;
  p.base_version = sim.model_version;
  std::vector<std::unique_ptr<CutSurface>> owned;
  std::vector<const CutSurface*> surfaces;
  // cut_front "enriched": which surfaces' fronts are enriched. A swept cut's
  // only once its sweep is complete: while it grows its front stays on
  // element faces, as an enriched front carried to a moved front changed
  // the energy by up to 8.4% of the gravity work (the old sqrt(r) is not in
  // the new space), while the face-snapped model is a subspace of the
  // enriched one at the same front, so enriching a front that stops is
  // exact (FrontEnrichment.AGrowingFrontStaysOnFacesAndIsEnrichedOnceItStops).
  // The scalpels' incisions keep their fronts on faces. Enriched while the
  // blade rests (twenty-first session, measured and withdrawn): on an
  // incision the bottom front line stays in the same elements while the
  // blade cuts on, so the rested front either froze there or had to be
  // carried to faces through the whole incision's ring at every rebuild
  // (docs/cutting.md, "The element at the cut front").
  std::vector<char> branch;
  for (size_t k = 0; k < sim.scene.cuts.size(); ++k) {
    if (progress[k] <= 0.0) continue;
    auto s = make_cut_surface(sim.scene.cuts[k], t_sweep);
    if (!s) continue;
    surfaces.push_back(s.get());
    owned.push_back(std::move(s));
    branch.push_back(sim.scene.front_enrichment && progress[k] >= 1.0);
  }
  for (size_t i = 0; i < sim.scene.instruments.size(); ++i) {
    auto s = make_swept_surface(swept, swept_tool, static_cast<int>(i), sim.scene.instruments[i].json_path);
    if (!s) continue;
    surfaces.push_back(s.get());
    owned.push_back(std::move(s));
    branch.push_back(0);
  }
  if (surfaces.empty()) return p;
  Stopwatch part;
  CutLayout layout = compute_cut_layout(sim.model, surfaces, &p.report, branch);
  p.layout_ms = part.lap();
  if (same_layout(sim.model, layout) || (!sim.model.has_cuts() && layout.n_enriched == 0 && p.report.cut_elements == 0))
    return p;
  p.next = std::make_unique<Model>(build_model(sim.mesh, sim.scene, &layout, &sim.model));
  for (int e = 0; e < p.next->nelem; ++e)
    if (!same_element_pieces(*p.next, sim.model, e)) p.changed.push_back(e);
  p.map = dofnode_map(sim.model, *p.next);
  p.plan = make_assembly_plan(*p.next, std::max(1, sim.ws.runtime.threads));
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
  sim.state.cut_progress = p.progress;
  if (!p.rebuild) {
    up.ms = clock.ms();
    return up;
  }
  Stopwatch part;
  Model& next = *p.next;
  State& st = sim.state;
  Kinematics k = transfer_kinematics(sim.model, st, next);  // (reads st: no copy of u, v, a)
  std::vector<double> R = carried_rotations(sim.model, st.R, next);
  std::unique_ptr<Model> old_model = std::make_unique<Model>(std::move(sim.model));
  sim.model = std::move(next);
  ++sim.model_version;
  st.u.swap(k.u);
  st.v.swap(k.v);
  st.a.swap(k.a);
  st.du.swap(k.du);
  st.R.swap(R);
  up.part_ms[kCutTransfer] = part.lap();
  carry_workspace_over_cut(*old_model, sim.model, p.map, p.changed, &p.plan, st.frame, sim.ws);
  sim.retired_model = std::move(old_model);  // freed by the next cut-ahead task, off this thread
  up.part_ms[kCutSolverSetup] = part.lap();
  consistent_acceleration_near(sim.model, st, sim.ws, p.changed);
  up.part_ms[kCutAcceleration] = part.lap();
  up.changed = true;
  up.ms = clock.ms();
  return up;
}

// The next frame's cut update, prepared on a helper thread during this
// frame's step (Simulation::cut_ahead).
struct CutAhead {
  PreparedCut result;
  std::exception_ptr error;
  std::vector<double> swept, swept_tool;  // copies of the State's, for the helper
  std::vector<double> progress;
  double t_sweep = 0.0;
  int base_version = -1;
};

// Progress of every cut for a frame at time t whose swept cuts reach t_sweep;
// *changed when it differs from sim.state.cut_progress.
std::vector<double> progress_at(const Simulation& sim, double t, double t_sweep, bool* changed) {
  std::vector<double> progress = sim.state.cut_progress;
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
bool take_ahead(Simulation& sim, const std::vector<double>& progress, double t_sweep, size_t swept, PreparedCut* out) {
  auto ahead = std::static_pointer_cast<CutAhead>(sim.cut_ahead);
  if (!ahead) return false;
  sim.cut_ahead.reset();
  sim.cut_helper->wait();
  if (ahead->error) std::rethrow_exception(ahead->error);
  if (ahead->base_version != sim.model_version || ahead->progress != progress || ahead->t_sweep != t_sweep ||
      ahead->result.swept != swept)
    return false;
  *out = std::move(ahead->result);
  return true;
}

}  // namespace

void start_cut_ahead(Simulation& sim, double t, double t_sweep) {
  PreparedCut dropped;
  take_ahead(sim, {}, 0.0, 0, &dropped);  // at most one helper
  bool changed = false;
  std::vector<double> progress = progress_at(sim, t, t_sweep, &changed);
  if (!changed) return;
  auto ahead = std::make_shared<CutAhead>();
  ahead->swept = sim.state.swept;
  ahead->swept_tool = sim.state.swept_tool;
  ahead->progress = progress;
  ahead->t_sweep = t_sweep;
  ahead->base_version = sim.model_version;
  CutAhead* a = ahead.get();
  const Simulation* s = &sim;
  const bool helper_cpus = sim.ws.runtime.split_affinity;
  if (!sim.cut_helper || sim.cut_helper->helper_cpus() != helper_cpus)
    sim.cut_helper = std::make_unique<HelperThread>(helper_cpus, HelperThread::Priority::Normal);  // (none running)
  std::shared_ptr<Model> retired = std::move(sim.retired_model);
  sim.cut_helper->run([ahead, a, s, retired]() mutable {  // (ahead: the task keeps its result alive)
    retired.reset();  // the model the last cut replaced (0.2-0.4 ms of frees)
    try {
      a->result = prepare_cut(*s, a->progress, a->t_sweep, a->swept, a->swept_tool);
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

// The DOF nodes of model m carrying the field at local point rst of piece P
// of element e (corner coordinates Xe), with their weights and gradients
// (g: n x 3): N_a on node a's standard DOF and on its enriched DOF node in
// P, N_a (F_k - F_k(x_a)) on its branch DOF nodes (side: of the front's
// plane, as for_each_branch_weight), whose gradient is grad N_a (F_k -
// F_k(x_a)) + N_a (dF_k/dphi grad phi + dF_k/dpsi grad psi) as the model's
// own points have it (model_build.cpp add_branch_gradients). Returns the
// count (<= 2 npe + npe kBranchFunctions) and the Jacobian determinant in *detJ.
constexpr int kMaxWeights = 2 * 10 + 10 * kBranchFunctions;
int field_basis(const Model& m, int e, int P, const double rst[3], int side, const double* Xe, int* dof, double* w,
                double* g, double* detJ) {
  const int npe = m.mesh.npe();
  const int* nodes = &m.mesh.tet[static_cast<size_t>(e) * npe];
  double N[10], dN[30];
  shape_values(npe, rst, N);
  *detJ = shape_global_gradients(npe, Xe, rst, dN);
  int n = 0;
  const auto put = [&](int j, double wt, const double* gr) {
    dof[n] = j, w[n] = wt;
    for (int d = 0; d < 3; ++d) g[3 * n + d] = gr[d];
    ++n;
  };
  for (int a = 0; a < npe; ++a) {
    put(nodes[a], N[a], &dN[3 * a]);
    const int q = P >= 0 && m.has_cuts() ? m.cuts.piece_enr[static_cast<size_t>(P) * npe + a] : -1;
    if (q >= 0) put(q, N[a], &dN[3 * a]);
  }
  if (!element_has_branch(m, e)) return n;
  double phi[10], psi[10], ph = 0, ps = 0, gph[3] = {0, 0, 0}, gps[3] = {0, 0, 0};
  front_node_values(m, e, phi, psi);
  for (int a = 0; a < npe; ++a) {
    ph += N[a] * phi[a], ps += N[a] * psi[a];
    for (int d = 0; d < 3; ++d) gph[d] += dN[3 * a + d] * phi[a], gps[d] += dN[3 * a + d] * psi[a];
  }
  const BranchValue F = side != 0 ? branch_function(side * std::abs(ph), ps, side) : branch_function(ph, ps);
  for (int a = 0; a < npe; ++a) {
    const int b = m.cuts.node_branch[nodes[a]];
    if (b < 0) continue;
    const BranchValue Fa = branch_function(phi[a], psi[a]);
    for (int k = 0; k < kBranchFunctions; ++k) {
      double gr[3];
      for (int d = 0; d < 3; ++d)
        gr[d] = dN[3 * a + d] * (F.F[k] - Fa.F[k]) + N[a] * (F.dphi[k] * gph[d] + F.dpsi[k] * gps[d]);
      put(b + k, N[a] * (F.F[k] - Fa.F[k]), gr);
    }
  }
  return n;
}

// Whether element e is split into the same sub-tetrahedra, piece by piece,
// in both models (enriched DOF node ids may differ).
bool same_subtets(const Model& a, const Model& b, int e) {
  const auto pieces = [](const Model& m, int e) {
    return m.has_cuts() ? m.cuts.elem_piece_ptr[e + 1] - m.cuts.elem_piece_ptr[e] : 1;
  };
  if (!a.has_cuts() || !b.has_cuts()) return pieces(a, e) == 1 && pieces(b, e) == 1 && !(a.has_cuts() && a.cuts.elem_split[e]) &&
                                              !(b.has_cuts() && b.cuts.elem_split[e]);
  const CutLayout &A = a.cuts, &B = b.cuts;
  if (pieces(a, e) != pieces(b, e)) return false;
  for (int k = 0; k < pieces(a, e); ++k) {
    const int P = A.elem_piece_ptr[e] + k, Q = B.elem_piece_ptr[e] + k;
    const int n = A.piece_subtet_ptr[P + 1] - A.piece_subtet_ptr[P];
    if (n != B.piece_subtet_ptr[Q + 1] - B.piece_subtet_ptr[Q]) return false;
    if (!std::equal(A.subtet_rst.begin() + 12 * static_cast<size_t>(A.piece_subtet_ptr[P]),
                    A.subtet_rst.begin() + 12 * static_cast<size_t>(A.piece_subtet_ptr[P + 1]),
                    B.subtet_rst.begin() + 12 * static_cast<size_t>(B.piece_subtet_ptr[Q])))
      return false;
  }
  return true;
}

// Whether the elements S (in_s) have the same pieces and the same fronts
// (branch DOF nodes and level sets at their nodes) in both models: then the
// old field is the new one with the same nodal and branch values.
bool same_fronts(const Model& from, const Model& to, const std::vector<char>& in_s) {
  if (!from.cuts.has_branch() || !to.cuts.has_branch()) return false;
  const int npe = to.mesh.npe();
  for (int e = 0; e < to.nelem; ++e) {
    if (!in_s[e]) continue;
    if (!same_subtets(from, to, e)) return false;
    for (int a = 0; a < npe; ++a) {
      const int i = to.mesh.tet[static_cast<size_t>(e) * npe + a];
      if ((from.cuts.node_branch[i] >= 0) != (to.cuts.node_branch[i] >= 0) ||
          from.cuts.front_phi[i] != to.cuts.front_phi[i] || from.cuts.front_psi[i] != to.cuts.front_psi[i])
        return false;
    }
  }
  return true;
}

// Near enriched fronts, old or new, the new model's DOFs by a local
// projection of the old field (after the nodal transfer, which is exact
// elsewhere), over the elements S holding a branch DOF node in either model,
// for the DOF nodes (standard, enriched, branch) of the mesh nodes whose
// elements all lie in S; the nodes on S's boundary keep their nodal values,
// which the old field takes there exactly (its branch part vanishes outside
// S), so the field stays continuous:
//   u:         min 1/2 int_S eps(e) : C : eps(e) + beta (lambda + 2 mu) |e|^2,
//              e = u_new - u_old  (the energy norm: 3 x 3 blocks)
//   v, a, du:  min int_S |f_new - f_old|^2  (L2, one scalar system)
// beta = 1e-2 / h^2 (h: the cube root of S's mean element volume) makes the
// problem definite where S holds a whole free piece.
// Where S keeps its sub-tetrahedra and fronts (another cut's rebuild) the
// DOFs copy over one by one, exactly (same_fronts); face-snapped ->
// enriched at the same front comes back exactly too (the new space contains
// the old). Otherwise the old sqrt(r) is not in the new space and this is
// its best fit: a second cut through an enriched slit's front elements
// (which takes that front to faces) changed the energy by 0.21 of the
// gravity work, against 2.6 before (branch DOFs dropped by node, 4-point
// rule; 1.7 by node with the 27-point rule; FrontEnrichment.ASecondCut...).
// Points: branch_cubature on every sub-tetrahedron of the new pieces; the
// old piece is looked up once per sub-tetrahedron (new pieces lie inside
// old ones: cuts only grow); the branch functions take the sign of phi at
// each point, as the model's gradients do (a sub-tetrahedron ahead of the
// front may straddle the plane: 18 of 861 in the slit of the tests).
void project_near_fronts(const Model& from, const State& os, const Model& to, int nf, Kinematics& ns) {
  if (!from.cuts.has_branch() && !to.cuts.has_branch()) return;
  const int npe = to.mesh.npe(), nnode = to.nnode;
  std::vector<char> in_s(to.nelem, 0), fixed(nnode, 0);
  double vol = 0;
  int ns_elem = 0;
  for (int e = 0; e < to.nelem; ++e) in_s[e] = element_has_branch(from, e) || element_has_branch(to, e);
  for (int e = 0; e < to.nelem; ++e) {
    if (in_s[e]) vol += to.elem_volume[e], ++ns_elem;
    if (!in_s[e])
      for (int a = 0; a < npe; ++a) fixed[to.mesh.tet[static_cast<size_t>(e) * npe + a]] = 1;
  }
  if (ns_elem == 0) return;
  if (same_fronts(from, to, in_s)) {
    // Another cut's rebuild: S's DOFs copy over one by one (mesh nodes to
    // themselves, enriched ones by dofnode_map, branch ones by node), exact.
    const std::vector<int> map = dofnode_map(from, to);
    const std::vector<double>* oldf[4] = {&os.u, &os.v, &os.a, &os.du};
    std::vector<double>* newf[4] = {&ns.u, &ns.v, &ns.a, &ns.du};
    for (int e = 0; e < to.nelem; ++e)
      for (int k = to.elem_dof_ptr[e]; in_s[e] && k < to.elem_dof_ptr[e + 1]; ++k) {
        const int j = to.elem_dof_node[k], i = j < nnode ? j : to.cuts.enr_node[j - nnode];
        const int b = to.cuts.node_branch[i], o = b >= 0 && j >= b && j < b + kBranchFunctions
                                                     ? from.cuts.node_branch[i] + (j - b)
                                                     : map[j];
        if (o < 0) continue;
        for (int f = 0; f < nf; ++f)
          for (int d = 0; d < 3; ++d) (*newf[f])[3 * j + d] = (*oldf[f])[3 * o + d];
      }
    return;
  }
  const double beta = 1e-2 / std::pow(vol / ns_elem, 2.0 / 3.0);
  std::vector<int> col(to.ndofnode, -1), node_of;  // free DOF node -> unknown index
  for (int e = 0; e < to.nelem; ++e)
    for (int k = to.elem_dof_ptr[e]; in_s[e] && k < to.elem_dof_ptr[e + 1]; ++k) {
      const int j = to.elem_dof_node[k], i = j < nnode ? j : to.cuts.enr_node[j - nnode];
      if (fixed[i] || col[j] >= 0) continue;
      col[j] = static_cast<int>(node_of.size());
      node_of.push_back(j);
    }
  const int nu = static_cast<int>(node_of.size());
  if (nu == 0) return;
  const std::vector<double>* oldf[4] = {&os.u, &os.v, &os.a, &os.du};
  std::vector<double>* newf[4] = {&ns.u, &ns.v, &ns.a, &ns.du};
  Eigen::MatrixXd Ru = Eigen::MatrixXd::Zero(3 * nu, 1), Rm = Eigen::MatrixXd::Zero(nu, 3 * (nf - 1));
  std::vector<Eigen::Triplet<double>> Mt, Kt;  // (nu, nu) L2, (3 nu, 3 nu) elastic matrices
  const double stiff = to.lambda + 2 * to.mu;
  const Cubature& cub = branch_cubature();
  const CutLayout& L = to.cuts;
  double Xe[30];
  std::vector<double> Me, Ke;
  std::vector<int> loc(to.ndofnode, -1);
  for (int e = 0; e < to.nelem; ++e) {
    if (!in_s[e]) continue;
    const int* nodes = &to.mesh.tet[static_cast<size_t>(e) * npe];
    for (int a = 0; a < npe; ++a)
      for (int d = 0; d < 3; ++d) Xe[3 * a + d] = to.mesh.X[3 * nodes[a] + d];
    // Local matrices over the element's DOF nodes (loc: DOF node -> local index).
    const int d0 = to.elem_dof_ptr[e], nl = to.elem_dof_ptr[e + 1] - d0;
    for (int i = 0; i < nl; ++i) loc[to.elem_dof_node[d0 + i]] = i;
    Me.assign(static_cast<size_t>(nl) * nl, 0.0);
    Ke.assign(9 * static_cast<size_t>(nl) * nl, 0.0);
    for (int P = L.elem_piece_ptr[e]; P < L.elem_piece_ptr[e + 1]; ++P)
      for (int t = L.piece_subtet_ptr[P]; t < L.piece_subtet_ptr[P + 1]; ++t) {
        const double* v = &L.subtet_rst[12 * static_cast<size_t>(t)];
        double c[3] = {0, 0, 0};
        for (int k = 0; k < 4; ++k)
          for (int d = 0; d < 3; ++d) c[d] += 0.25 * v[3 * k + d];
        const int old_piece = from.has_cuts() ? piece_containing(from, e, c) : -1;
        {
          const double* sub = v;
          const double vol6 = 6.0 * std::abs(subtet_ref_volume(sub));
          for (int q = 0; q < cub.npoint(); ++q) {
            double rst[3], detJ = 0, det_old = 0;
            map_to_element(sub, &cub.rst[3 * q], rst);
            int dof[kMaxWeights], dof_old[kMaxWeights];
            double w[kMaxWeights], g[3 * kMaxWeights], w_old[kMaxWeights], g_old[3 * kMaxWeights];
            // (side 0: the sign of phi at the point, as the model's own
            // gradients take it, model_build.cpp add_branch_gradients)
            const int n = field_basis(to, e, P, rst, 0, Xe, dof, w, g, &detJ);
            const int n_old = field_basis(from, e, old_piece, rst, 0, Xe, dof_old, w_old, g_old, &det_old);
            const double wq = cub.weight[q] * vol6 * detJ;
            for (int k = 0; k < nf; ++k) {
              // The old field less the new one with the nodal values: value
              // (3) and gradient (3 x 3); the systems solve for the change.
              double r[3] = {0, 0, 0}, gr[9] = {0};
              const double* f = oldf[k]->data();
              for (int j = 0; j < n_old; ++j)
                for (int d = 0; d < 3; ++d) {
                  r[d] += w_old[j] * f[3 * dof_old[j] + d];
                  for (int x = 0; x < 3; ++x) gr[3 * d + x] += g_old[3 * j + x] * f[3 * dof_old[j] + d];
                }
              const double* fn = newf[k]->data();
              for (int j = 0; j < n; ++j)
                for (int d = 0; d < 3; ++d) {
                  r[d] -= w[j] * fn[3 * dof[j] + d];
                  for (int x = 0; x < 3; ++x) gr[3 * d + x] -= g[3 * j + x] * fn[3 * dof[j] + d];
                }
              // u: the stress of the residual, sigma = lambda tr(G) I + mu (G + G^T).
              double sig[9];
              if (k == 0) {
                const double tr = gr[0] + gr[4] + gr[8];
                for (int d = 0; d < 3; ++d)
                  for (int x = 0; x < 3; ++x)
                    sig[3 * d + x] = to.mu * (gr[3 * d + x] + gr[3 * x + d]) + (d == x ? to.lambda * tr : 0.0);
              }
              for (int j = 0; j < n; ++j) {
                const int i = col[dof[j]];
                if (i < 0) continue;
                for (int d = 0; d < 3; ++d) {
                  if (k == 0) {
                    double h1 = beta * stiff * w[j] * r[d];
                    for (int x = 0; x < 3; ++x) h1 += g[3 * j + x] * sig[3 * d + x];
                    Ru(3 * i + d, 0) += wq * h1;
                  } else {
                    Rm(i, 3 * (k - 1) + d) += wq * w[j] * r[d];
                  }
                }
              }
            }
            for (int a = 0; a < n; ++a) {
              const int i = loc[dof[a]];
              if (col[dof[a]] < 0) continue;
              for (int b = 0; b < n; ++b) {
                const int j = loc[dof[b]];
                if (col[dof[b]] < 0) continue;
                Me[i * nl + j] += wq * w[a] * w[b];
                // the elasticity block of (a, b): lambda g_a g_b^T + mu (g_b g_a^T + (g_a . g_b) I)
                const double* ga = &g[3 * a];
                const double* gb = &g[3 * b];
                const double dot = ga[0] * gb[0] + ga[1] * gb[1] + ga[2] * gb[2];
                for (int c = 0; c < 3; ++c)
                  for (int d = 0; d < 3; ++d)
                    Ke[(3 * i + c) * 3 * nl + 3 * j + d] +=
                        wq * (to.lambda * ga[c] * gb[d] + to.mu * (ga[d] * gb[c] + (c == d ? dot : 0.0)) +
                              (c == d ? beta * stiff * w[a] * w[b] : 0.0));
              }
            }
          }
        }
      }
    for (int i = 0; i < nl; ++i)
      for (int j = 0; j < nl; ++j) {
        const int ci = col[to.elem_dof_node[d0 + i]], cj = col[to.elem_dof_node[d0 + j]];
        if (ci < 0 || cj < 0) continue;
        Mt.emplace_back(ci, cj, Me[i * nl + j]);
        for (int c = 0; c < 3; ++c)
          for (int d = 0; d < 3; ++d) Kt.emplace_back(3 * ci + c, 3 * cj + d, Ke[(3 * i + c) * 3 * nl + 3 * j + d]);
      }
    for (int i = 0; i < nl; ++i) loc[to.elem_dof_node[d0 + i]] = -1;
  }
  Eigen::SparseMatrix<double> M(nu, nu), H(3 * nu, 3 * nu);
  M.setFromTriplets(Mt.begin(), Mt.end());
  H.setFromTriplets(Kt.begin(), Kt.end());
  // Each solved for the change from the nodal values, with a 1e-10 relative diagonal shift (a DOF of a
  // sliver piece, a near-null combination of branch functions stays near
  // its nodal value) and two refinement steps on the unshifted system.
  const auto solve = [&](const Eigen::SparseMatrix<double>& A, const Eigen::MatrixXd& R, Eigen::MatrixXd* D) {
    Eigen::SparseMatrix<double> As = A;
    double dmax = 0;
    for (int i = 0; i < A.rows(); ++i) dmax = std::max(dmax, A.coeff(i, i));
    for (int i = 0; i < A.rows(); ++i) As.coeffRef(i, i) += 1e-10 * A.coeff(i, i) + 1e-14 * dmax;
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(As);
    if (ldlt.info() != Eigen::Success) return false;
    *D = ldlt.solve(R);
    for (int it = 0; it < 2; ++it) *D += ldlt.solve(R - A * *D);
    return D->allFinite();
  };
  Eigen::MatrixXd Du, Dm;
  const bool ok_u = solve(H, Ru, &Du), ok_m = nf < 2 || solve(M, Rm, &Dm);
  for (int j = 0; j < nu; ++j)
    for (int d = 0; d < 3; ++d) {
      if (ok_u) (*newf[0])[3 * node_of[j] + d] += Du(3 * j + d, 0);
      for (int k = 1; ok_m && k < nf; ++k) (*newf[k])[3 * node_of[j] + d] += Dm(j, 3 * (k - 1) + d);
    }
}

Kinematics transfer_kinematics(const Model& from, const State& os, const Model& to) {
  Kinematics ns;
  const int n = to.ndof(), nstd = 3 * to.nnode, npe = to.mesh.npe();
  ns.u.assign(os.u.begin(), os.u.begin() + nstd);
  ns.v.assign(os.v.begin(), os.v.begin() + nstd);
  ns.a.assign(os.a.begin(), os.a.begin() + nstd);
  const int nf = os.du.size() == static_cast<size_t>(from.ndof()) ? 4 : 3;  // du too, when the old state has it
  if (nf == 4) ns.du.assign(os.du.begin(), os.du.begin() + nstd);
  for (auto* f : {&ns.u, &ns.v, &ns.a}) f->resize(n, 0.0);
  if (nf == 4) ns.du.resize(n, 0.0);
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
        const int side = front_side(from, e, rst);
        for (int a = 0; a < npe; ++a) {
          const int q = L.piece_enr[static_cast<size_t>(P) * npe + a];
          if ((pass == 0) != (q < 0)) continue;
          const int i = to.mesh.tet[static_cast<size_t>(e) * npe + a];
          // The old opening at a node that keeps branch DOFs stays in them
          // (fitted below, project_branch_dofs); at one that loses them it
          // goes to u and q here.
          const bool keeps_branch = L.has_branch() && L.node_branch[i] >= 0;
          double val[12];
          old_piece_values(from, os, e, Q, a, nf, keeps_branch ? 0 : side, val);
          std::vector<double>* f[4] = {&ns.u, &ns.v, &ns.a, &ns.du};
          for (int k = 0; k < nf; ++k)
            for (int c = 0; c < 3; ++c) {
              if (q < 0) (*f[k])[3 * i + c] = val[3 * k + c];
              else (*f[k])[3 * q + c] = val[3 * k + c] - (*f[k])[3 * i + c];
            }
        }
      }
    }
  project_near_fronts(from, os, to, nf, ns);
  return ns;
}

CutUpdate update_cuts(Simulation& sim, double t, double t_sweep, bool swept_changed) {
  Stopwatch clock;
  bool changed = false;
  const std::vector<double> progress = progress_at(sim, t, t_sweep, &changed);
  PreparedCut p;
  const bool ahead = take_ahead(sim, progress, t_sweep, sim.state.swept_tool.size(), &p);
  if (!changed && !swept_changed) return {};
  if (!ahead) p = prepare_cut(sim, progress, t_sweep, sim.state.swept, sim.state.swept_tool);
  CutUpdate up = commit_cut(sim, std::move(p), clock);
  up.ahead = ahead;
  return up;
}

CutUpdate apply_all_cuts(Simulation& sim) {
  warn_cuts_that_cut_nothing(sim);
  std::vector<double> progress(sim.scene.cuts.size(), 1.0);
  double t_end = 0.0;
  for (const CutSpec& c : sim.scene.cuts) t_end = std::max(t_end, c.at_time + c.duration);
  PreparedCut dropped;
  take_ahead(sim, {}, 0.0, 0, &dropped);
  Stopwatch clock;
  return commit_cut(sim, prepare_cut(sim, progress, t_end, sim.state.swept, sim.state.swept_tool), clock);
}

}  // namespace incise

namespace incise {

std::vector<std::string> cuts_that_cut_nothing(const Simulation& sim) {
  std::vector<std::string> out;
  for (const CutSpec& c : sim.scene.cuts) {
    // The complete surface (a swept cut at the end of its sweep), alone.
    const auto surf = make_cut_surface(c, c.at_time + c.duration);
    CutReport rep;
    if (surf) compute_cut_layout(sim.model, {surf.get()}, &rep);
    if (!surf || (rep.cut_elements == 0 && rep.front_elements == 0 && rep.separated_faces == 0))
      out.push_back((sim.scene.path.empty() ? std::string() : sim.scene.path + ": ") + c.json_path +
                    " does not cross the body: it cuts nothing");
  }
  return out;
}

void warn_cuts_that_cut_nothing(const Simulation& sim) {
  for (const std::string& w : cuts_that_cut_nothing(sim)) std::fprintf(stderr, "warning: %s\n", w.c_str());
  for (const std::string& w : fronts_left_on_faces(sim)) std::fprintf(stderr, "warning: %s\n", w.c_str());
}

std::vector<std::string> fronts_left_on_faces(const Simulation& sim) {
  std::vector<std::string> out;
  if (!sim.scene.front_enrichment) return out;
  std::vector<std::unique_ptr<CutSurface>> owned;
  std::vector<const CutSurface*> surfaces;
  std::vector<const CutSpec*> spec;
  for (const CutSpec& c : sim.scene.cuts)  // each complete (a swept cut at the end of its sweep)
    if (auto s = make_cut_surface(c, c.at_time + c.duration)) {
      surfaces.push_back(s.get());
      owned.push_back(std::move(s));
      spec.push_back(&c);
    }
  if (surfaces.empty()) return out;
  CutReport rep;
  compute_cut_layout(sim.model, surfaces, &rep, true);
  for (int k : rep.fronts_on_faces)
    out.push_back((sim.scene.path.empty() ? std::string() : sim.scene.path + ": ") + spec[k]->json_path +
                  ": its front stays on element faces: it lies a few elements from an earlier cut's enriched "
                  "front, or in an element another cut splits (cut_front \"enriched\", docs/cutting.md)");
  return out;
}

}  // namespace incise
