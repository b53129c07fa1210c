#pragma once
// A scene file (JSON) parsed into plain settings. Loading validates every
// field; errors name the file, the JSON path and what is allowed. See
// docs/scene-format.md for the keys and defaults.
#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>
#include <utility>

namespace incise {

using Vec3 = std::array<double, 3>;

// A set of mesh nodes, chosen geometrically or by id.
struct Region {
  enum class Kind { Box, Plane, Nodes };
  Kind kind = Kind::Box;
  Vec3 lo{}, hi{};            // Box: corners (inclusive, with a tolerance)
  Vec3 point{}, normal{};     // Plane: nodes with (X - point) . normal <= 0 (tolerance);
                              // the loader scales normal to unit length
  std::vector<int> nodes;     // Nodes: 0-based node ids
  std::string json_path;      // e.g. "fixed[1]", for messages
};

struct Prescribed {
  Region region;
  std::array<bool, 3> active{false, false, false};  // an absent component stays free
  Vec3 displacement{};                              // final value of each active component
  double ramp = 0.0;  // seconds; value grows linearly from 0 over [0, ramp], 0 = at once
};

enum class MaterialModel { Linear, Corotated };
enum class RotationMode { PerPoint, Single };  // Single = tet10SR (rotation from corners)
enum class MassKind { Lumped, Consistent };

struct Material {
  MaterialModel model = MaterialModel::Corotated;
  RotationMode rotation = RotationMode::PerPoint;
  double young = 0.0;    // Pa (or consistent units), > 0
  double poisson = 0.0;  // in (-1, 0.5)
  double density = 0.0;  // > 0
  double rayleigh_mass = 0.0;       // a in D = a M + b K, >= 0
  double rayleigh_stiffness = 0.0;  // b, >= 0
};

struct OutputSettings {
  std::string dir;        // resolved; empty = no field output unless --out is given
  int every = 1;          // write every N-th frame, >= 1
  bool write_vtu = true;  // ParaView .vtu + .pvd series
  bool vtu_ascii = false; // output.vtu_format "ascii"; default "binary" (appended, zlib)
};

// A cut declared in the scene (applied by cutting/ at at_time; static: all at once).
struct CutSpec {
  enum class Type { Plane, Polygon, Mesh, Swept };
  Type type = Type::Plane;
  Vec3 point{}, normal{};       // plane: infinite plane through point (normal unit length)
  std::vector<Vec3> points;     // polygon: >= 3 vertices of a planar polygon, in order
  std::string file;             // mesh: triangle surface (.obj or ASCII .stl), resolved
  std::array<Vec3, 2> edge_start{}, edge_end{};  // swept: blade edge segment at start and end
  double duration = 0.0;        // swept: seconds to move from start to end (0 = at once)
  double at_time = 0.0;         // seconds, >= 0
  std::string json_path;        // "cuts[2]"
};

// An instrument of the scene (scene key "instruments"; docs/scene-format.md).
// Poses are rigid transforms tool frame -> world: position and unit
// quaternion (w, x, y, z). Tool-frame geometry (metres or the scene's unit):
//   probe    a sphere of `radius` centred at the tool origin, or a capsule
//            (`length` > 0): the segment from the origin to (0, 0, length)
//            swept by `radius` (the tip is the hemisphere at the origin);
//   scalpel  a blade box x in [-L/2, L/2], y in [-T/2, T/2], z in [0, H]
//            (blade = [L, T, H]); its cutting edge is the segment
//            edge[0] -> edge[1] (default: the blade's lower edge, z = 0);
//   grasper  two parallel jaw boxes [W, T, J] (jaw = [width x, thickness y,
//            length z], centred at z = 0) facing each other across the tool's
//            y axis, their inner faces `opening` apart at jaw = 0 and touching
//            at jaw = 1; while jaw >= grasp_at the tissue between them is held.
struct InstrumentSpec {
  enum class Kind { Probe, Scalpel, Grasper };
  Kind kind = Kind::Probe;
  std::string name;             // "instruments[0]" unless given
  std::string trajectory;       // resolved keyframe CSV (t,x,y,z,qw,qx,qy,qz[,jaw]); empty: fixed `pose`
  Vec3 position{};              // pose without a trajectory
  std::array<double, 4> orientation{1.0, 0.0, 0.0, 0.0};  // (w, x, y, z), unit
  double jaw = 0.0;             // grasper without a trajectory: 0 open .. 1 closed
  double radius = 0.0;          // probe: > 0
  double length = 0.0;          // probe: capsule length, 0 = sphere
  Vec3 blade{};                 // scalpel: [L, T, H], each > 0
  std::array<Vec3, 2> edge{};   // scalpel: cutting edge in the tool frame
  Vec3 jaw_size{};              // grasper: [W, T, J], each > 0
  double opening = 0.0;         // grasper: > 0
  double grasp_at = 0.9;        // grasper: jaw value from which it holds, in (0, 1]
  bool contact = true;          // probe and grasper: the tissue is pushed out of the tool
  std::string json_path;        // "instruments[1]"
};

// Gap between a grasper's inner jaw faces: (1 - jaw) * opening (collision
// and the renderer draw the same jaws).
inline double jaw_gap(const InstrumentSpec& spec, double jaw) {
  return (1.0 - (jaw < 0.0 ? 0.0 : jaw > 1.0 ? 1.0 : jaw)) * spec.opening;
}

// Contact response settings (scene key "contact"; docs/scene-format.md).
struct ContactSettings {
  // Where a probe's rows sit on the tissue (collision/face_contact.h):
  //   Face         one per face and tool part, at the face's depth-weighted point (default)
  //   FaceDeepest  one per face and tool part, at its deepest point (the rule before the
  //                twenty-fifth session: a held probe's force alternates frame to frame)
  //   Triangle     one per surface triangle, at its deepest point: with render.subdivision
  //                raised, the converged reference the others are measured against
  enum class Rows { Face, FaceDeepest, Triangle };
  Rows rows = Rows::Face;
  int max_rows = 48;            // contact constraints kept per frame (deepest first), >= 1
  double friction = 0.0;        // Coulomb coefficient, >= 0 (0: frictionless)
  int pgs_iterations = 200;     // projected Gauss-Seidel sweeps, >= 1
  int refine_rounds = 0;        // lagged / warped_cg: correction rounds refined by CG (0: Y dlambda alone)
  // lagged: the rows' compliance columns Y = P^-1 H^T of an earlier frame
  // of the same factor serve while every row (by key) changed its
  // coefficients by at most this fraction (0: only identical rows), [0, 1]
  double compliance_reuse = 0.1;
  // A probe moving more than half its radius a frame is swept: faces it
  // went through get rows (collision_stage.cpp, sweep_probe). Off: it fixes
  // a jab into thick tissue at the cost of the press it then simulates
  // (docs/instruments.md, "Fast motion").
  bool sweep = false;
  // Speculative rows for tissue that may run into a probe faster than the
  // margin a frame (add_speculative_contacts). Off: measured to help a
  // coarse beam falling onto a probe and to make a finer one bounce.
  bool speculative = false;
};

// A haptic device driving one instrument from a 1 kHz thread (scene key
// "haptics"; docs/haptics.md). Only `incise run --haptics` (or an embedding
// application, haptics/haptic_stage.h) starts the thread; otherwise the
// instrument follows its own trajectory or pose. Lengths in the scene's
// unit (metres in the bundled scenes), forces in newtons.
struct HapticsSpec {
  enum class Device { None, Scripted, Replay, OpenIGTLink };
  Device device = Device::None;   // None: no "haptics" key
  int instrument = 0;             // scene.instruments index (the key gives its name; default the first)
  std::string trajectory;         // scripted: keyframe CSV (default: the instrument's trajectory)
  std::string stream;             // replay: a recorded device stream (haptics/replay_device.h)
  int port = 18944;               // openigtlink: TCP port to listen on (0: any free one)
  double rate_hz = 1000.0;        // ticks per second, [100, 10000]
  double max_force = 3.3;         // N: the device's limit; the force is clamped to it
  double scale = 1.0;             // device units -> scene units (openigtlink default 0.001: mm -> m)
  Vec3 offset{};                  // added after scaling (device origin in the scene)
  double stiffness = 1000.0;      // coupling.stiffness: virtual coupling spring (N per scene unit), > 0
  double damping = 0.5;           // coupling.damping: on the device-proxy velocity (N s per unit), >= 0
  std::optional<Vec3> center;     // guard.center: workspace centre (default: the mesh's bounding-box centre)
  double workspace_radius = 1.0;  // guard.workspace_radius: farther readings are rejected, > 0
  double max_speed = 2.0;         // guard.max_speed: faster readings are a jump (units per second), > 0
  double max_turn = 20.0;         // guard.max_turn: faster turns are a jump (rad/s), > 0
  double reacquire = 0.2;         // guard.reacquire: s of agreeing readings before a jump is taken back, >= 0
  double glide_speed = 0.05;      // guard.glide_speed: how fast the tool goes to a reacquired reading (units/s), > 0
  bool realtime = true;           // ask for SCHED_FIFO (falls back, and says so, without the right)
};

// Linear-solver policy of the dynamics (issue 4). Every policy is measured
// against `exact` by `incise compare`; none is applied silently.
enum class SolverPolicy {
  Exact,     // numeric refactorization of the corotated system every frame
  Lagged,    // CG on the current system, preconditioned by an older frame's factor
  Warped,    // factor of the rest system, per-node rotations around the solve
  WarpedCG,  // CG on the current system, preconditioned by the warped solve
};
enum class FactorMethod { Auto, Supernodal, Simplicial };  // CHOLMOD's choice or forced
enum class OrderingMethod { Auto, Amd, Metis };            // CHOLMOD's default tries both
// The lagged preconditioner's copy of the factor: none (CHOLMOD's doubles), float, or
// binary16 scaled per supernode (CholmodSolver::set_factor_copy).
enum class FactorCopy { None, Float, Half };

// How the solver runs on this machine, not what it computes: threads, CPUs
// and priorities. Scene keys under solver.*, but kept out of the Model: the
// Workspace holds them (engine/solve/workspace.h).
struct RuntimeSettings {
  int threads = 2;               // solver.threads: assembly workers incl. the calling thread (1..64)
  int substitution_threads = 1;  // solver.substitution_threads: 1 or 2 threads per substitution (supernodal factor)
  bool split_affinity = false;   // solver.affinity "split" (engine/runtime/thread_affinity.h) or "none"
  bool idle_background = true;   // lagged, background: solver.background_priority "idle" (true) or "normal"
};

struct SolverSettings {
  SolverPolicy policy = SolverPolicy::Exact;  // solver.policy
  int refresh_every = 1;       // lagged: refactor every k frames (>= 1)
  bool background = false;     // lagged: factorize on a second thread, used from the next refresh on
  bool warp = false;           // lagged: rotate the lagged factor by the node rotations since its frame
  FactorCopy factor_copy = FactorCopy::Float;  // lagged: the preconditioner substitutes with this copy of the factor
  bool single_factorization = false;  // lagged: solver.factor_precision "single" (engine/solve/single_factor.h) or "double"
  int rescue_after = 0;        // lagged: CG iterations after which the current matrix is factored now (0 = never)
  bool skip_late_factor = false;  // lagged + background: solver.late_factor "skip" (true) or "wait"
  bool multiplicative_patch = true;  // lagged after cuts: solver.patch "multiplicative" (true) or "additive"
  bool carry_ordering = true;        // lagged after cuts: solver.cut_ordering "carried" (true) or "search"
  double tolerance = 1e-6;     // CG: relative residual |r| / |b| (> 0, < 1)
  bool previous_guess = true;  // CG: solver.initial_guess "previous" (the last frame's increment, scaled) or "zero"
  int max_iterations = 50;     // CG iterations per solve (>= 1)
  // CG: solver.matrix_precision "single": CG's products with A read a float
  // copy of it (half the bytes of the frame's most-read matrix after the
  // factor); the Newton residual stays in double, so only the step moves,
  // by about 6e-8 of A (docs/numerics.md, "CG's matrix in single precision").
  bool single_matrix = false;
  // CG: solver.frame_iterations, CG iterations per frame over all its Newton
  // iterations (0 = no cap): once spent, the frame accepts the residual it
  // has (FrameTiming::budget_spent) instead of iterating or rescuing further.
  int frame_iterations = 0;
  // lagged: the DOFs of a mesh node with a region of its support below this
  // fraction of it (a tiny cut piece) are condensed out exactly every Newton
  // iteration; CG solves the rest (0 = none; engine/solve/condensed_dofs.h).
  double condense_below = 0.05;
  bool coarse = false;         // lagged: solver.coarse "corners" (two-level, engine/solve/coarse_space.h) or "none"
  // lagged: the DOF nodes within this many element rings of the grasp
  // rows' nodes form a patch factored exactly every frame and combined with
  // the lagged factor like a cut's patch (0 = none; linear_solve.cpp
  // lagged_patch).
  int contact_patch = 0;
  FactorMethod factor = FactorMethod::Auto;
  OrderingMethod ordering = OrderingMethod::Auto;
};
const char* policy_name(SolverPolicy p);
// What `incise render` / `run --render` / `bench --render` draw and how
// (scene key "render"; docs/scene-format.md). Colours are linear RGB in [0, 1].
struct RenderSettings {
  int width = 640, height = 480;        // pixels, each in [16, 8192]
  int subdivision = 2;                  // segments per tet10 face edge: n^2 flat triangles per face, [2, 16]
  std::optional<Vec3> camera_position;  // absent: framed from the mesh's bounding box
  std::optional<Vec3> camera_target;    // absent: the bounding-box centre
  Vec3 camera_up{0.0, 0.0, 1.0};        // nonzero
  double fov_deg = 30.0;                // vertical field of view, (0, 180)
  std::optional<Vec3> light_direction;  // direction the light travels (unit); absent: from above-left of the camera
  double ambient = 0.25;                // share of light that ignores orientation, [0, 1]
  Vec3 color_tissue{0.85, 0.55, 0.50};
  Vec3 color_interior{0.70, 0.10, 0.15};  // faces on a cut surface
  Vec3 color_background{0.12, 0.12, 0.14};
  Vec3 color_instrument{0.75, 0.77, 0.80};
};

// A command-line override of one scene key, applied to the scene's JSON
// before it is parsed, so the parser checks it like a key of the file
// (`incise bench scene.json --set solver.policy=lagged`).
struct ScenePatch {
  std::string key;    // dotted path: "solver.policy", "cuts.0.at_time" (also "cuts[0].at_time")
  std::string value;  // parsed as JSON when it is valid JSON (1e-3, true, [0, 0, -1], "x"), else taken as a string
  std::string given;  // as the user wrote it, for messages: "--set solver.policy=lagged" or "--policy lagged"
};
// Parses the text of one --set, "KEY=VALUE". Throws incise::Error ("--set foo:
// expected KEY=VALUE ...") when there is no '=' or the key is empty.
ScenePatch parse_scene_patch(const std::string& text);

// Where a resolved solver.* / integrator.* value came from (Scene::origin).
struct SettingOrigin {
  enum class Kind { Default, Scene, Preset, Patch };
  Kind kind = Kind::Default;
  std::string detail;  // Preset: the preset's name; Patch: the patch as given ("--set solver.policy=lagged")
};

// The most frames run.frames (and the command line's --frames) may ask for:
// 9.3 h at 30 Hz. The run's timings alone take 320 bytes a frame.
inline constexpr int kMaxFrames = 1000000;

struct Scene {
  std::string path;       // the scene file as given
  // The --set patches applied: (the JSON path each set, in the parser's
  // notation "cuts[0].at_time"; the patch as given), for checks made after
  // parsing (key_origin).
  std::vector<std::pair<std::string, std::string>> patched;
  std::string mesh_file;  // resolved relative to the scene file's folder
  int order = 2;          // element order the model uses (a tet4 mesh is raised to 2)
  Material material;
  MassKind mass = MassKind::Lumped;
  Vec3 gravity{0.0, 0.0, -9.81};
  std::vector<Region> fixed;
  std::vector<Prescribed> prescribed;
  double dt = 1.0 / 30.0;        // integrator.dt, > 0
  int newton_iterations = 1;     // integrator.newton_iterations, >= 1: linearised solves every step
  // Extra iterations (up to max_newton_iterations in all) while a rotation moved
  // more than rotation_tolerance (radians) between the configuration it was
  // frozen at and the step's result; 0 turns the check off. See docs/numerics.md.
  int max_newton_iterations = 4;
  double rotation_tolerance = 0.1;
  // The rotation test over the body, not at its worst point
  // (integrator.rotation_fraction, rotation_rms; docs/numerics.md,
  // "Linearisation, iterations and stability"): iterate again while the
  // slots that turned more than rotation_tolerance hold more than
  // rotation_fraction of the body's volume (0: any slot, the test before the
  // twenty-sixth session), or while the volume-weighted RMS of every slot's
  // turn is above rotation_rms (0: off).
  // A few crushed points (singular values of F near 0.1: their rotation is
  // ill-conditioned and does not settle) no longer decide alone.
  double rotation_fraction = 1e-4;
  double rotation_rms = 0.02;
  // integrator.line_search: an iteration whose configuration has a larger
  // residual than the one before is taken back halfway, up to 3 times
  // (engine/dynamics/step.cpp, assemble_system). Off by default: it costs an
  // assembly per halving; for converged references of hard frames.
  bool line_search = false;
  // integrator.residual_tolerance (>= 0, 0 = off): also iterate while the
  // relative residual at the last iteration's start (|r| / |(f_gravity,
  // f_int)|) is above this; the rotation test alone stops at iterates the
  // tangent approaches only linearly. For converged references.
  double residual_tolerance = 0.0;
  // Newmark parameters (integrator.newmark_gamma / newmark_beta): gamma = 1/2
  // with beta = 1/4 is the trapezoidal rule (no numerical damping); gamma > 1/2
  // damps the high frequencies (docs/numerics.md, "Numerical damping").
  double newmark_gamma = 0.5;
  double newmark_beta = 0.25;
  // integrator.recovery: "backward_euler" (true, the default) takes the step
  // of a frame in which a cut severs a piece, and of each frame after one
  // whose Newton iteration stopped at its cap with the rotations still
  // moving, by backward Euler instead of Newmark's rule
  // (State::recovery; docs/numerics.md, "Recovery steps"); "none": Newmark's
  // rule in every step.
  bool recovery_steps = true;
  // integrator.tangent: "frozen_rotation" (R K0 R^T) or "consistent" (plus the
  // dR/dF term of engine/fem/rotation_stiffness.h).
  bool consistent_tangent = false;
  bool increment_predictor = false;  // integrator.predictor: "velocity" (false, the default) or "increment"
  // integrator.tangent_reuse (>= 0, 0 = off): an element keeps the tangent
  // blocks it assembled while every deformation gradient of its rotation
  // slots stays within this (largest entry of F - F_then) of the one they
  // were computed at; forces are always exact (docs/numerics.md).
  double tangent_reuse = 0.0;
  SolverSettings solver;                // solver.* (what the solver computes)
  RuntimeSettings runtime;              // solver.threads, substitution_threads, affinity, background_priority
  // solver.preset: "" (none), "realtime" or "reference" (docs/scene-format.md,
  // "Presets"). A preset fills the solver.* and integrator.* keys the scene
  // and the patches leave unset.
  std::string preset;
  // "solver.policy", "integrator.tangent", ... -> where the value came from
  // (scene file, preset, or a patch); a key that is absent kept its default.
  std::map<std::string, SettingOrigin> origin;
  bool initial_static = false;          // initial: "static" (frame 0 at static equilibrium) or "rest" (unstressed)
  double static_tolerance = 1e-8;       // static.tolerance: relative residual
  int static_max_iterations = 50;       // static.max_iterations
  int frames = 60;                      // run.frames default for `incise run`
  OutputSettings output;
  std::vector<CutSpec> cuts;
  // cut_front "enriched": cut fronts inside elements open up to the front
  // line (the front enrichment of engine/model/cut_layout.h) instead of
  // closing at the last fully crossed face ("faces"): a scene cut's once it
  // is complete; a scalpel's incision keeps its front on faces
  // (cutting/cut_apply.cpp prepare_cut, docs/cutting.md).
  bool front_enrichment = false;
  // cut_stabilization: a piece under 10% of its tet10 element also
  // integrates its field over the whole element with this weight times its
  // volume fraction (engine/model/model_build.cpp add_piece_extension,
  // docs/cutting.md "Small pieces"); 0 = off.
  double cut_stabilization = 0.1;
  std::vector<InstrumentSpec> instruments;
  ContactSettings contact;
  HapticsSpec haptics;
  RenderSettings render;
};

// Reads and validates a scene file, with `patches` applied in order to its
// JSON before it is parsed (then solver.preset is expanded). Throws
// incise::Error: an error in a patched key names the patch as given
// ("--set solver.policy=lagged2: solver.policy must be one of ...").
Scene load_scene(const std::string& path, const std::vector<ScenePatch>& patches = {});
// Same, from text already read (path used for messages and relative paths).
// `trajectories_needed` false (a replay): trajectory files are named, not
// required to exist.
Scene parse_scene(const std::string& json_text, const std::string& path, const std::vector<ScenePatch>& patches = {},
                  bool trajectories_needed = true);

// Where a scene value came from, to start an error message with: the --set
// patch that set the JSON path `where` (or an object around it), else the
// scene file ("--set instruments.0.radius=1e-9: instruments[0].radius ...").
std::string key_origin(const Scene& scene, const std::string& where);

// One resolved setting for print-outs: every solver.* and integrator.* key
// the resolved solver.policy uses, in the parser's order.
struct ResolvedSetting {
  std::string key;    // "solver.refresh_every"
  std::string value;  // as JSON: 3, "lagged", true
  SettingOrigin origin;
};
std::vector<ResolvedSetting> resolved_settings(const Scene& s);

// Whether solver.<key> means something under `policy`: the parser refuses a
// policy-specific key under another policy (tolerance under exact, ...).
bool solver_key_used_by(const std::string& key, SolverPolicy policy);

// The patches that turn the scene a run resolved (`run`, loaded with
// `patches`) into `incise compare`'s exact reference: appended to the run's
// patches they replace the whole solver object by solver.preset "reference"
// (policy exact, nothing lagged or iterative) keeping run.solver.threads,
// keep the run's integrator.tangent and predictor (the same equations and starts) and set
// integrator.tangent_reuse 0 (every element assembled). No preset or
// solver patch of the run reaches the reference.
std::vector<ScenePatch> exact_reference_patches(const Scene& run);

}  // namespace incise
