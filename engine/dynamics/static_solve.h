#pragma once
// Static equilibrium f_int(u) = f_ext by Newton iterations on the corotated
// tangent (book eq. 3.53 without inertia), prescribed displacements at their
// final values.
#include "engine/model/model.h"
#include "engine/dynamics/state.h"
#include "engine/solve/workspace.h"

namespace incise {

struct StaticResult {
  int iterations = 0;
  double residual = 0.0;  // ||r_free|| / reference (see below)
  bool converged = false;
};

// Solves into state.u (state and ws must be init_state'd). Converged when
// ||f_ext - f_int(u)|| on the free DOFs <= tolerance * max(||f_ext||, ||r_0||),
// r_0 the first residual (covers load-free, displacement-driven problems).
// A linear model converges in one solve.
StaticResult solve_static(const Model& model, State& state, Workspace& ws, double tolerance, int max_iterations);

}  // namespace incise
