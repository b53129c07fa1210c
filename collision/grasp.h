#pragma once
// A grasper holding tissue: when its jaw value reaches grasp_at, the surface
// points between the jaws are taken (material points: element, piece, local
// coordinates) with their position in the tool frame; while it stays closed
// each held point must end the frame where the jaws carry it, as three
// bilateral rows per point (engine/dynamics/contact_rows.h); when the jaw
// value drops below grasp_at they are let go.
#include <vector>

#include "collision/tissue_surface.h"
#include "engine/dynamics/contact_rows.h"
#include "engine/model/model.h"
#include "engine/runtime/tool_pose.h"
#include "engine/scene/scene.h"

namespace incise {

struct HeldPoint {
  int elem = -1, piece = -1;
  int side = 0;                 // of the front's cut plane (TissueSurface::vert_side)
  double rst[3] = {0, 0, 0};
  double local[3] = {0, 0, 0};  // position in the tool frame when it was taken
};

struct Grasp {
  bool holding = false;
  // Closed with no surface vertex between the jaws (update_grasp keeps
  // looking each frame while they stay closed); cleared when they open.
  bool closed_empty = false;
  int model_version = -1;       // of the pieces in `held`
  std::vector<HeldPoint> held;
  // The jaw value the grasp took hold at: grasp_at, or less when the jaws
  // closed onto the tissue from both sides first (update_grasp's `pressed`);
  // it lets go once the jaw falls below it.
  double took_at = 1.0;
};

// The points a grasp took when it closed (frame: State::frame of the frame
// it closed in; tool: the instrument), as logged by the collision stage and
// imposed on another run of the same scene (incise compare: the policy's
// grasps take the reference's points, so its error measures the solver, not
// which surface points happened to lie between the jaws).
struct GraspTaken {
  int frame = 0, tool = 0;
  std::vector<HeldPoint> held;
};

// Most points a grasp holds (three rows each).
inline constexpr int kMaxHeldPoints = 6;

// Takes or lets go as the jaw value at the frame's end says. Takes the
// surface vertices (where the tissue is now) inside the jaws' box, between
// their inner faces and up to a jaw thickness beyond, nearest the tool's
// origin, at their place in the tool frame at the frame's start. After a cut
// (a new model version) the held points' pieces are looked up on `model`.
// imposed: when closing, take these points instead (their pieces looked up
// on `model`).
// pressed: both jaws pushed the tissue in the last frame while closing (a
// grasper with `contact`): the grasp takes hold now, below grasp_at, instead
// of squeezing the tissue between two contacts until then.
void update_grasp(const Model& model, const InstrumentSpec& spec, const ToolFrame& tool, const TissueSurface& surface,
                  int model_version, Grasp& grasp, const std::vector<HeldPoint>* imposed = nullptr,
                  bool pressed = false);

// The rows of a holding grasp: each point from where it is now to where the
// jaws carry it at the frame's end (moving with them: the rows' velocity).
// `surface` is synced to `state`.
void add_grasp_rows(const State& state, const Grasp& grasp, const ToolFrame& tool_frame, double dt, int tool,
                    const TissueSurface& surface, ContactRows& rows);

}  // namespace incise
