#pragma once
// The slit studies of incise-study-slit (docs/cutting.md, "Accuracy against a
// conforming mesh"): a slit x = 2, z >= 0.5 through a beam [0,4]x[0,1]x[0,1]
// clamped at x = 0, solved statically by the X-FEM on meshes that do not
// conform to it and on conforming meshes (nodes duplicated along the slit).
#include <array>
#include <vector>

#include "engine/mesh/mesh.h"
#include "engine/scene/scene.h"

namespace incise {

struct SlitCase {
  const char* name;
  MaterialModel model;
  bool gravity;  // else a prescribed end displacement
};

Scene slit_scene(const SlitCase& c, int order);

// Solves the scene on `mesh` (the slit cut by the X-FEM when xfem, else the
// mesh is taken as it is) and returns the displacement at each probe, (n, 3).
std::vector<double> slit_solve(const Mesh& mesh, Scene s, bool xfem, const std::vector<std::array<double, 3>>& probes,
                               int* dof);

// The probes away from the slit (|x - 2| > 0.3): 104 points.
std::vector<std::array<double, 3>> slit_far_probes();

// Relative L2 difference of u against ref, over the probes.
double relative_l2(const std::vector<double>& u, const std::vector<double>& ref);

// The extended study (issue 21): the slit's front on element faces and inside
// elements at 0.1, 0.5 and 0.9 of h, X-FEM against conforming meshes of the
// same slit, both against a fine conforming reference, without and with the
// front enrichment (CutLayout::node_branch). Prints a markdown table.
// only_enriched: skip the X-FEM runs without front enrichment.
int run_front_study(bool quick, bool only_enriched);

}  // namespace incise
