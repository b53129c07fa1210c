#pragma once
// The physical State of a simulation: what the next frame starts from and a
// replay hashes. A small copyable value: no solver, threads, caches or
// timings (those live in the Workspace, engine/solve/workspace.h). Together
// with the scene and the Model it was stepped on, a State determines the
// next frame (with deterministic solver settings: no `late_factor: skip`).
#include <array>
#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

namespace incise {

struct Model;

struct State {
  double time = 0.0;
  int frame = 0;
  std::vector<double> u, v, a;        // (ndof) displacement, velocity, acceleration
  std::vector<double> R;              // (nrot, 9) rotation of each slot, column-major
  // (ndof) the last step's increment u(t) - u(t - dt): the next step's
  // Newton predictor (integrator.predictor); empty before the first step.
  std::vector<double> du;
  std::vector<double> cut_progress;   // (scene.cuts) share of each cut applied: -1 none, 1 whole
  // Cuts made by instruments (cutting/blade_sweep.h): the triangles a
  // scalpel's edge swept inside the tissue, in reference coordinates.
  std::vector<double> swept;          // (ntri, 9) corners
  std::vector<double> swept_tool;     // (ntri) the instrument (scene.instruments index)
  std::vector<double> swept_frame;    // (ntri) the frame that swept it
  // cut_front "enriched" only (empty otherwise): the scalpels' finished
  // strokes, in order, as (instrument, how many of its swept triangles it
  // had when its blade left the tissue). Each finished stroke is a surface
  // with an enriched front; the triangles after its last one are the
  // stroke in progress, on faces (cutting/cut_apply.cpp).
  std::vector<double> blade_done;     // (nstroke, 2)
  // The next step is a recovery step (backward Euler, integrator.recovery):
  // a cut severed a piece before it, or the last step's Newton iteration stopped at
  // its cap with the rotations still moving (engine/dynamics/step.cpp,
  // docs/numerics.md "Recovery steps").
  bool recovery = false;

  bool operator==(const State& o) const {
    return time == o.time && frame == o.frame && u == o.u && v == o.v && a == o.a && R == o.R && du == o.du &&
           cut_progress == o.cut_progress && swept == o.swept && swept_tool == o.swept_tool &&
           swept_frame == o.swept_frame && blade_done == o.blade_done && recovery == o.recovery;
  }
  bool operator!=(const State& o) const { return !(*this == o); }
};

// Hashes of the State's fields (64-bit FNV-1a over their bytes): equal
// states hash equal bit for bit; a replay names the first field that differs.
enum StateField { kFieldClock, kFieldU, kFieldV, kFieldA, kFieldR, kFieldTopology, kNumStateFields };
// (the velocity's hash covers du too, the increment that v came from: a
// replay file keeps one hash per field, and its format did not change)
inline constexpr std::array<const char*, kNumStateFields> kStateFieldNames = {"time/frame", "u", "v/du", "a", "R",
                                                                             "topology"};
std::array<std::uint64_t, kNumStateFields> state_field_hashes(const State& state);
std::uint64_t state_hash(const State& state);  // of the field hashes

// Binary save and restore (little-endian host format, versioned). read_state
// checks the header, every length against the bytes left and the finiteness
// of every value, and throws incise::Error naming `what` and the field.
void write_state(std::ostream& os, const State& state);
State read_state(std::istream& is, const std::string& what);

// Sizes u, v, a (zero) and R (identities) for the model and empties du;
// time, frame and cut progress are left as they are.
void size_state(const Model& model, State& state);

}  // namespace incise
