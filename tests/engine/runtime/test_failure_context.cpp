// engine/runtime/failure_context.cpp: a failing DOF named as its node (an
// enriched one as the mesh node whose cut piece it moves) and the scene
// values to check, the extreme ones first.
#include "engine/runtime/failure_context.h"

#include <gtest/gtest.h>

namespace incise {
namespace {

Model two_nodes_and_a_piece() {
  Model m;
  m.nnode = 2;
  m.ndofnode = 3;  // mesh nodes 0, 1; enriched DOF node 2 on mesh node 1
  m.X = {0, 0, 0, 1, 2, 3, 0, 0, 0};
  m.cuts.n_enriched = 1;
  m.cuts.enr_node = {1};
  m.material.young = 3000;
  m.material.poisson = 0.4995;
  m.material.density = 1000;
  m.dt = 0.01;
  return m;
}

TEST(FailureContext, DofNamedAsItsNodeEnrichedAsItsMeshNode) {
  const Model m = two_nodes_and_a_piece();
  EXPECT_EQ(describe_dof(m, 4), "node 1 component y (x = 1, 2, 3)");
  EXPECT_EQ(describe_dof(m, 8), "enriched DOF node 2 (a cut piece at mesh node 1) component z (x = 1, 2, 3)");
  EXPECT_EQ(describe_dof(m, 9), "");  // out of range: not named
  EXPECT_EQ(describe_dof(m, -1), "");
}

TEST(FailureContext, ExtremeValuesComeFirst) {
  Model m = two_nodes_and_a_piece();
  const NumericalError e("CHOLMOD: the system matrix is not positive definite at DOF 4", 4);
  EXPECT_EQ(with_failure_context(e, m),
            "CHOLMOD: the system matrix is not positive definite at DOF 4; at node 1 component y (x = 1, 2, 3); check "
            "material.poisson = 0.4995 (extreme: nearly incompressible, the volumetric stiffness dwarfs the rest), "
            "material.young = 3000, material.density = 1000, integrator.dt = 0.01, gravity = [0, 0, 0]");
  m.material.poisson = 0.3;
  EXPECT_EQ(likely_inputs(m), "material.young = 3000, material.poisson = 0.3, material.density = 1000, integrator.dt = "
                              "0.01, gravity = [0, 0, 0]");
  // Gravity is listed too, first when extreme (a run with g = 1e8 diverged
  // and the message named everything but it).
  m.gravity[2] = -1e8;
  EXPECT_EQ(likely_inputs(m), "gravity = [0, 0, -1e+08] (extreme: Earth's is 9.81 m/s^2, 9810 mm/s^2), material.young = "
                              "3000, material.poisson = 0.3, material.density = 1000, integrator.dt = 0.01");
}

}  // namespace
}  // namespace incise
