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

#include "engine/runtime/simulation.h"

namespace incise {

// Reference position of the material point at world position x in the
// current configuration: the element whose deformed corner tetrahedron
// contains x (barycentric coordinates of the corners, the largest smallest
// one), mapped by the same coordinates to the reference corners; outside the
// tissue the nearest such element's map, extrapolated. *inside tells which.
std::array<double, 3> reference_point(const Model& model, const State& state, const double x[3], bool* inside);

// The same for many points of one configuration: the deformed corner
// tetrahedra and their bounding boxes made once (O(elements)); a point
// inside the tissue then tests only the elements whose box holds it, a
// point outside all of them (its extrapolation).
class TissueLocator {
 public:
  TissueLocator(const Model& model, const State& state) : TissueLocator(model, state.u.data()) {}
  // u: the displacement (ndof); null: the reference configuration.
  TissueLocator(const Model& model, const double* u);
  std::array<double, 3> reference(const double x[3], bool* inside) const;  // as reference_point
  bool inside(const double x[3]) const;  // whether x lies in the tissue (no mapping; cheap)

 private:
  Eigen::Vector4d barycentric(int e, const double x[3]) const;
  int best_element(const double x[3], bool all, double& best_min, Eigen::Vector4d& best_L) const;
  const Model* model_;
  std::vector<double> corners_;  // (ntet, 4, 3) deformed corner positions
  std::vector<double> box_;      // (ntet, 6) their bounding boxes (lo, hi), grown by 1e-6 of their size
  double lo_[3], hi_[3];         // the tissue's box
};

// Appends to sim.state.swept the triangles each scalpel's edge swept in the
// coming frame (sim.tools: before -> after), when the band meets the tissue.
// Returns how many were added.
int sweep_blades(Simulation& sim);

// Edge segments sampled per frame: the band is (kSweepSegments) quads.
inline constexpr int kSweepSegments = 2;
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
