#include "engine/runtime/failure_context.h"
#include "engine/util/number_text.h"

#include <cmath>
#include <cstdio>
#include <vector>

namespace incise {

std::string describe_dof(const Model& m, long dof) {
  if (dof < 0 || dof >= static_cast<long>(m.ndof())) return "";
  const long node = dof / 3;
  const char comp = "xyz"[dof % 3];
  long mesh_node = node;
  std::string who = "node " + std::to_string(node);
  if (node >= m.nnode) {  // enriched DOF nodes follow the mesh nodes (engine/model/model.h)
    const long k = node - m.nnode;
    mesh_node = k < static_cast<long>(m.cuts.enr_node.size()) ? m.cuts.enr_node[static_cast<size_t>(k)] : -1;
    who = "enriched DOF node " + std::to_string(node) +
          (mesh_node >= 0 ? " (a cut piece at mesh node " + std::to_string(mesh_node) + ")" : "");
  }
  std::string at;
  if (mesh_node >= 0 && 3 * mesh_node + 2 < static_cast<long>(m.X.size()))
    at = " (x = " + number_text(m.X[3 * mesh_node]) + ", " + number_text(m.X[3 * mesh_node + 1]) + ", " + number_text(m.X[3 * mesh_node + 2]) + ")";
  return who + " component " + comp + at;
}

std::string likely_inputs(const Model& m) {
  // Broad bands, in SI units, of what a simulated body has: outside them a
  // value is the likely cause (a product that overflows, a term lost in
  // roundoff). Inside them the others are listed for reference.
  struct Value {
    std::string text;
    bool extreme;
  };
  const Material& mat = m.material;
  const auto band = [](double x, double lo, double hi) { return !(x >= lo && x <= hi); };
  const double g = std::sqrt(m.gravity[0] * m.gravity[0] + m.gravity[1] * m.gravity[1] + m.gravity[2] * m.gravity[2]);
  std::vector<Value> v = {
      {"material.young = " + number_text(mat.young) +
           (band(mat.young, 1.0, 1e12) ? " (extreme: tissues to steel are 1e2 to 2e11 Pa)" : ""),
       band(mat.young, 1.0, 1e12)},
      {"material.poisson = " + number_text(mat.poisson) +
           (mat.poisson > 0.499 ? " (extreme: nearly incompressible, the volumetric stiffness dwarfs the rest)"
                                : mat.poisson < -0.99 ? " (extreme: nearly -1, no shear stiffness left)" : ""),
       mat.poisson > 0.499 || mat.poisson < -0.99},
      {"material.density = " + number_text(mat.density) +
           (band(mat.density, 1e-3, 1e5) ? " (extreme: materials are 1 to 2e4 kg/m^3)" : ""),
       band(mat.density, 1e-3, 1e5)},
      {"integrator.dt = " + number_text(m.dt) + (band(m.dt, 1e-7, 1.0) ? " (extreme: frames are 1e-4 to 0.1 s)" : ""),
       band(m.dt, 1e-7, 1.0)},
      {"gravity = [" + number_text(m.gravity[0]) + ", " + number_text(m.gravity[1]) + ", " + number_text(m.gravity[2]) +
           "]" + (g > 1e5 ? " (extreme: Earth's is 9.81 m/s^2, 9810 mm/s^2)" : ""),
       g > 1e5},
  };
  std::string out;
  for (bool extreme : {true, false})
    for (const Value& x : v)
      if (x.extreme == extreme) out += (out.empty() ? "" : ", ") + x.text;
  return out;
}

std::string with_failure_context(const NumericalError& e, const Model& m) {
  std::string s = e.what();
  const std::string where = describe_dof(m, e.dof);
  if (!where.empty()) s += "; at " + where;
  return s + "; check " + likely_inputs(m);
}

}  // namespace incise
