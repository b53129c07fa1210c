#pragma once
// The collision stage plugged into the frame's pipeline: the tissue's FCL
// model synced to the State (refit, or rebuilt after a cut), each instrument
// posed where it will be at the end of the frame, and what the step must
// respect turned into rows of ws.contacts (engine/dynamics/contact_rows.h):
//   probe, open grasper  contacts: the tissue point must move by the depth
//                        along the contact normal (unilateral), one per
//                        tissue face and tool part (contact.rows "face": a
//                        round part's at the face's weighted point,
//                        collision/face_contact.h, a box's at the deepest
//                        point), plus two friction rows each with
//                        contact.friction > 0;
//   closed grasper       the held points follow the jaws (bilateral,
//                        collision/grasp.h); opening releases them;
//   scalpel              nothing here: its edge cuts (cutting/blade_sweep.h).
// Contacts are found with the tissue where it is (start of the frame) and
// the tool where it will be (end), inflated by a margin so that tissue moving
// towards a tool during the frame is caught too (such rows have a negative
// target: inactive unless the tissue closes the gap). Two options, off by
// default (docs/instruments.md, "Fast motion"): contact.sweep (a probe that
// moves more than half its radius in the frame is swept; a face its path
// struck from outside, and its end pose does not touch, gets a row along
// its inward normal to leave the end pose; none for a path through the
// tissue) and contact.speculative (rows with negative targets for tissue
// that may run into a probe faster than the margin). Installed only when
// the scene has a probe that pushes or a grasper.
#include <vector>

#include "collision/collision_model.h"
#include "collision/contact_query.h"
#include "collision/grasp.h"
#include "collision/tool_shape.h"
#include "engine/runtime/simulation.h"

namespace incise {

// What the stage keeps between frames (sim.module_data[kStageCollision]).
struct CollisionData {
  CollisionModel model;
  std::vector<ToolShape> shapes;         // (instruments) posed at the frame's end, inflated by the margin
  std::vector<double> margin;            // (instruments) detection margin (tool length units)
  std::vector<ContactResult> results;    // (instruments) the last query
  std::vector<Grasp> grasps;             // (instruments) held points of graspers
  std::vector<GraspTaken> taken;         // every grasp's points when it closed, in order
  std::vector<GraspTaken> imposed;       // points to take instead when a grasp closes (incise compare)
  ContactRequest request;
  std::vector<unsigned char> face_seen;  // (surface faces) tool parts with a row on the face this frame
  struct Candidate {
    double depth;     // penetration of the real (not inflated) tool; < 0 within the margin
    int tool, index;  // instrument, contact in results[tool]
    long long id;     // what the row holds across frames (its key's id)
  };
  std::vector<Candidate> candidates;     // this frame's, deepest first (kept: no allocation per frame)
  std::vector<char> warned_deep;         // (instruments) a probe's "deeper than half its radius" warning was given
  std::vector<int> untouched_frames;     // (instruments) frames since the probe last found a contact (capped)
  std::vector<char> warned_inside;       // (instruments) its "lost its contact inside the tissue" warning was given
  std::vector<char> grasped_dof;         // (ndof) this frame: a grasp row holds the DOF
  std::vector<char> warned_held;         // (instruments) its "pressed tissue a grasper holds" warning was given
  // A fast probe's sweep and speculative query (collision_stage.cpp,
  // sweep_probe, add_speculative_contacts): their shapes (instruments;
  // inflated as `shapes`, their FCL geometry shared), their query, and
  // which surface faces already have a contact this frame.
  std::vector<ToolShape> sweep_shapes;
  ContactResult sweep_result;
  std::vector<unsigned char> sweep_face;
};

// A probe whose axis moves more than this share of its radius in a frame is
// swept: its end pose alone may have passed faces it went through.
inline constexpr double kSweepStepShare = 0.5;
// At most this many sub-poses a frame (a stroke of 500 radii a frame).
inline constexpr int kMaxSweepSteps = 1000;

// A probe that lost its contacts is checked for lying inside the tissue
// for this many frames after (collision_stage.cpp, check_probe_inside).
inline constexpr int kInsideCheckFrames = 10;

// Fraction of an instrument's smallest dimension used as detection margin.
inline constexpr double kContactMarginShare = 0.25;
// Tissue near a probe that may move more than the margin in a frame gets
// speculative rows within this multiple of that motion
// (collision_stage.cpp, add_speculative_contacts).
inline constexpr double kSpeculativeShare = 1.25;

void collision_stage(Simulation& sim);
void install_collision_stage(Simulation& sim);

// The stage's data (nullptr when the stage is not installed).
CollisionData* collision_data(Simulation& sim);

// A copy of instrument i's shape at `pose`, not inflated: for penetration
// measurements (max_penetration) and rendering.
ToolShape instrument_shape(const Simulation& sim, int i, const ToolPose& pose);

}  // namespace incise
