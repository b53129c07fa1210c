#include "engine/output/result_grid.h"

#include "engine/fem/assemble.h"
#include "engine/output/display_mesh.h"

namespace incise {

VtuGrid result_grid(const Model& m, const State& s) {
  const DisplayMesh d = display_mesh(m, s);
  VtuGrid g;
  const int np = d.npoint(), npe = d.npe(), nc = d.ncell();
  // Points are written deformed (x = X + u) so the motion shows without a
  // Warp filter; the displacement field is there for colouring and probing.
  g.points.resize(3 * static_cast<size_t>(np));
  for (int i = 0; i < 3 * np; ++i) g.points[i] = d.X[i] + d.u[i];
  g.connectivity = d.cells;
  g.offsets.resize(nc);
  g.types.assign(nc, npe == 10 ? 24 : 10);
  for (int c = 0; c < nc; ++c) g.offsets[c] = (c + 1) * npe;
  g.point_data.push_back({"displacement", 3, d.u});
  g.point_data.push_back({"velocity", 3, d.v});
  std::vector<double> vm_elem(m.nelem);
  element_von_mises(m, s.u.data(), s.R.data(), vm_elem.data());
  VtuField vm{"von_mises", 1, std::vector<double>(nc)};
  VtuField elem{"element", 1, std::vector<double>(nc)};
  for (int c = 0; c < nc; ++c) {
    vm.values[c] = vm_elem[d.cell_elem[c]];
    elem.values[c] = d.cell_elem[c];
  }
  g.cell_data.push_back(std::move(vm));
  g.cell_data.push_back(std::move(elem));
  return g;
}

}  // namespace incise
