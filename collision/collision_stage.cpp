#include "collision/collision_stage.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "collision/face_contact.h"
#include "collision/narrowphase.h"
#include "engine/model/tissue_locator.h"
#include "engine/runtime/trajectory.h"
#include "engine/util/error.h"

namespace incise {

namespace {

// Probes that push and every grasper (it holds even without contact rows).
bool touches(const InstrumentSpec& s) {
  return s.kind == InstrumentSpec::Kind::Grasper || (s.kind == InstrumentSpec::Kind::Probe && s.contact);
}

// The instrument as the query sees it: a probe inflated by its margin.
InstrumentSpec inflated(const InstrumentSpec& s, double margin) {
  InstrumentSpec t = s;
  if (t.kind == InstrumentSpec::Kind::Probe) t.radius += margin;
  return t;
}

double contact_margin(const InstrumentSpec& s) {
  return s.kind == InstrumentSpec::Kind::Probe ? kContactMarginShare * s.radius : 0.0;
}

// Triangle tri's unit outward normal at the surface's positions (zero for
// a degenerate triangle).
Eigen::Vector3d triangle_outward(const TissueSurface& s, int tri) {
  const int* tv = &s.tri[3 * static_cast<size_t>(tri)];
  Eigen::Vector3d v[3];
  for (int j = 0; j < 3; ++j) v[j] = Eigen::Vector3d(s.x[3 * tv[j]], s.x[3 * tv[j] + 1], s.x[3 * tv[j] + 2]);
  const Eigen::Vector3d n = (v[1] - v[0]).cross(v[2] - v[0]);
  return n.norm() > 0 ? Eigen::Vector3d(n.normalized()) : Eigen::Vector3d::Zero();
}

// cd.sweep_face with the faces instrument i's end pose already has a
// contact on marked: the sweep and the speculative rows add only others.
std::vector<unsigned char>& faces_found(CollisionData& cd, size_t i) {
  std::vector<unsigned char>& seen = cd.sweep_face;
  seen.assign(cd.model.surface().nface, 0);
  for (const TissueContact& c : cd.results[i].contacts) seen[c.face] = 1;
  return seen;
}

// Two estimates of surface vertex q's motion over the frame: its last
// increment du and dt v, at its material point.
struct VertexMotion {
  Eigen::Vector3d last, velocity;
  // kSpeculativeShare times the larger, as a length, or along -n (towards
  // whatever lies on the other side of n).
  double length() const { return kSpeculativeShare * std::max(last.norm(), velocity.norm()); }
  double towards(const Eigen::Vector3d& n) const { return -kSpeculativeShare * std::min(last.dot(n), velocity.dot(n)); }
};
VertexMotion vertex_motion(const Simulation& sim, const TissueSurface& s, int q) {
  const std::vector<double>&v = sim.state.v, &du = sim.state.du;
  const bool has_du = du.size() == v.size();
  VertexMotion m{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  for (int k = s.vert_ptr[q]; k < s.vert_ptr[q + 1]; ++k) {
    const size_t n = 3 * static_cast<size_t>(s.vert_dofnode[k]);
    const double w = s.vert_weight[k];
    for (int d = 0; d < 3; ++d) m.velocity[d] += w * v[n + d], m.last[d] += has_du ? w * du[n + d] : 0.0;
  }
  m.velocity *= sim.model.dt;
  return m;
}

// How far the tissue near a probe may move in the frame, times
// kSpeculativeShare: the largest vertex_motion (either way) over the
// surface vertices within the probe's reach; a cheap bound over the DOF
// nodes first returns 0 while that cannot exceed the detection margin
// (tissue at rest: no speculative rows). Newmark's acceleration is no
// estimate: it carries the Newton residual and the contact impulses (it
// read 5-9 cm a frame on a beam moving 1 cm), and a gravity term
// dt^2 |g| / 2 (5.4 mm at 30 Hz) would give a probe on a supported organ
// speculative rows in every frame, each a substitution.
double speculative_reach(const Simulation& sim, const CollisionData& cd, const InstrumentSpec& spec,
                         const ToolFrame& tf, double margin) {
  const double dt = sim.model.dt;
  const std::vector<double>&v = sim.state.v, &du = sim.state.du;
  const bool has_du = du.size() == v.size();
  const auto norm2 = [](const double* w) { return w[0] * w[0] + w[1] * w[1] + w[2] * w[2]; };
  double node_max = 0.0;  // the largest motion of a DOF node, squared
  for (size_t k = 0; k + 2 < v.size(); k += 3)
    node_max = std::max({node_max, dt * dt * norm2(&v[k]), has_du ? norm2(&du[k]) : 0.0});
  // A vertex moves by sum_k w_k (motion of node k): at most sum |w_k| times
  // the largest; sum |N_a| <= 2 for tet10, and a Heaviside enrichment
  // N_a (H - H_a) doubles a weight at most (branch DOFs aside: a skip
  // there only means fewer speculative rows).
  constexpr double kWeightBound = 6.0;
  const double bound = kSpeculativeShare * kWeightBound * std::sqrt(node_max);
  if (!(bound > margin)) return 0.0;
  const TissueSurface& s = cd.model.surface();
  const double reach = spec.radius + bound;
  // The probe's axis at the frame's end, as a box grown by the reach.
  const std::array<double, 3> p0 = tool_to_world(tf.after, {0, 0, 0}), p1 = tool_to_world(tf.after, {0, 0, spec.length});
  double lo[3], hi[3];
  for (int d = 0; d < 3; ++d) lo[d] = std::min(p0[d], p1[d]) - reach, hi[d] = std::max(p0[d], p1[d]) + reach;
  double reach_max = 0.0;
  for (int q = 0; q < s.nvert(); ++q) {
    const double* x = &s.x[3 * static_cast<size_t>(q)];
    if (x[0] < lo[0] || x[0] > hi[0] || x[1] < lo[1] || x[1] > hi[1] || x[2] < lo[2] || x[2] > hi[2]) continue;
    reach_max = std::max(reach_max, vertex_motion(sim, s, q).length());
  }
  return reach_max;
}

// Tissue that runs into a resting probe faster than the detection margin a
// frame was inside it before any row held it: a beam tip falling onto a
// 5 mm probe at 1 cm a frame went 3.4 mm into it, and its contact came and
// went. Where the tissue near the probe may move further than the margin
// (speculative_reach), faces within that reach of the probe's end pose,
// not already found, whose corners may move towards the probe further
// than their gap and the margin, get speculative rows: the geometric
// normal from the axis and the gap as a negative target, inactive unless
// the step closes it. Measured before the per-face test: a probe held
// beside a fresh incision took 3 rows of faces that did not move (9 frames
// of 90, 2-5 ms each); counting motion either way and any gap, slow presses
// of a 3 mm probe took them in 19 frames, and Newton hit its cap in 41
// frames instead of 5. Only faces the axis is outside of (the probe on
// their outer side): with a reach larger than the tissue is thick, the
// back faces of a thin part lie within it too, and the face rule of
// collision/narrowphase.h would push them through the tissue (tried: a
// 2.6 cm reach under the beam gave 48 rows, 500 N and 100 inverted points
// a frame).
void add_speculative_contacts(const Simulation& sim, CollisionData& cd, size_t i) {
  const InstrumentSpec& spec = sim.scene.instruments[i];
  const ToolFrame& tf = sim.tools[i];
  const double reach = speculative_reach(sim, cd, spec, tf, cd.margin[i]);
  if (!(reach > cd.margin[i])) return;
  ToolShape& sh = cd.sweep_shapes[i];
  set_probe_radius(sh, spec.radius + reach);
  set_tool_pose(sh, inflated(spec, reach), tf.after);
  query_contacts(cd.model, sh, cd.request, cd.sweep_result);
  // Back to the margin: the sweep's shapes share their FCL geometry with `shapes`.
  set_probe_radius(sh, spec.radius + cd.margin[i]);
  const TissueSurface& s = cd.model.surface();
  std::vector<unsigned char>& seen = faces_found(cd, i);
  std::vector<TissueContact>& contacts = cd.results[i].contacts;
  const ToolPart& part = cd.shapes[i].part[0];
  for (const TissueContact& c : cd.sweep_result.contacts) {
    if (seen[c.face]) continue;
    seen[c.face] = 1;
    const int* tv = &s.tri[3 * static_cast<size_t>(c.tri)];
    const Eigen::Vector3d n_out = triangle_outward(s, c.tri), x(c.point[0], c.point[1], c.point[2]);
    const Eigen::Vector3d y = nearest_on_segment(part.a, part.b, x);
    const Eigen::Vector3d g = x - y;
    const double d = g.norm();
    if (!((y - x).dot(n_out) > 0) || !(d > spec.radius + cd.margin[i])) continue;  // behind the face, or found already
    // The triangle's corners' motion towards the probe: a face that would
    // not pass its gap by more than the margin (or moves away, pushed by the
    // probe itself) needs no row: the next frame's rows push out what a
    // margin holds, as they did before.
    double approach = 0.0;
    for (int j = 0; j < 3; ++j) approach = std::max(approach, vertex_motion(sim, s, tv[j]).towards(g / d));
    if (!(approach > d - spec.radius + cd.margin[i])) continue;
    TissueContact& kept = contacts.emplace_back(c);
    for (int k = 0; k < 3; ++k) kept.normal[k] = g[k] / d;
    kept.depth = spec.radius - d + cd.margin[i];  // the stage subtracts the margin: the target is minus the gap
    kept.speculative = true;
  }
}

// Two unit tangents orthogonal to n.
void tangents(const double n[3], double t1[3], double t2[3]) {
  const int a = std::abs(n[0]) < 0.6 ? 0 : (std::abs(n[1]) < 0.6 ? 1 : 2);
  double e[3] = {0, 0, 0};
  e[a] = 1.0;
  t1[0] = n[1] * e[2] - n[2] * e[1];
  t1[1] = n[2] * e[0] - n[0] * e[2];
  t1[2] = n[0] * e[1] - n[1] * e[0];
  const double l = std::sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
  for (int d = 0; d < 3; ++d) t1[d] /= l;
  t2[0] = n[1] * t1[2] - n[2] * t1[1];
  t2[1] = n[2] * t1[0] - n[0] * t1[2];
  t2[2] = n[0] * t1[1] - n[1] * t1[0];
}

// Where the tool's surface point at p (world, at the frame's start) is at its end.
std::array<double, 3> carried(const ToolFrame& f, const double p[3]) {
  return tool_to_world(f.after, world_to_tool(f.before, {p[0], p[1], p[2]}));
}

// What a contact row holds across frames (ContactRows::key): its surface
// face and tool part, or its triangle under contact.rows "triangle".
long long contact_id(const TissueContact& c, ContactSettings::Rows rule) {
  return 4LL * (rule == ContactSettings::Rows::Triangle ? c.tri : c.face) + c.part;
}

// One unilateral row: n . (sum_k w_k Delta_k) >= target.
void add_contact_row(const TissueContact& c, long long id, double target, const ToolFrame& f, double dt, int tool,
                     ContactRows& rows) {
  const std::array<double, 3> moved = carried(f, c.point);
  double vel = 0.0;
  for (int d = 0; d < 3; ++d) vel += c.normal[d] * (moved[d] - c.point[d]) / dt;
  rows.begin_row(RowKind::Contact, target, tool, c.point, c.normal, std::max(0.0, target), -1, vel);
  rows.key.back() = row_key(tool, 3, id);
  for (int k = 0; k < c.weights.n; ++k)
    for (int d = 0; d < 3; ++d) rows.add(3 * c.weights.dofnode[k] + d, c.weights.weight[k] * c.normal[d]);
}

// Coulomb friction: the tissue point follows the tool's surface tangentially
// while it sticks. Target: the tool's motion at the point over the frame.
void add_friction_rows(const TissueContact& c, long long id, const ToolFrame& tool_frame, double dt, int tool,
                       int normal_row, ContactRows& rows) {
  double t[2][3];
  tangents(c.normal, t[0], t[1]);
  const std::array<double, 3> moved = carried(tool_frame, c.point);
  for (int j = 0; j < 2; ++j) {
    const double* dir = t[j];
    double target = 0.0;
    for (int d = 0; d < 3; ++d) target += dir[d] * (moved[d] - c.point[d]);
    rows.begin_row(RowKind::Friction, target, tool, c.point, dir, 0.0, normal_row, target / dt);
    rows.key.back() = row_key(tool, 4 + j, id);
    for (int k = 0; k < c.weights.n; ++k)
      for (int d = 0; d < 3; ++d) rows.add(3 * c.weights.dofnode[k] + d, c.weights.weight[k] * dir[d]);
  }
}

}  // namespace

CollisionData* collision_data(Simulation& sim) {
  return static_cast<CollisionData*>(sim.module_data[kStageCollision].get());
}

ToolShape instrument_shape(const Simulation& sim, int i, const ToolPose& pose) {
  return make_tool_shape(sim.scene.instruments[i], pose);
}

namespace {
// "instruments[1]" or "instruments[1] ("grasper")" for messages.
std::string instrument_label(const InstrumentSpec& spec) {
  return spec.json_path + (!spec.name.empty() && spec.name != spec.json_path ? " (\"" + spec.name + "\")" : "");
}

// What holds a probe narrower than the faces or pressed deeper than its
// radius (docs/instruments.md, "Known limits"), for both warnings below.
constexpr const char* kNarrowProbeRecipe =
    "contact.rows \"triangle\" with contact.max_rows 600 and render.subdivision 4, at several times the contact "
    "stage's time";

// A probe deeper in the tissue than half its radius: its rows' normals and
// depths no longer say where the surface is (the far side of the sphere is
// nearer), and one frame's contact solve cannot push that much tissue out:
// a 5 cm probe started 10 cm inside organ_3k crushed it (700-1300 inverted
// points and 1e4-6e6 N every frame) and the run ended "successfully". At
// the run's first frame that is a bad scene (the instrument starts inside
// the tissue): an error. Later, a stroke faster than half the radius a
// frame put it there: a warning, once per instrument. A frame that swept
// the probe (sweep_probe) has rows for the faces it went through; a probe
// still deep a frame after that is what the warning is for.
void check_probe_depth(const Simulation& sim, CollisionData& cd, size_t i, const std::vector<TissueContact>& found,
                       bool swept) {
  const InstrumentSpec& spec = sim.scene.instruments[i];
  if (swept && sim.state.frame > 0) return;  // a fast stroke: its sweep's rows push the tissue out
  double depth = 0.0;
  for (const TissueContact& c : found)
    if (!c.swept) depth = std::max(depth, c.depth - cd.margin[i]);
  if (!(depth > 0.5 * spec.radius)) return;
  const std::string who = instrument_label(spec);
  char buf[512];
  if (sim.state.frame == 0) {
    std::snprintf(buf, sizeof buf,
                  "%s: %s starts %.3g m inside the tissue (its deepest point; radius %g m): a rigid probe cannot start "
                  "more than half its radius inside; move the first pose of its trajectory out of the tissue",
                  sim.scene.path.c_str(), who.c_str(), depth, spec.radius);
    throw Error(buf);
  }
  if (cd.warned_deep[i]) return;
  cd.warned_deep[i] = 1;
  std::fprintf(stderr,
               "warning: %s: %s went %.3g m into the tissue by t = %g s, more than half its radius (%g m): the contact "
               "did not push the tissue out: it moved through the surface faster than half its radius a frame "
               "(contact.sweep: true sweeps its path), the tissue ran into it faster than the margin, %g m, a frame "
               "(contact.speculative: true), or, narrower than the faces or pressed deeper than its radius, the faces "
               "folded round it (one row per face holds one point of each; %s holds them); the motion near it is not "
               "physical from here (docs/instruments.md)\n",
               sim.scene.path.c_str(), who.c_str(), depth, sim.state.time + sim.model.dt, spec.radius, cd.margin[i],
               kNarrowProbeRecipe);
}

// Whether world point x lies in the tissue (the deformed corner
// tetrahedra); `locator` is made on first use in the frame (O(elements))
// and serves the frame's other asks. False in scenes with cuts: an
// element's corner tetrahedron spans its cut's gap.
bool in_tissue(const Simulation& sim, const double x[3], std::unique_ptr<TissueLocator>& locator) {
  if (sim.model.has_cuts()) return false;
  if (!locator) locator = std::make_unique<TissueLocator>(sim.model, sim.state);
  return locator->inside(x);
}

// Whether probe i's tip centre lies in the tissue (in_tissue).
bool centre_in_tissue(const Simulation& sim, const CollisionData& cd, size_t i,
                      std::unique_ptr<TissueLocator>& locator) {
  const Eigen::Vector3d& c = cd.shapes[i].part[0].a;
  const double x[3] = {c[0], c[1], c[2]};
  return in_tissue(sim, x, locator);
}

// Whether sphere probe i's centre lies outside the tissue, asked when its
// query used the face rule (the centre at or behind a face's plane). The
// face rule assumes the probe came through that face into the tissue; a
// probe whose centre is not in the tissue came through none: the faces
// behind its centre have folded round it (a sphere pressed deeper than its
// radius), and the face rule pushed them through it, below the sphere (a 1
// cm sphere pressed 2 cm into organ_10k: 167 inverted points, 30 N;
// geometric, they are pushed away from it: none, 3.7 N held). Not for
// capsules (a shaft can be in the tissue with its tip outside) and not in
// scenes with cuts.
bool centre_outside_tissue(const Simulation& sim, const CollisionData& cd, size_t i,
                           std::unique_ptr<TissueLocator>& locator) {
  const ToolPart& part = cd.shapes[i].part[0];
  if (part.kind == ToolPart::Kind::Box || part.a != part.b || sim.model.has_cuts()) return false;
  return !centre_in_tissue(sim, cd, i, locator);
}

// A probe that lost all its contacts and, within kInsideCheckFrames frames,
// has its centre inside the tissue (the deformed corner tetrahedra): the
// tissue closed over it, and it pushes nothing from here. It was silent: a
// 3 mm probe pressed 1 cm into organ_10k lost its rows at frame 18 (the
// faces pushed off it), the tissue closed over it at frame 19 and it sat
// inside at 0 N for 35 frames. Not in scenes with cuts: an element's corner
// tetrahedron spans its cut's gap. Once per instrument; the locator is made
// only in those frames.
void check_probe_inside(const Simulation& sim, CollisionData& cd, size_t i, std::unique_ptr<TissueLocator>& locator) {
  if (cd.warned_inside[i] || cd.untouched_frames[i] < 1 || sim.model.has_cuts()) return;
  if (!centre_in_tissue(sim, cd, i, locator)) return;
  cd.warned_inside[i] = 1;
  const InstrumentSpec& spec = sim.scene.instruments[i];
  std::fprintf(stderr,
               "warning: %s: %s lost its contact, and at t = %g s its centre is inside the tissue: the tissue closed "
               "over it and it pushes nothing from here. A probe narrower than the faces it presses or pressed deeper "
               "than its radius needs %s; one moved faster than half its radius (%g m) a frame, contact.sweep: true "
               "(docs/instruments.md)\n",
               sim.scene.path.c_str(), instrument_label(spec).c_str(), sim.state.time + sim.model.dt, kNarrowProbeRecipe,
               spec.radius);
}

// A probe that moves more than kSweepStepShare of its radius in the frame
// (against the frame's start): the end pose's query (already in
// cd.results[i]) misses the faces the probe went through, and a probe
// jabbed its diameter in one frame ended inside the tissue untouched. The
// path is sampled at sub-poses kSweepStepShare radii apart (positions
// linear, orientation by slerp, as trajectories interpolate); a face first
// touched at a sub-pose, from outside, and not at the end pose, gets a row
// along its inward normal, as deep as its point must move along it to
// leave the end pose (round_exit_distance with the real radius; none where
// that misses the end pose: a probe drawn sideways over the face left it
// behind). The first version pushed along the direction the face was
// struck in, which put the faces under a sideways stroke 3 cm ahead of the
// probe. A path that meets a face from inside the tissue went through it,
// as does an end pose moving out through a face it touches: no swept rows
// that frame. Where the face is touched at the end pose the
// end pose's contact stays, so a slow probe's rows are what they were.
// Returns whether it swept.
bool sweep_probe(const Simulation& sim, CollisionData& cd, size_t i) {
  const InstrumentSpec& spec = sim.scene.instruments[i];
  const ToolFrame& tf = sim.tools[i];
  const InstrumentSpec shape_spec = inflated(spec, cd.margin[i]);
  ToolShape& sh = cd.sweep_shapes[i];
  set_tool_pose(sh, shape_spec, tf.before);
  const ToolPart& end = cd.shapes[i].part[0];
  const double r = spec.radius;
  const double move = std::max((end.a - sh.part[0].a).norm(), (end.b - sh.part[0].b).norm());
  if (!(move > kSweepStepShare * r)) return false;
  const int steps = static_cast<int>(std::min<double>(kMaxSweepSteps, std::ceil(move / (kSweepStepShare * r))));
  const TissueSurface& s = cd.model.surface();
  std::vector<unsigned char>& seen = faces_found(cd, i);
  std::vector<TissueContact>& contacts = cd.results[i].contacts;
  const size_t end_contacts = contacts.size();
  bool exits = false;  // the path met a face from the tissue's side: it went through
  // The end pose touching a face whose plane the axis crossed outwards
  // during the frame (it started on the face's tissue side and moved along
  // its outward normal): a jab that ends across a 4 mm plate, whose far
  // side it reached from inside.
  const Eigen::Vector3d start = sh.part[0].a, motion = end.a - start;
  for (size_t k = 0; k < end_contacts && !exits; ++k) {
    const Eigen::Vector3d n_out = triangle_outward(s, contacts[k].tri),
                          x(contacts[k].point[0], contacts[k].point[1], contacts[k].point[2]);
    exits = (start - x).dot(n_out) < 0 && motion.dot(n_out) > 0;
  }
  for (int k = 0; k < steps && !exits; ++k) {  // t = k / steps, earliest first; t = 1 is the end pose's query
    const double t = static_cast<double>(k) / steps;
    ToolPose pose = tf.after;
    for (int d = 0; d < 3; ++d) pose.p[d] = (1.0 - t) * tf.before.p[d] + t * tf.after.p[d];
    pose.q = slerp(tf.before.q, tf.after.q, t);
    set_tool_pose(sh, shape_spec, pose);
    query_contacts(cd.model, sh, cd.request, cd.sweep_result);
    for (const TissueContact& c : cd.sweep_result.contacts) {  // deepest first: a face's first is its deepest
      if (seen[c.face]) continue;
      seen[c.face] = 1;
      const Eigen::Vector3d n_out = triangle_outward(s, c.tri), x(c.point[0], c.point[1], c.point[2]);
      if (!(n_out.squaredNorm() > 0)) continue;
      const Eigen::Vector3d y = nearest_on_segment(sh.part[0].a, sh.part[0].b, x);
      if (!((y - x).dot(n_out) > 0)) {  // reached from inside the tissue
        exits = true;
        break;
      }
      const double depth = round_exit_distance(end.a, end.b, r, x, -n_out);
      if (!(depth > 0)) continue;
      TissueContact& kept = contacts.emplace_back(c);
      for (int d = 0; d < 3; ++d) kept.normal[d] = -n_out[d];
      kept.depth = depth + cd.margin[i];  // the stage subtracts the margin
      kept.swept = true;
    }
  }
  // A probe that went through the tissue (a plate, an edge) in the frame:
  // its path has no side for the struck faces to go to but a tear, and
  // pushing them to the end pose's far side wrecked a 4 mm plate (170 N,
  // 279 inverted points); the end pose's rows alone, as without the sweep.
  if (exits) contacts.resize(end_contacts);
  return true;
}

}  // namespace

void collision_stage(Simulation& sim) {
  CollisionData& cd = *collision_data(sim);
  FrameTiming& ft = sim.ws.timing;
  if (cd.model.sync(sim.model, sim.state, sim.model_version) == SyncAction::Rebuild) ++ft.bvh_rebuilds;
  else ++ft.bvh_refits;
  const TissueSurface& surface = cd.model.surface();
  ContactRows& rows = sim.ws.contacts;
  rows.clear();
  rows.friction = sim.scene.contact.friction;
  rows.max_sweeps = sim.scene.contact.pgs_iterations;
  rows.refine_rounds = sim.scene.contact.refine_rounds;
  rows.compliance_reuse = sim.scene.contact.compliance_reuse;
  // Grasps first: they are what the user asked for, and not subject to max_rows.
  auto& candidates = cd.candidates;
  candidates.clear();
  double deepest = 0.0;  // penetration of the deepest point found
  const ContactSettings::Rows rule = sim.scene.contact.rows;
  std::unique_ptr<TissueLocator> locator;  // made when a probe first needs it this frame
  for (size_t i = 0; i < sim.scene.instruments.size(); ++i) {
    const InstrumentSpec& spec = sim.scene.instruments[i];
    if (!touches(spec)) continue;
    const ToolFrame& tf = sim.tools[i];
    if (spec.kind == InstrumentSpec::Kind::Grasper) {
      const bool was_holding = cd.grasps[i].holding;
      const std::vector<HeldPoint>* imposed = nullptr;
      for (const GraspTaken& g : cd.imposed)
        if (g.frame == sim.state.frame && g.tool == static_cast<int>(i)) imposed = &g.held;
      const bool was_empty = cd.grasps[i].closed_empty;
      // Jaws that pushed the tissue from both sides in the last frame's
      // query (jaw 0, at -y, toward +y of the tool frame; jaw 1 toward -y)
      // take hold now: squeezed between two contacts up to grasp_at, a 1.5
      // cm bite of the liver had no solution (618 N, 99 inverted points).
      // Jaws pressed up into a face together (a grasper brought up under the
      // tissue) push it one way and squeeze nothing. Not where another run's
      // grasp points are imposed (incise compare): they come with their frame.
      bool pressed = false;
      if (spec.contact && !cd.grasps[i].holding) {
        const std::array<double, 3> o = tool_to_world(tf.before, {0, 0, 0}), e = tool_to_world(tf.before, {0, 1, 0});
        bool jaw0 = false, jaw1 = false;
        for (const TissueContact& c : cd.results[i].contacts) {
          if (c.speculative) continue;
          const double along = c.normal[0] * (e[0] - o[0]) + c.normal[1] * (e[1] - o[1]) + c.normal[2] * (e[2] - o[2]);
          if (c.part == 0 && along > 0.5) jaw0 = true;
          if (c.part == 1 && along < -0.5) jaw1 = true;
        }
        bool imposing = false;
        for (const GraspTaken& g : cd.imposed) imposing = imposing || g.tool == static_cast<int>(i);
        pressed = jaw0 && jaw1 && !imposing;
      }
      update_grasp(sim.model, spec, tf, surface, sim.model_version, cd.grasps[i], imposed, pressed);
      if (!was_holding && cd.grasps[i].holding) cd.taken.push_back({sim.state.frame, static_cast<int>(i), cd.grasps[i].held});
      // A grasp that silently held nothing looked like a solver failure (the
      // tissue did not follow): say so once each time the jaws close on nothing.
      // Jaws closed inside the tissue (a grasper started in it) meet no
      // surface either; that message sent the user to close them over the
      // tissue when they already were in it (not told in scenes with cuts).
      if (cd.grasps[i].closed_empty && !was_empty) {
        if (in_tissue(sim, tf.after.p.data(), locator))
          std::fprintf(stderr,
                       "warning: %s: %s closed its jaws at t = %g s inside the tissue: it holds nothing (a grasper "
                       "takes the tissue surface that comes between its closing jaws; start it outside the tissue and "
                       "close it over the surface)\n",
                       sim.scene.path.c_str(), instrument_label(spec).c_str(), sim.state.time + sim.model.dt);
        else
          std::fprintf(stderr,
                       "warning: %s: %s closed its jaws at t = %g s with no tissue surface between them: it holds "
                       "nothing (it takes tissue that comes between the closed jaws; to grasp, close them over the "
                       "tissue, and slower if the jaws push it out while closing)\n",
                       sim.scene.path.c_str(), instrument_label(spec).c_str(), sim.state.time + sim.model.dt);
      }
      if (cd.grasps[i].holding) {
        add_grasp_rows(sim.state, cd.grasps[i], tf, sim.model.dt, static_cast<int>(i), surface, rows);
        continue;  // the jaws hold: no contact rows from them
      }
      if (!spec.contact) continue;
    }
    set_tool_pose(cd.shapes[i], inflated(spec, cd.margin[i]), tf.after);
    query_contacts(cd.model, cd.shapes[i], cd.request, cd.results[i]);
    const bool probe = spec.kind == InstrumentSpec::Kind::Probe;
    if (probe && cd.results[i].face_rule > 0 && centre_outside_tissue(sim, cd, i, locator)) {
      cd.request.outside_tissue = true;  // the same query without the face rule
      query_contacts(cd.model, cd.shapes[i], cd.request, cd.results[i]);
      cd.request.outside_tissue = false;
    }
    const bool swept = probe && sim.scene.contact.sweep && sweep_probe(sim, cd, i);
    if (probe && sim.scene.contact.speculative) add_speculative_contacts(sim, cd, i);
    // One row per tissue face a tool part touches (contact.rows "face",
    // "face_deepest"; the contacts come deepest first, so the first of a
    // face is its deepest point): a face's triangles give nearly the same
    // row, and each row costs the contact stage a substitution. Under "face"
    // a round part's row moves to the face's weighted point
    // (collision/face_contact.h: the deepest point jumps about a face that
    // wraps the tool); a box pushes along the face's normal, where it does not.
    auto& found = cd.results[i].contacts;
    cd.face_seen.assign(cd.model.surface().nface, 0);
    if (probe && !found.empty()) check_probe_depth(sim, cd, i, found, swept);
    if (probe) {
      cd.untouched_frames[i] = found.empty() ? std::min(cd.untouched_frames[i] + 1, kInsideCheckFrames + 1) : 0;
      if (cd.untouched_frames[i] <= kInsideCheckFrames) check_probe_inside(sim, cd, i, locator);
    }
    for (size_t k = 0; k < found.size(); ++k) {
      TissueContact& c = found[k];
      unsigned char& seen = cd.face_seen[c.face];
      if (rule != ContactSettings::Rows::Triangle && (seen & (1 << c.part))) continue;
      seen |= static_cast<unsigned char>(1 << c.part);
      deepest = std::max(deepest, c.depth - cd.margin[i]);
      if (rule == ContactSettings::Rows::Face && !c.swept && !c.speculative)
        weight_round_face_contact(surface, cd.shapes[i].part[c.part], sim.state.u.data(), c);
      candidates.push_back({c.depth - cd.margin[i], static_cast<int>(i), static_cast<int>(k), contact_id(c, rule)});
    }
  }
  ft.grasp_rows = rows.nrow();
  // The deepest contacts, up to contact.max_rows rows (a contact and its two
  // friction rows count three).
  std::sort(candidates.begin(), candidates.end(), [](const CollisionData::Candidate& a, const CollisionData::Candidate& b) {
    return a.depth != b.depth ? a.depth > b.depth : (a.tool != b.tool ? a.tool < b.tool : a.index < b.index);
  });
  const bool friction = rows.friction > 0.0;
  const size_t keep = std::min(candidates.size(), static_cast<size_t>(sim.scene.contact.max_rows / (friction ? 3 : 1)));
  // The kept rows in the order of their keys, not of their depth: a held
  // tool's rows then come in the same order frame after frame, and the
  // contact stage keeps their compliance columns while the factor and the
  // rows' keys stay (engine/dynamics/contact_solve.cpp, rows_change).
  std::sort(candidates.begin(), candidates.begin() + static_cast<std::ptrdiff_t>(keep),
            [](const CollisionData::Candidate& a, const CollisionData::Candidate& b) {
              return a.tool != b.tool ? a.tool < b.tool : a.id < b.id;
            });
  // The DOFs the grasps hold. A contact row whose point moves mostly with
  // them (most of its coefficients' weight on held DOFs: a face of an
  // element a grasp holds points of) is left out: the grasp holds that
  // tissue where the jaws put it, and a tool pressing the same points
  // elsewhere asked for two places at once. With both rows the LCP had no
  // solution; its solver ran to its sweep cap and pushed the tissue with
  // hundreds of newtons (a probe pressed onto the liver beside a grasper's
  // jaws: 452 N, 463 inverted points, 13 m/s).
  const int ngrasp_rows = rows.nrow();
  if (ngrasp_rows > 0) {
    cd.grasped_dof.assign(sim.model.ndof(), 0);
    for (int k = 0; k < rows.ptr[ngrasp_rows]; ++k) cd.grasped_dof[rows.dof[k]] = 1;
  }
  const auto held_row = [&](int row) {
    double held = 0.0, all = 0.0;
    for (int k = rows.ptr[row]; k < rows.ptr[row + 1]; ++k) {
      const double w = rows.coef[k] * rows.coef[k];
      all += w;
      if (cd.grasped_dof[rows.dof[k]]) held += w;
    }
    return held > 0.5 * all;
  };
  for (size_t q = 0; q < keep; ++q) {
    const CollisionData::Candidate& c = candidates[q];
    const TissueContact& tc = cd.results[c.tool].contacts[c.index];
    const int normal_row = rows.nrow();
    add_contact_row(tc, c.id, c.depth, sim.tools[c.tool], sim.model.dt, c.tool, rows);
    if (ngrasp_rows > 0 && held_row(normal_row)) {
      rows.pop_row();
      ++ft.held_rows_dropped;
      if (!cd.warned_held[c.tool]) {
        cd.warned_held[c.tool] = 1;
        std::fprintf(stderr,
                     "warning: %s: %s pressed tissue that a grasper holds at t = %g s: its contact rows there are "
                     "left out (the grasp keeps that tissue where the jaws hold it; the tool passes into it "
                     "without a force)\n",
                     sim.scene.path.c_str(), instrument_label(sim.scene.instruments[c.tool]).c_str(),
                     sim.state.time + sim.model.dt);
      }
      continue;
    }
    if (friction) add_friction_rows(tc, c.id, sim.tools[c.tool], sim.model.dt, c.tool, normal_row, rows);
    ++ft.contacts;
    ft.swept_rows += tc.swept;
    ft.speculative_rows += tc.speculative;
  }
  ft.max_depth = deepest;
}

void install_collision_stage(Simulation& sim) {
  bool any = false;
  for (const InstrumentSpec& s : sim.scene.instruments) any = any || touches(s);
  if (!any) return;
  auto cd = std::make_shared<CollisionData>();
  cd->model = CollisionModel(sim.scene.render.subdivision);
  const size_t n = sim.scene.instruments.size();
  cd->margin.resize(n, 0.0);
  cd->results.resize(n);
  cd->grasps.resize(n);
  cd->warned_deep.assign(n, 0);
  cd->untouched_frames.assign(n, kInsideCheckFrames + 1);  // not touched yet: nothing to check
  cd->warned_inside.assign(n, 0);
  cd->warned_held.assign(n, 0);
  for (size_t i = 0; i < n; ++i) {
    const InstrumentSpec& s = sim.scene.instruments[i];
    cd->margin[i] = contact_margin(s);
    const ToolPose pose = i < sim.tools.size() ? sim.tools[i].after : ToolPose{};
    cd->shapes.push_back(make_tool_shape(inflated(s, cd->margin[i]), pose));
  }
  cd->sweep_shapes = cd->shapes;  // the FCL geometry is shared, the poses are the sweep's own
  // Several triangles per face: enough candidates for max_rows faces.
  cd->request.max_contacts = 8 * std::max(sim.scene.contact.max_rows, 1);
  cd->request.edges_geometric = sim.scene.contact.rows == ContactSettings::Rows::Triangle;
  sim.module_data[kStageCollision] = cd;
  sim.pipeline.set(kStageCollision, collision_stage);
}

}  // namespace incise
