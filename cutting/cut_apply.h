#pragma once
// A cut update: applies the scene's cuts that are due, rebuilds the Model
// with the new X-FEM layout ([preprint] eqs. (42), (44): enriched DOFs
// appended), moves the State's fields onto it and hands the Workspace to
// carry_workspace_over_cut (engine/solve/workspace_carry.h). The frame's
// cutting stage (cut_stage.h) calls update_cuts, start_cut_ahead and
// prepare_cut_now.
#include "cutting/xfem_layout.h"
#include <array>
#include <string>
#include <vector>

#include "engine/runtime/simulation.h"
#include "engine/runtime/timing.h"

namespace incise {

struct CutUpdate {
  bool changed = false;  // the model (DOF set) changed this frame
  CutReport report;      // of the new layout
  double ms = 0.0;       // time spent (layout, model, analysis, transfer)
  std::array<double, kNumCutParts> part_ms{};  // its parts (engine/runtime/timing.h)
  bool ahead = false;    // layout and model were prepared during the previous frame (start_cut_ahead)
  bool early = false;    // ... beside this frame's collision stage (prepare_cut_now)
};

// Cuts with at_time <= t are active; a swept cut covers its sweep up to time
// t_sweep (pass the end of the coming frame). Rebuilds only when the set of
// split elements changes (a blade tip moving inside an element changes nothing).
// swept_changed: instruments added swept triangles (State::swept) this frame.
CutUpdate update_cuts(Simulation& sim, double t, double t_sweep, bool swept_changed = false);

// Starts preparing, on a helper thread, the cut update of the frame at time t
// (swept cuts reaching t_sweep): its layout and next Model, which read only
// the current model, mesh and scene. Call it after this frame's update_cuts
// and before its step; the next update_cuts with those times takes the
// result (waiting for it if needed), so the layout and the model build run
// beside the step instead of before it. Does nothing when that update would
// change nothing. The helper holds a reference to `sim`: nothing but the
// step may change sim.model until the next update_cuts (which joins it).
void start_cut_ahead(Simulation& sim, double t, double t_sweep);

// Prepares the cut update of the frame at time t itself, now, once its
// scalpels have swept (sweep_blades): the cutting stage's start
// (cut_stage.cpp), which runs while the collision stage runs on a helper
// (Pipeline::set_start). The cutting stage's update_cuts with those times
// takes the result. A scalpel's band is known only once the frame's poses
// are, so it cannot be prepared a frame ahead.
void prepare_cut_now(Simulation& sim, double t, double t_sweep);

// Applies every scene cut completely (static solves).
CutUpdate apply_all_cuts(Simulation& sim);

// The scene cuts that, once complete, cross no element of sim.model, one
// message each ("scene.json: cuts[1] does not cross the body: it cuts
// nothing"), so a misplaced cut is not silently a no-op.
std::vector<std::string> cuts_that_cut_nothing(const Simulation& sim);
// Prints them, and fronts_left_on_faces', to stderr as warnings; called once
// when cutting is set up.
void warn_cuts_that_cut_nothing(const Simulation& sim);
// cut_front "enriched": the scene cuts whose fronts, all cuts complete, stay
// on element faces (compute_cut_layout's fronts_on_faces), one message each.
std::vector<std::string> fronts_left_on_faces(const Simulation& sim);

struct Kinematics {
  std::vector<double> u, v, a;  // (to.ndof) the transferred fields
  std::vector<double> du;       // (to.ndof) State::du likewise; empty when the old state had none
};

// Moves kinematics to a model with more cuts (same mesh): every piece of the
// new model keeps the displacement, velocity, acceleration (and last increment) of the old piece
// it lies in, so the field is unchanged by the cut itself: a piece's nodal
// value is d_a = u_a + q_a ([preprint] eq. (66)), so u_a takes the home
// piece's value and q_a = d_a(old piece) - u_a. Where the new layout joins
// old regions (a scalpel's bands are not nested), a DOF takes their values'
// mean weighted by their lumped masses at the node, keeping its momentum.
// Returns (to.ndof) arrays.
Kinematics transfer_kinematics(const Model& from, const State& old, const Model& to);

// For each DOF node of `to` (a model with more cuts, same mesh) the DOF node
// of `from` carrying the same field: mesh nodes map to themselves, an
// enriched DOF node to the enriched DOF node of the old piece its piece lies
// in (-1 where that old piece was the node's home, i.e. the DOF is new).
std::vector<int> dofnode_map(const Model& from, const Model& to);

// Whether element e is split into the same sub-tetrahedra, piece by piece,
// in both models (enriched DOF node ids may differ); false where either has
// no cuts.
bool same_subtets(const Model& a, const Model& b, int e);

}  // namespace incise
