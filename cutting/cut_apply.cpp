#include "cutting/cut_apply.h"

#include "cutting/front_transfer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <map>
#include <memory>
#include <set>
#include <thread>

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
  std::vector<double> blade_done;  // the State::blade_done it was prepared with
  std::vector<std::string> faces_strokes;  // finished scalpel strokes whose fronts stay on faces (warned once)
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

// A group of a scalpel's strokes that make one surface: its ranges of the
// tool's triangles, whether all of them are finished, and its name.
struct StrokeGroup {
  std::vector<std::pair<size_t, size_t>> ranges;
  bool finished = true;
  std::string label;                     // "stroke 2", "strokes 1, 3"
  std::unique_ptr<CutSurface> surface;   // a one-stroke group's, made while grouping (else null)
};

// Scalpel `tool`'s strokes (blade_done: (nstroke, 2) (tool, triangles at its
// end); after the last, the stroke in progress), grouped: two strokes with
// a corner of one within `reach` of the other are in one group, in the
// order of their first stroke. Without strokes, one group of all (not
// finished): the whole incision on faces.
std::vector<StrokeGroup> stroke_groups(const std::vector<double>& swept, const std::vector<double>& swept_tool,
                                       const std::vector<double>& blade_done, int tool, const std::string& name,
                                       double reach) {
  std::vector<std::pair<size_t, size_t>> ranges;  // the strokes, the last one in progress
  size_t begin = 0;
  for (size_t k = 0; k + 1 < blade_done.size(); k += 2)
    if (blade_done[k] == double(tool)) {
      ranges.emplace_back(begin, static_cast<size_t>(blade_done[k + 1]));
      begin = ranges.back().second;
    }
  const size_t finished = ranges.size();
  ranges.emplace_back(begin, SIZE_MAX);
  if (ranges.size() == 1) {  // (no surface built to group)
    std::vector<StrokeGroup> one(1);
    one[0].ranges = ranges;
    one[0].finished = false;
    one[0].label = "stroke 1";
    return one;
  }
  std::vector<std::unique_ptr<CutSurface>> part(ranges.size());
  for (size_t r = 0; r < ranges.size(); ++r) part[r] = make_swept_surface(swept, swept_tool, tool, name, {ranges[r]});
  std::vector<size_t> root(ranges.size());
  for (size_t r = 0; r < root.size(); ++r) root[r] = r;
  const auto find = [&](size_t r) {
    while (root[r] != r) r = root[r] = root[root[r]];
    return r;
  };
  // Whether a corner of b's facets lies within reach of a.
  const auto near = [&](const CutSurface& a, const CutSurface& b) {
    for (const Facet& f : b.facets())
      for (const Vec3& v : f.v)
        if (a.distance(v.data()) <= reach) return true;
    return false;
  };
  for (size_t b = 1; b < ranges.size(); ++b)
    for (size_t a = 0; a < b; ++a)
      if (part[a] && part[b] && find(a) != find(b) && (near(*part[a], *part[b]) || near(*part[b], *part[a])))
        root[find(b)] = find(a);
  std::vector<StrokeGroup> groups;
  std::vector<int> group_of(ranges.size(), -1);
  for (size_t r = 0; r < ranges.size(); ++r) {
    int& g = group_of[find(r)];
    if (g < 0) {
      g = static_cast<int>(groups.size());
      groups.emplace_back();
    }
    StrokeGroup& G = groups[g];
    G.ranges.push_back(ranges[r]);
    if (r >= finished) G.finished = false;
    G.label += (G.label.empty() ? "" : ", ") + std::to_string(r + 1);
  }
  for (size_t r = 0; r < ranges.size(); ++r) {
    StrokeGroup& G = groups[group_of[find(r)]];
    if (G.ranges.size() == 1) G.surface = std::move(part[r]);
  }
  for (StrokeGroup& G : groups) G.label = (G.ranges.size() > 1 ? "strokes " : "stroke ") + G.label;
  return groups;
}

