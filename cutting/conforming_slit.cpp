#include "cutting/conforming_slit.h"

#include <cmath>
#include <map>

namespace incise {

Mesh duplicate_nodes_along_slit(const Mesh& mesh, double xc, double z_tip) {
  const int npe = mesh.npe(), nt = mesh.ntet();
  double size = 0;
  for (double v : mesh.X) size = std::max(size, std::abs(v));
  const double eps = 1e-9 * size;
  auto at = [&](int i, int d) { return mesh.X[3 * i + d]; };
  // Nodes of faces lying on the slit (and not on its front line).
  std::vector<char> on_slit(mesh.nnode(), 0);
  for (int e = 0; e < nt; ++e)
    for (int k = 0; k < 4; ++k) {
      bool in = true;
      double zc = 0;
      for (int j = 0; j < 3; ++j) {
        const int i = mesh.tet[static_cast<size_t>(e) * npe + kTetFace[k][j]];
        in = in && std::abs(at(i, 0) - xc) <= eps && at(i, 2) >= z_tip - eps;
        zc += at(i, 2) / 3;
      }
      if (!in || zc <= z_tip + eps) continue;
      for (int j = 0; j < 3; ++j) on_slit[mesh.tet[static_cast<size_t>(e) * npe + kTetFace[k][j]]] = 1;
      if (npe == 10)
        for (int j = 0; j < 3; ++j) on_slit[mesh.tet[static_cast<size_t>(e) * npe + kTet10FaceMid[k][j]]] = 1;
    }
  Mesh out = mesh;
  std::map<int, int> dup;
  for (int i = 0; i < mesh.nnode(); ++i)
    if (on_slit[i] && at(i, 2) > z_tip + eps) {
      dup[i] = out.nnode();
      for (int d = 0; d < 3; ++d) out.X.push_back(at(i, d));
    }
  for (int e = 0; e < nt; ++e) {
    double xcen = 0;
    for (int a = 0; a < 4; ++a) xcen += at(mesh.tet[static_cast<size_t>(e) * npe + a], 0) / 4;
    if (xcen <= xc) continue;
    for (int a = 0; a < npe; ++a) {
      int& id = out.tet[static_cast<size_t>(e) * npe + a];
      if (auto it = dup.find(id); it != dup.end()) id = it->second;
    }
  }
  return out;
}

}  // namespace incise
