#pragma once
// Where a round tool part (sphere, capsule) presses one surface face: the
// point of the face's contact row (collision/collision_stage.h, scene
// contact.rows "face", the default).
//
// The deepest point of a face is a poor row point once the tissue wraps
// the tool: every point of the face then lies near the tool's surface, and
// which one is deepest (and with it the sphere's normal there) jumps from
// frame to frame as each frame's correction pushes the last deepest point
// out and lets another in. A held probe's force alternated so by +-12% at
// 15 Hz, and Newton stayed at its cap (docs/benchmarks.md, "A held probe's
// force: the row at the face's weighted point"). The row is placed instead
// at the face's weighted material point
//   rst_f = sum_j w_j rst_j / sum_j w_j,
//   w_j = a_j max(0, r - |x_j - y(x_j)|)^p   (samples j over the face, area a_j),
// r the part's radius inflated by the detection margin, y(x) the axis point
// nearest x, p = 3, the samples the centroids of k^2 sub-triangles of each
// of the face's triangles, plus each triangle's own nearest point to the
// axis with the weight a (depth_t^p - max depth_j^p over its samples): a
// touch between samples, or a thin sliver at the contact's rim, still has
// a point. Every weight vanishes where its point leaves the inflated tool
// and a triangle's nearest point is continuous in the tool's pose (the
// argmax over a face's triangles is not: the face's own deepest point as
// that fallback made the row point jump at a rim, tests/collision/
// test_face_contact.cpp), so rst_f moves continuously with the tissue. The
// margin is what lets the weights see a face that wraps the tool without
// penetrating it (with the real radius a settled face has no weight left
// and the rule falls back to the deepest point, chatter included); the
// power keeps the point near the deepest region of a face the tool only
// partly covers. The row's normal and depth are the tool's at the material
// point x(rst_f): (x - y) / |x - y| and r - |x - y|.
//
// What it costs: one row still holds one point of a face, so the rest of a
// face the tool covers may stay inside it; measured against one row per
// triangle on a refined surface (contact.rows "triangle", render.subdivision
// 4-8), the converged reference: total force within 3%, penetration 0.5-0.7 mm
// under a 1 cm probe pressed 6 mm (docs/benchmarks.md).
#include "collision/contact_query.h"
#include "collision/tissue_surface.h"
#include "collision/tool_shape.h"

namespace incise {

// Moves c (the deepest contact of `part`, inflated, with face c.face, from
// query_contacts) to the face's weighted point; u: the displacement the
// surface's positions were computed from ((ndofnode, 3)). c.depth is then
// the inflated depth at that point (it may be <= 0: the point lies on the
// tool's surface or off it). Leaves c as it is for a box part, and where
// the axis has passed the point (the face rule of collision/narrowphase.h
// keeps the direction there). Allocates nothing.
void weight_round_face_contact(const TissueSurface& s, const ToolPart& part, const double* u, TissueContact& c);

}  // namespace incise
