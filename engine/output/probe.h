#pragma once
// Point location in the reference configuration and interpolation of the
// displacement with the element shape functions.
#include <array>
#include <vector>

#include "engine/model/model.h"

namespace incise {

struct ProbeHit {
  int elem = -1;          // -1: outside the mesh
  double rst[3] = {0, 0, 0};  // local coordinates in elem
  int piece = -1;         // piece of elem holding the point (cut models), -1 = whole element
};

// The piece of element e whose sub-tetrahedra contain local point rst (the one
// it is deepest in); -1 for a model without cuts.
int piece_containing(const Model& model, int e, const double rst[3]);

// The element containing reference point x (inclusive of faces, with a 1e-9
// tolerance in local coordinates; curved tet10 inverted by Newton).
ProbeHit locate_point(const Model& model, const double x[3]);

// u(x) = sum_a N_a(rst) (u_a + u_enr(piece, a)) over the element's nodes: in a
// cut element, the displacement of the side the point lies on.
std::array<double, 3> interpolate_displacement(const Model& model, const double* u, const ProbeHit& hit);

}  // namespace incise
