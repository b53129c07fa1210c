#pragma once
// Where a world point lies in the deformed tissue: the element whose
// deformed corner tetrahedron holds it. The scalpel maps the bands its edge
// sweeps to reference coordinates with it (cutting/blade_sweep.h); the
// collision stage asks whether a probe that lost its contact sits inside
// the tissue (collision/collision_stage.cpp).
#include <array>
#include <vector>

#include <Eigen/Core>

#include "engine/dynamics/state.h"
#include "engine/model/model.h"

namespace incise {

// Reference position of the material point at world position x in the
// current configuration: the element whose deformed corner tetrahedron
// contains x (barycentric coordinates of the corners, the largest smallest
// one), mapped by the same coordinates to the reference corners; outside the
// tissue the nearest such element's map, extrapolated. *inside tells which.
std::array<double, 3> reference_point(const Model& model, const State& state, const double x[3], bool* inside);

// The same for many points of one configuration: the deformed corner
// tetrahedra, their bounding boxes and a uniform grid of those boxes made
// once (O(elements)); a point then tests only the elements whose box
// holds it (of its grid cell's), a point outside the tissue all of them
// for its extrapolation (reference), or none with an element given
// (reference_by).
class TissueLocator {
 public:
  TissueLocator(const Model& model, const State& state) : TissueLocator(model, state.u.data()) {}
  // u: the displacement (ndof); null: the reference configuration.
  TissueLocator(const Model& model, const double* u);
  std::array<double, 3> reference(const double x[3], bool* inside) const;  // as reference_point
  bool inside(const double x[3]) const;  // whether x lies in the tissue (no mapping; cheap)
  // The element whose deformed corner tetrahedron holds x (as reference
  // picks it), or -1 outside the tissue.
  int locate(const double x[3]) const;
  // x mapped by element e's corner map (extrapolated when x is outside it).
  std::array<double, 3> reference_by(int e, const double x[3]) const;

 private:
  Eigen::Vector4d barycentric(int e, const double x[3]) const;
  int best_element(const double x[3], bool all, double& best_min, Eigen::Vector4d& best_L) const;
  const Model* model_;
  std::vector<double> corners_;  // (ntet, 4, 3) deformed corner positions
  std::vector<double> box_;      // (ntet, 6) their bounding boxes (lo, hi), grown by 1e-6 of their size
  double lo_[3], hi_[3];         // the tissue's box
  // Uniform grid over the tissue's box, about one cell per element: the
  // elements whose box meets each cell, in element order (CSR).
  int dim_[3] = {1, 1, 1};
  double cell_[3] = {1, 1, 1};
  std::vector<int> cell_ptr_, cell_elem_;
  int cell_of(const double x[3]) const;
};

}  // namespace incise
