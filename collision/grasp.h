#pragma once
// A grasper holding tissue: when its jaw value reaches grasp_at, the surface
// between the jaws is taken, as material points (element, piece, local
// coordinates: the centroids of the surface triangles there, each with its
// area) with their position in the tool frame; while it stays closed the
// held patch moves with the jaws, and when the jaw value drops below
// grasp_at it is let go.
//
// The patch, not each point, is held: six bilateral rows
// (engine/dynamics/contact_rows.h) make its area-weighted mean translation
// and least-squares rotation those of the jaws (a rigid fit, linearised
// about the points' current positions; rows of a rotation the points cannot
// define, as for points on one line, are left out). The force is then a
// traction over the held area (H^T lambda with weights area_p / area, one
// point per surface triangle), the tissue between the jaws deforms about
// that rigid motion, and a fast drag does not pull a few nodes through the
// mesh as one point constraint per grid vertex did (docs/benchmarks.md,
// Issue 20: elements next to 4 held vertices inverted at 6.7 mm a frame).
// Rows stay six however many points are held.
#include <vector>

#include "collision/tissue_surface.h"
#include "engine/dynamics/contact_rows.h"
#include "engine/model/model.h"
#include "engine/runtime/tool_pose.h"
#include "engine/scene/scene.h"

namespace incise {

struct HeldPoint {
  int elem = -1, piece = -1;
  double rst[3] = {0, 0, 0};
  double local[3] = {0, 0, 0};  // position in the tool frame when it was taken
  double area = 0.0;            // of the surface triangle it is the centroid of, when taken
};

struct Grasp {
  bool holding = false;
  int model_version = -1;       // of the pieces in `held`
  std::vector<HeldPoint> held;
};

// Most points a grasp holds (the rows are six however many).
inline constexpr int kMaxHeldPoints = 32;

// Takes or lets go as the jaw value at the frame's end says. Takes the
// surface triangles whose centroid (where the tissue is now) lies inside the
// jaws' box, between their inner faces and up to a jaw thickness beyond,
// nearest the tool's origin, at their place in the tool frame at the
// frame's start. After a cut
// (a new model version) the held points' pieces are looked up on `model`.
void update_grasp(const Model& model, const InstrumentSpec& spec, const ToolFrame& tool, const TissueSurface& surface,
                  int model_version, Grasp& grasp);

// The rows of a holding grasp: the patch from where it is now to where the
// jaws carry it at the frame's end (moving with them: the rows' velocity).
// Rows 0-2: the area-weighted mean displacement along x, y, z (dir = the
// axis, lambda a force in N). Rows 3-5: the rotation about the principal
// axes e of the patch's J = sum a_p (|r_p|^2 I - r_p r_p^T) (a_p = area_p /
// area), scaled by rho_e = sqrt(j_e), the patch's rms radius about e, so the
// row reads a displacement (omega rho_e) and lambda is a force at that
// radius; dir = 0 (no net force). `surface` is
// synced to `state`.
void add_grasp_rows(const State& state, const Grasp& grasp, const ToolFrame& tool_frame, double dt, int tool,
                    const TissueSurface& surface, ContactRows& rows);

}  // namespace incise
