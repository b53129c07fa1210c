#pragma once
// Display meshes built in code, shared by the engine/output and render tests
// (render_test_util.h) and the render benchmark (tools/bench/render_bench.cpp):
// an undeformed body, and a block cut by hand into two halves with a gap.
// No GoogleTest here.
#include <algorithm>
#include <array>
#include <map>
#include <utility>
#include <vector>

#include "engine/dynamics/state.h"
#include "engine/mesh/mesh.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/model/model.h"
#include "engine/output/display_mesh.h"

namespace incise::test {

// The DisplayMesh of an undeformed body (u = v = 0) built by the engine.
inline DisplayMesh display_of(const Mesh& mesh) {
  Scene s;
  s.path = "render-test";
  s.order = mesh.order;
  s.material.young = 1.0;
  s.material.poisson = 0.3;
  s.material.density = 1.0;
  s.gravity = {0, 0, 0};
  const Model m = build_model(mesh, s);
  State st;
  st.u.assign(m.ndof(), 0.0);
  st.v.assign(m.ndof(), 0.0);
  return display_mesh(m, st);
}

// A hand-made cut: cells whose centroid has x > cut_x move to their own
// copies of the points, displaced by +gap in x; faces between the two halves
// become kFaceCut on both sides. Stands in for an X-FEM complete cut through
// a plane that falls between element layers (see docs of tests/render).
inline DisplayMesh split_block(const DisplayMesh& in, double cut_x, double gap) {
  DisplayMesh d = in;
  const int npe = d.npe(), nc = d.ncell();
  std::vector<char> right(nc, 0);
  for (int c = 0; c < nc; ++c) {
    double cx = 0;
    for (int k = 0; k < 4; ++k) cx += 0.25 * d.X[3 * d.cells[npe * c + k]];
    right[c] = cx > cut_x;
  }
  // Faces by sorted corner ids -> (cell, local face).
  std::map<std::array<int, 3>, std::vector<std::pair<int, int>>> faces;
  for (int c = 0; c < nc; ++c)
    for (int k = 0; k < 4; ++k) {
      std::array<int, 3> key;
      for (int j = 0; j < 3; ++j) key[j] = d.cells[npe * c + kTetFace[k][j]];
      std::sort(key.begin(), key.end());
      faces[key].push_back({c, k});
    }
  for (const auto& [key, cf] : faces)
    if (cf.size() == 2 && right[cf[0].first] != right[cf[1].first])
      for (const auto& [c, k] : cf) d.face_flags[4 * c + k] |= kFaceCut;
  // Right cells get their own points.
  std::vector<int> copy(d.npoint(), -1);
  for (int c = 0; c < nc; ++c) {
    if (!right[c]) continue;
    for (int k = 0; k < npe; ++k) {
      int& p = d.cells[npe * c + k];
      if (copy[p] < 0) {
        copy[p] = d.npoint();
        for (int j = 0; j < 3; ++j) {
          d.X.push_back(d.X[3 * p + j]);
          d.u.push_back(d.u[3 * p + j] + (j == 0 ? gap : 0.0));
          d.v.push_back(d.v[3 * p + j]);
        }
      }
      p = copy[p];
    }
  }
  return d;
}

}  // namespace incise::test
