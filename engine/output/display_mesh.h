#pragma once
// What a viewer shows: the deformed body as cells with their own points. An
// uncut element is one cell on the mesh's shared points; an X-FEM element is
// written as its sub-elements, each on points of its own side moved with that
// side's displacement field, so a cut opens as a gap. Faces lying on a cut
// surface are flagged so renderers colour them as tissue interior. Used by the
// .vtu output (engine/result_grid) and the renderer (render/).
#include <vector>

#include "engine/model/model.h"
#include "engine/dynamics/state.h"

namespace incise {

struct DisplayMesh {
  int order = 1;                   // cells are tet4 (1) or tet10 (2), ordering of engine/mesh/mesh.h
  std::vector<double> X;           // (npoint, 3) reference positions
  std::vector<double> u;           // (npoint, 3) displacement
  std::vector<double> v;           // (npoint, 3) velocity
  std::vector<int> cells;          // (ncell, npe) point ids
  std::vector<int> cell_elem;      // (ncell) model element the cell belongs to
  std::vector<int> cell_piece;     // (ncell) model piece (CutLayout) of the cell; -1 when the model has no cuts
  // (ncell, npe, 3) local coordinates (r, s, t) of each cell node in its
  // element: the reference tet4/tet10 nodes for a whole element, the
  // sub-tetrahedron's corners and their edge midpoints for a piece's cell.
  // Mapped through the element's shape functions they give the cell's X.
  std::vector<double> cell_rst;
  // (ncell, 4) flags of face k (the face opposite corner k): kFaceBoundary =
  // on the body's outer surface, kFaceCut = on a cut surface. Faces with no
  // flag are inside the body; a renderer draws the flagged ones only.
  std::vector<unsigned char> face_flags;

  int npe() const { return order == 2 ? 10 : 4; }
  int npoint() const { return static_cast<int>(X.size() / 3); }
  int ncell() const { return static_cast<int>(cell_elem.size()); }
  double x(int p, int d) const { return X[3 * p + d] + u[3 * p + d]; }  // current position
};

inline constexpr unsigned char kFaceBoundary = 1, kFaceCut = 2;

// Which cells display_mesh writes: all, or (Surface) only those with a
// flagged face, which is all that the flagged faces need: the instruments'
// collision surface (collision/tissue_surface.h) is rebuilt after every cut
// from them, and most cells of an organ are inside it.
enum class DisplayCells { All, Surface };

DisplayMesh display_mesh(const Model& model, const State& state, DisplayCells cells = DisplayCells::All);


}  // namespace incise