// swept, swept_tool, blade_done: the instruments' swept triangles the update
// includes and the scalpels' finished strokes (State::swept...; the
// cut-ahead helper passes its own copies: it must not read the State the
// stages change). spare: a model no longer needed, storage for the new one
// (build_model).
PreparedCut prepare_cut(const Simulation& sim, const std::vector<double>& progress, double t_sweep,
                        const std::vector<double>& swept, const std::vector<double>& swept_tool,
                        const std::vector<double>& blade_done, Model* spare = nullptr) {
  PreparedCut p;
  p.progress = progress;
  p.swept = swept_tool.size();
  p.blade_done = blade_done;
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
  // A scalpel's incision likewise: on faces while the blade is in the
  // tissue, enriched once it is out (State::blade_done: the strokes so far
  // are done, their front lines no longer move). When the blade goes in
  // again elsewhere, the new stroke is another surface, on faces, and the
  // finished ones keep their enriched fronts (unchanged): taking an
  // enriched front back to faces (project_near_fronts) changes the energy
  // by 0.2-0.5 of the gravity work. Back in (or beside) its own incision,
  // it joins that stroke's surface, which goes back to faces until the
  // blade is out again (stroke_groups).
  // Enriched while the blade merely rests (twenty-first session, measured
  // and withdrawn): the incision's bottom front line stays in the same
  // elements while the blade cuts on, so the rested front either froze
  // there or had to be carried to faces through the whole incision's ring
  // at every rebuild (docs/cutting.md, "The element at the cut front").
  std::vector<char> branch;
  std::vector<std::string> stroke;  // (surfaces) a finished stroke's name, "" for the others
  for (size_t k = 0; k < sim.scene.cuts.size(); ++k) {
    if (progress[k] <= 0.0) continue;
    auto s = make_cut_surface(sim.scene.cuts[k], t_sweep);
    if (!s) continue;
    surfaces.push_back(s.get());
    owned.push_back(std::move(s));
    branch.push_back(sim.scene.front_enrichment && progress[k] >= 1.0);
    stroke.emplace_back();
  }
  const double h = blade_done.empty() ? 0.0 : mean_element_size(sim.model);  // strokes closer are one surface
  for (size_t i = 0; i < sim.scene.instruments.size(); ++i) {
    // A scalpel's strokes (State::blade_done; the last one in progress) in
    // groups, each a surface: strokes within an element of each other are
    // one (a blade back in its own incision: two coincident surfaces there
    // made sliver pieces that spun, 3 rad a frame, on organ_10k). A group
    // whose strokes are all finished has its front enriched; the one the
    // blade is cutting keeps its front on faces. Without cut_front
    // "enriched" (no strokes recorded) one surface, on faces.
    const std::string& name = sim.scene.instruments[i].json_path;
    for (StrokeGroup& g : stroke_groups(swept, swept_tool, blade_done, static_cast<int>(i), name, h)) {
      auto s = g.surface ? std::move(g.surface) : make_swept_surface(swept, swept_tool, static_cast<int>(i), name, g.ranges);
      if (!s) continue;
      surfaces.push_back(s.get());
      owned.push_back(std::move(s));
      branch.push_back(sim.scene.front_enrichment && g.finished);
      stroke.push_back(g.finished ? name + " " + g.label : std::string());
    }
  }
  if (surfaces.empty()) return p;
  Stopwatch part;
  CutLayout layout = compute_cut_layout(sim.model, surfaces, &p.report, branch);
  p.layout_ms = part.lap();
  for (int c : p.report.fronts_on_faces)
    if (!stroke[c].empty()) p.faces_strokes.push_back(stroke[c]);
  if (same_layout(sim.model, layout) || (!sim.model.has_cuts() && layout.n_enriched == 0 && p.report.cut_elements == 0))
    return p;
  p.next = std::make_unique<Model>(build_model(sim.mesh, sim.scene, &layout, &sim.model, spare));
  for (int e = 0; e < p.next->nelem; ++e)
    if (!same_element_pieces(*p.next, sim.model, e)) p.changed.push_back(e);
  p.map = dofnode_map(sim.model, *p.next);
  p.plan = make_assembly_plan(*p.next, std::max(1, sim.ws.runtime.threads));
  p.rebuild = true;
  p.model_ms = part.lap();
  return p;
}

