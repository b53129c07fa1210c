#include "engine/result_grid.h"

#include "engine/assemble.h"

namespace incise {

VtuGrid result_grid(const Model& m, const State& s) {
  VtuGrid g;
  const int nn = m.nnode, npe = m.mesh.npe();
  // Points are written deformed (x = X + u) so the motion shows without a
  // Warp filter; the displacement field is there for colouring and probing.
  g.points.resize(3 * static_cast<size_t>(nn));
  for (int i = 0; i < 3 * nn; ++i) g.points[i] = m.X[i] + s.u[i];
  g.connectivity = m.mesh.tet;
  g.offsets.resize(m.mesh.ntet());
  g.types.assign(m.mesh.ntet(), npe == 10 ? 24 : 10);
  for (int e = 0; e < m.mesh.ntet(); ++e) g.offsets[e] = (e + 1) * npe;
  g.point_data.push_back({"displacement", 3, std::vector<double>(s.u.begin(), s.u.begin() + 3 * nn)});
  g.point_data.push_back({"velocity", 3, std::vector<double>(s.v.begin(), s.v.begin() + 3 * nn)});
  VtuField vm{"von_mises", 1, std::vector<double>(m.nelem)};
  element_von_mises(m, s.u.data(), s.R.data(), vm.values.data());
  g.cell_data.push_back(std::move(vm));
  return g;
}

}  // namespace incise
