#pragma once
// What a numerical failure (engine/util/error.h NumericalError: a
// non-finite residual, a pivot that is not positive) says to the user: the
// node behind the failing DOF, where it is, and the scene values that most
// likely caused it, the extreme ones first, e.g.
//   frame 0: CHOLMOD: the system matrix is not positive definite at DOF 37
//   (...); at node 12 component y (x = 0.5, 0, 1); check material.young =
//   1e+30 (extreme: ...), material.poisson = 0.3, material.density = 1,
//   integrator.dt = 0.0333
#include <string>

#include "engine/model/model.h"
#include "engine/util/error.h"

namespace incise {

// "node 12 component y (x = 0.5, 0, 1)"; an enriched DOF names the mesh node
// whose cut piece it moves: "enriched DOF node 530 (a cut piece at mesh node 12) component y (x = ...)".
std::string describe_dof(const Model& m, long dof);

// "material.young = 1e+30 (extreme: ...), material.poisson = 0.3, ...": the
// scene values behind the system matrix and the residual, those outside a
// plausible range first.
std::string likely_inputs(const Model& m);

// e's message with the DOF's node and the inputs to check appended.
std::string with_failure_context(const NumericalError& e, const Model& m);

}  // namespace incise