// A finished scalpel stroke whose front the layout keeps on faces (beside
// an earlier enriched front, or in an element another cut splits) is named
// once a run, as fronts_left_on_faces names a scene cut's. The names seen
// live in sim.module_data[kStageCutting].
void warn_strokes_on_faces(Simulation& sim, const std::vector<std::string>& strokes) {
  if (strokes.empty()) return;
  auto& slot = sim.module_data[kStageCutting];
  if (!slot) slot = std::make_shared<std::set<std::string>>();
  auto& warned = *static_cast<std::set<std::string>*>(slot.get());
  for (const std::string& s : strokes)
    if (warned.insert(s).second)
      std::fprintf(stderr,
                   "warning: %s%s: its front stays on element faces: it lies a few elements from an earlier cut's "
                   "enriched front, or in an element another cut splits (cut_front \"enriched\", docs/cutting.md)\n",
                   sim.scene.path.empty() ? "" : (sim.scene.path + ": ").c_str(), s.c_str());
}

// Applies a prepared update: the new model, the kinematics and rotations
// carried over, the solver set up for the new pattern, the acceleration.
CutUpdate commit_cut(Simulation& sim, PreparedCut p, Stopwatch& clock) {
  warn_strokes_on_faces(sim, p.faces_strokes);
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
  // The instruments' force of the last frame on the new DOFs (mesh nodes
  // keep theirs; an old enriched node's goes to the first new one mapped to
  // it), for the acceleration below.
  std::vector<double> contact_force;
  if (sim.ws.contact_force.size() == static_cast<size_t>(sim.model.ndof())) {
    contact_force.assign(next.ndof(), 0.0);
    std::vector<char> given(sim.model.ndofnode, 0);
    for (int q = 0; q < next.ndofnode; ++q) {
      const int o = p.map[q];
      if (o < 0 || given[o]) continue;
      given[o] = 1;
      for (int c = 0; c < 3; ++c) contact_force[3 * q + c] = sim.ws.contact_force[3 * o + c];
    }
  }
  const bool severed = next.cuts.bodies != sim.model.cuts.bodies;
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
  // Freed by the next cut-ahead task, off this thread, or before a
  // scalpel's next cut is built (prepare_cut_now).
  sim.retired_model = std::move(old_model);
  up.part_ms[kCutSolverSetup] = part.lap();
  // The acceleration consistent with the new model near the elements the cut
  // changed; the whole body's when the cut severs a piece. Newmark's
  // acceleration carries each step's Newton residual (M a differs from
  // f_ext - f_int - D v), a field that sums to ~0 over a body but not over a
  // piece the cut severs: kept on the piece, it is a net force on it (a stiff
  // beam's severed end, E = 1e8 Pa, was shot off at 2.9 m/s). Not always the
  // whole body's: 3.1 ms more a cut frame on the 10k incision, and beside a
  // probe it cost cut frames a second Newton iteration (docs/benchmarks.md).
  if (severed) consistent_acceleration(sim.model, st, sim.ws, contact_force.empty() ? nullptr : &contact_force);
  else consistent_acceleration_near(sim.model, st, sim.ws, p.changed);
  // A severed piece is released with the stress that held it, a jump in the
  // forcing that Newmark's rule, which damps nothing, would ring on: the
  // step after the cut is a recovery step (backward Euler, State::recovery;
  // docs/numerics.md, "Recovery steps"). A soft beam severed while it swung
  // blew up without it (nu 0.3-0.499, either tangent). Not for a body at
  // rest (u = v = 0: a scene's cut before the first step): nothing is
  // released, and its pieces then fall exactly as Newmark's rule has them.
  const auto moving = [](const std::vector<double>& x) {
    return std::any_of(x.begin(), x.end(), [](double y) { return y != 0.0; });
  };
  if (severed && (moving(st.u) || moving(st.v))) st.recovery = true;
  up.part_ms[kCutAcceleration] = part.lap();
  up.changed = true;
  up.ms = clock.ms();
  return up;
}

