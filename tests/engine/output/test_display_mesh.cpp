// DisplayMesh cells know where they sit in their element: cell_rst mapped by
// the element's shape functions gives the cell's reference points, and
// cell_piece names the piece (X-FEM) they show.
#include "engine/output/display_mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "cutting/cut_surface.h"
#include "cutting/xfem_layout.h"
#include "engine/dynamics/step.h"  // init_state, which tests/cutting/test_util.h uses
#include "engine/fem/element.h"
#include "engine/mesh/mesh_io.h"
#include "tests/cutting/test_util.h"

namespace incise::test {
namespace {

State rest_state(const Model& m) {
  State st;
  st.u.assign(m.ndof(), 0.0);
  st.v.assign(m.ndof(), 0.0);
  return st;
}

// max over cells and nodes of |X(cell_rst) - X(point)|.
double rst_mismatch(const Model& m, const DisplayMesh& d) {
  const int npe = d.npe();
  EXPECT_EQ(d.cell_rst.size(), static_cast<size_t>(d.ncell()) * npe * 3);
  double worst = 0, N[10];
  for (int c = 0; c < d.ncell(); ++c) {
    const int* nodes = &m.mesh.tet[static_cast<size_t>(d.cell_elem[c]) * npe];
    for (int a = 0; a < npe; ++a) {
      shape_values(npe, &d.cell_rst[(static_cast<size_t>(c) * npe + a) * 3], N);
      for (int k = 0; k < 3; ++k) {
        double X = 0;
        for (int b = 0; b < npe; ++b) X += N[b] * m.X[3 * nodes[b] + k];
        worst = std::max(worst, std::abs(X - d.X[3 * d.cells[static_cast<size_t>(c) * npe + a] + k]));
      }
    }
  }
  return worst;
}

TEST(DisplayMesh, CellRstMapsToTheCellPointsOfACurvedMesh) {
  const Mesh mesh = read_mesh(std::string(INCISE_SOURCE_DIR) + "/assets/meshes/sphere_tet10.msh");
  const Model m = build_model(mesh, block_scene(2));
  const DisplayMesh d = display_mesh(m, rest_state(m));
  EXPECT_LT(rst_mismatch(m, d), 1e-15);
  for (int p : d.cell_piece) EXPECT_EQ(p, -1);
  // The reference nodes: corner 2 at (0, 1, 0), mid-edge 9 (corners 2-3) at (0, 1/2, 1/2).
  EXPECT_EQ(d.cell_rst[3 * 2 + 1], 1.0);
  EXPECT_EQ(d.cell_rst[3 * 9 + 1], 0.5);
  EXPECT_EQ(d.cell_rst[3 * 9 + 2], 0.5);
}

TEST(DisplayMesh, CellRstAndPiecesOfACutModel) {
  for (int order : {1, 2}) {
    const Scene s = block_scene(order);
    const Mesh mesh = make_beam(2, 1, 1, 4, 2, 2, 1);
    const Model uncut = build_model(mesh, s);
    const auto plane = make_cut_surface(plane_cut({1.05, 0, 0}, {1, 0.1, 0.05}), 0.0);
    const CutLayout layout = compute_cut_layout(uncut, {plane.get()}, nullptr);
    const Model m = build_model(mesh, s, &layout);
    const DisplayMesh d = display_mesh(m, rest_state(m));
    EXPECT_LT(rst_mismatch(m, d), 1e-14) << "order " << order;
    ASSERT_EQ(d.cell_piece.size(), static_cast<size_t>(d.ncell()));
    int split_cells = 0;
    for (int c = 0; c < d.ncell(); ++c) {
      const int e = d.cell_elem[c], P = d.cell_piece[c];
      EXPECT_GE(P, m.cuts.elem_piece_ptr[e]) << "cell " << c;
      EXPECT_LT(P, m.cuts.elem_piece_ptr[e + 1]) << "cell " << c;
      split_cells += m.cuts.elem_split[e];
    }
    EXPECT_GT(split_cells, 0);
  }
}

}  // namespace
}  // namespace incise::test
