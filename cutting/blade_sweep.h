#pragma once
// The cut a scalpel makes: in each frame its cutting edge moves from its pose
// at the frame's start to its pose at the end; the band it sweeps, where it
// passes through the tissue, is mapped into reference coordinates (X-FEM cuts
// live there) and appended to the State's swept triangles. The cutting stage
// (cut_stage.h) cuts along all of them, with the scene's declared cuts, as a
// progressive cut: the layout changes only when the set of split elements does.
#include <array>
#include <vector>

#include <Eigen/Core>

#include "engine/model/tissue_locator.h"
#include "engine/runtime/simulation.h"

namespace incise {

// Appends to sim.state.swept the triangles each scalpel's edge swept in the
// coming frame (sim.tools: before -> after), when the band meets the tissue.
// Returns how many were added. Under cut_front "enriched" it also appends
// to State::blade_done each stroke a scalpel finished (its edge at the
// frame's end pose outside the tissue after it swept bands: that stroke's
// front is enriched, cut_apply.cpp), and sets *blade_done_changed then.
int sweep_blades(Simulation& sim, bool* blade_done_changed = nullptr);

// The band a scalpel sweeps in one motion step is a strip of quads along its
// edge, one per segment: the edge is cut into segments of about two of the
// smaller elements (four sweep_spacings), at least kMinEdgeSegments and at
// most kMaxEdgeSegments, fixed for a run (edge_segments): samples in the
// tissue map to reference coordinates by the element holding them, so the
// band follows the tissue's deformation along the edge. Whether a step's
// edge is in the tissue is asked finer, every sweep_spacing along it: three
// samples (the ends and the middle) were the edge's only test, and an 8 cm
// blade drawn through a 2 cm beam, or a 2 cm blade across a 3 mm sheet 6 mm
// off its middle, cut nothing. (Each segment adds two facets a step to the
// incision's surface, and the cut layout's queries scan them: eight
// segments instead of two made organ_instruments' cut frames' layout 6 ->
// 15 ms, docs/benchmarks.md "A scalpel's edge".)
inline constexpr int kMinEdgeSegments = 2;
inline constexpr int kMaxEdgeSegments = 8;
// At most this many edge samples a motion step (the in-tissue test).
inline constexpr int kMaxEdgeSamples = 256;

// The step a frame's edge motion, and the edge itself, are sampled at: half
// the size (cube root of the corner tetrahedron's volume) the smallest 5% of
// the mesh's elements stay under, so thin tissue meshed one or two elements
// thick is not stepped over. From the mesh as read, so that it (and
// edge_segments) stays the same through a run's cuts.
double sweep_spacing(const Mesh& mesh);
// The band's segments along a scalpel's edge: about one per four spacings.
int edge_segments(const InstrumentSpec& spec, double spacing);
// A frame's motion is swept in steps of at most half the size of the
// smaller elements (sweep_spacing), and at most this many: a blade that
// passes through thin tissue within one frame, outside it at both ends,
// still cuts it.
inline constexpr int kMaxSweepSteps = 64;
// A band whose edge samples all lie within this many element sizes of the
// blade's incision so far (of its facets' planes, and not further ahead of
// its boundary) re-cuts it and is dropped.
inline constexpr double kReCutReach = 0.25;

}  // namespace incise