// The next frame's cut update, prepared on a helper thread during this
// frame's step (Simulation::cut_ahead).
struct CutAhead {
  PreparedCut result;
  bool early = false;  // this frame's update, prepared beside its collision stage (prepare_cut_now)
  std::exception_ptr error;
  std::vector<double> swept, swept_tool, blade_done;  // copies of the State's, for the helper
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
bool take_ahead(Simulation& sim, const std::vector<double>& progress, double t_sweep, size_t swept, PreparedCut* out,
                bool* early = nullptr) {
  auto ahead = std::static_pointer_cast<CutAhead>(sim.cut_ahead);
  if (!ahead) return false;
  sim.cut_ahead.reset();
  if (sim.cut_helper) sim.cut_helper->wait();
  if (ahead->error) std::rethrow_exception(ahead->error);
  if (ahead->base_version != sim.model_version || ahead->progress != progress || ahead->t_sweep != t_sweep ||
      ahead->result.swept != swept || ahead->result.blade_done != sim.state.blade_done)
    return false;
  *out = std::move(ahead->result);
  if (early) *early = ahead->early;
  return true;
}

// Starts prepare_cut for the update of the frame at time t (swept cuts
// reaching t_sweep, the scene cuts at `progress`) on the cut helper, with
// copies of the State's swept triangles and finished strokes.
void launch_cut(Simulation& sim, std::vector<double> progress, double t_sweep) {
  auto ahead = std::make_shared<CutAhead>();
  ahead->swept = sim.state.swept;
  ahead->swept_tool = sim.state.swept_tool;
  ahead->blade_done = sim.state.blade_done;
  ahead->progress = std::move(progress);
  ahead->t_sweep = t_sweep;
  ahead->base_version = sim.model_version;
  CutAhead* a = ahead.get();
  const Simulation* s = &sim;
  const bool helper_cpus = sim.ws.runtime.split_affinity;
  if (!sim.cut_helper || sim.cut_helper->helper_cpus() != helper_cpus)
    sim.cut_helper = std::make_unique<HelperThread>(helper_cpus, HelperThread::Priority::Normal);  // (none running)
  // (retired moved in, not copied: a copy left here would keep its count
  // above 1 while the task may already run, and the spare would go unused.)
  sim.cut_helper->run([ahead, a, s, retired = std::move(sim.retired_model)]() mutable {  // (ahead: the task keeps its result alive)
    try {  // the model the last cut replaced: storage for the new one, then freed
      Model* spare = retired.use_count() == 1 ? retired.get() : nullptr;
      a->result = prepare_cut(*s, a->progress, a->t_sweep, a->swept, a->swept_tool, a->blade_done, spare);
    } catch (...) {
      a->error = std::current_exception();
    }
    retired.reset();
  });
  sim.cut_ahead = ahead;
}

}  // namespace

void start_cut_ahead(Simulation& sim, double t, double t_sweep) {
  PreparedCut dropped;
  take_ahead(sim, {}, 0.0, 0, &dropped);  // at most one helper
  bool changed = false;
  std::vector<double> progress = progress_at(sim, t, t_sweep, &changed);
  if (changed) launch_cut(sim, std::move(progress), t_sweep);
}

void prepare_cut_now(Simulation& sim, double t, double t_sweep) {
  PreparedCut dropped;
  take_ahead(sim, {}, 0.0, 0, &dropped);  // one prepared before this frame's sweep has the old triangles
  // The model the last cut replaced: its large arrays' storage goes to the
  // new model (build_model's spare), the rest is freed here (it went at the
  // commit). probe-incision-20k, 70 frames (54 cut): 172k page faults ->
  // 111k (perf stat -e page-faults), about 1.5 ms a cut frame.
  std::shared_ptr<Model> retired = std::move(sim.retired_model);
  auto now = std::make_shared<CutAhead>();
  bool changed = false;
  now->early = true;
  now->progress = progress_at(sim, t, t_sweep, &changed);
  now->t_sweep = t_sweep;
  now->base_version = sim.model_version;
  now->result = prepare_cut(sim, now->progress, t_sweep, sim.state.swept, sim.state.swept_tool, sim.state.blade_done,
                            retired.use_count() == 1 ? retired.get() : nullptr);
  sim.cut_ahead = now;
}


bool same_subtets(const Model& a, const Model& b, int e) {
  const auto pieces = [](const Model& m, int e) { return m.cuts.elem_piece_ptr[e + 1] - m.cuts.elem_piece_ptr[e]; };
  if (!a.has_cuts() || !b.has_cuts()) return false;
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
  // Two passes: home values (standard DOFs) first, then enriched = old - home.
  // An element without enrichment in either model has the old nodal values,
  // copied above: only the elements near the cuts are visited.
  //
  // Each old sub-tetrahedron lies in a new piece (the one holding its
  // centroid) and brings its old region's value at each node of the element
  // to that piece's DOF node there, weighted by its lumped mass at the node
  // (volume fraction times the element's HRZ mass, as model_build.cpp lumps
  // a piece); a DOF node takes the weighted mean: the lumped momentum
  // sum_R m_R v_R of every node is kept where the new pieces are unions of
  // old ones. Where the cuts only grew, all of a DOF node's values are one
  // region's. They are not always: a scalpel's bands are mapped through the
  // tissue frame by frame, so a separation of one frame can be gone in the
  // next, joining two old regions, and the one that barely reaches a node
  // holds a far extrapolation there (measured on the organ with a probe
  // beside its incision: 1.1 cm at a node whose tissue had moved 0.2 mm, a
  // region of 3.5e-4 of the node's mass). The old piece of one point of each
  // new piece used to give the values, the last piece visited writing the
  // node, and two frames later the organ blew up. A new region that no old
  // sub-tetrahedron's centroid falls in (a sliver) takes the old piece
  // holding its own sub-tetrahedra's centroids.
  std::vector<double> hrz(npe);
  const auto element_hrz = [&](int e) {  // HRZ lumped masses of e's nodes: rho V M_aa / tr M
    const double* M = &from.elem_mass[static_cast<size_t>(e) * npe * npe];
    double tr = 0.0, total = 0.0;
    for (int a = 0; a < npe; ++a) {
      tr += M[a * npe + a];
      for (int b = 0; b < npe; ++b) total += M[a * npe + b];
    }
    for (int a = 0; a < npe; ++a) hrz[a] = M[a * npe + a] * total / tr;
  };
  static const double kWhole[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  struct Sum {  // mass-weighted values brought to one new DOF node
    double mass = 0.0;
    double v[12] = {0};
  };
  std::map<int, Sum> found;  // new DOF node -> its sum (ordered: the same sums every run)
  std::vector<double>* f[4] = {&ns.u, &ns.v, &ns.a, &ns.du};
  // Adds old piece Q's value at node a of element e (side: the point's side
  // of an old front) to the new DOF node of new piece P there, with weight w.
  const auto bring = [&](int pass, int e, int P, int Q, int side, int a, double w) {
    const int q = L.piece_enr[static_cast<size_t>(P) * npe + a];
    if ((pass == 0) != (q < 0)) return;
    const int i = to.mesh.tet[static_cast<size_t>(e) * npe + a];
    // The old opening at a node that keeps branch DOFs stays in them (fitted
    // below, project_near_fronts); at one that loses them it goes to u and q.
    const bool keeps_branch = L.has_branch() && L.node_branch[i] >= 0;
    double val[12];
    old_piece_values(from, os, e, Q, a, nf, keeps_branch ? 0 : side, val);
    Sum& sum = found[q < 0 ? i : q];
    sum.mass += w;
    for (int k = 0; k < nf; ++k)
      for (int c = 0; c < 3; ++c) sum.v[3 * k + c] += w * (q < 0 ? val[3 * k + c] : val[3 * k + c] - (*f[k])[3 * i + c]);
  };
  const auto centroid = [](const double* v, double c[3]) {
    for (int d = 0; d < 3; ++d) c[d] = 0.25 * (v[d] + v[3 + d] + v[6 + d] + v[9 + d]);
  };
  // The (old piece, new piece, side) parts of the elements either model
  // enriches, with their volume fractions, found once for both passes: the
  // values are looked up once per part, not per sub-tetrahedron.
  struct Part {
    int e, Q, P, side;
    double frac;
  };
  std::vector<Part> parts;
  std::vector<char> visited(to.nelem, 0);
  for (int e = 0; e < to.nelem; ++e) {
    if (!enriched(to, e) && !enriched(from, e)) continue;
    visited[e] = 1;
    const size_t first = parts.size();
    const int q0 = from.has_cuts() ? from.cuts.elem_piece_ptr[e] : -1;
    const int q1 = from.has_cuts() ? from.cuts.elem_piece_ptr[e + 1] : 0;
    const bool same = same_subtets(from, to, e);  // (the usual element: no point location)
    for (int Q = q0; Q < q1 || (Q == -1 && q1 == 0); ++Q) {  // (-1: the old model had no cuts)
      const int t0 = Q >= 0 ? from.cuts.piece_subtet_ptr[Q] : 0, t1 = Q >= 0 ? from.cuts.piece_subtet_ptr[Q + 1] : 1;
      for (int t = t0; t < t1; ++t) {
        const double* v = Q >= 0 ? &from.cuts.subtet_rst[12 * static_cast<size_t>(t)] : kWhole;
        double c[3];
        centroid(v, c);
        const int P = same ? L.elem_piece_ptr[e] + (Q - q0) : piece_containing(to, e, c);
        const int side = front_side(from, e, c);
        const double frac = std::max(6.0 * std::abs(subtet_ref_volume(v)), 1e-12);  // (a degenerate one still counts)
        size_t k = first;
        while (k < parts.size() && !(parts[k].Q == Q && parts[k].P == P && parts[k].side == side)) ++k;
        if (k == parts.size()) parts.push_back({e, Q, P, side, 0.0});
        parts[k].frac += frac;
      }
      if (Q == -1) break;
    }
  }
  for (int pass = 0; pass < 2; ++pass) {
    found.clear();
    for (size_t k = 0; k < parts.size(); ++k) {
      const Part& part = parts[k];
      if (k == 0 || parts[k - 1].e != part.e) element_hrz(part.e);
      for (int a = 0; a < npe; ++a) bring(pass, part.e, part.P, part.Q, part.side, a, part.frac * hrz[a]);
    }
    if (pass == 0) {
      // A node's elements that neither model enriches are whole, in its home
      // region in both, with the values copied above.
      for (auto& [i, sum] : found)
        for (int k = to.node_elem_ptr[i]; k < to.node_elem_ptr[i + 1]; ++k) {
          const int e = to.node_elem[k];
          if (visited[e]) continue;
          element_hrz(e);
          const int* nodes = &to.mesh.tet[static_cast<size_t>(e) * npe];
          const double w = hrz[std::find(nodes, nodes + npe, i) - nodes];
          sum.mass += w;
          for (int kf = 0; kf < nf; ++kf)
            for (int c = 0; c < 3; ++c) sum.v[3 * kf + c] += w * (*f[kf])[3 * i + c];
        }
    } else {
      for (int e = 0; e < to.nelem; ++e)  // enriched DOF nodes no old sub-tetrahedron reached
        for (int P = visited[e] ? L.elem_piece_ptr[e] : 0; visited[e] && P < L.elem_piece_ptr[e + 1]; ++P)
          for (int a = 0; a < npe; ++a) {
            const int q = L.piece_enr[static_cast<size_t>(P) * npe + a];
            if (q < 0 || found.count(q)) continue;
            for (int t = L.piece_subtet_ptr[P]; t < L.piece_subtet_ptr[P + 1]; ++t) {
              double c[3];
              centroid(&L.subtet_rst[12 * static_cast<size_t>(t)], c);
              const int Q = from.has_cuts() ? piece_containing(from, e, c) : -1;
              bring(1, e, P, Q, front_side(from, e, c), a, 1.0);
            }
          }
    }
    for (const auto& [node, sum] : found)
      for (int k = 0; k < nf; ++k)
        for (int c = 0; c < 3; ++c) (*f[k])[3 * node + c] = sum.v[3 * k + c] / sum.mass;
  }
  project_near_fronts(from, os, to, nf, ns);
  return ns;
}

CutUpdate update_cuts(Simulation& sim, double t, double t_sweep, bool swept_changed) {
  Stopwatch clock;
  bool changed = false;
  const std::vector<double> progress = progress_at(sim, t, t_sweep, &changed);
  PreparedCut p;
  bool early = false;
  const bool ahead = take_ahead(sim, progress, t_sweep, sim.state.swept_tool.size(), &p, &early);
  if (!changed && !swept_changed) return {};
  if (!ahead) p = prepare_cut(sim, progress, t_sweep, sim.state.swept, sim.state.swept_tool, sim.state.blade_done);
  CutUpdate up = commit_cut(sim, std::move(p), clock);
  up.ahead = ahead && !early;
  up.early = ahead && early;
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
  return commit_cut(sim, prepare_cut(sim, progress, t_end, sim.state.swept, sim.state.swept_tool, sim.state.blade_done), clock);
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
