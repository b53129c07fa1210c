#pragma once
// Static equilibrium f_int(u) = f_ext by Newton iterations on the corotated
// tangent (book eq. 3.53 without inertia), prescribed displacements at their
// final values (or at their values at `time` >= 0).
#include <string>

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
StaticResult solve_static(const Model& model, State& state, Workspace& ws, double tolerance, int max_iterations,
                          double time = -1.0);

// The scene key `initial: "static"` (issue 20): the State at frame 0 becomes
// the static equilibrium under the loads and the prescribed values at t = 0,
// at rest (v = 0, a from the forces left, ~0), so a hanging organ starts
// hanging instead of falling from its unstressed shape. Throws naming the
// scene, the iterations and the residual when it does not converge.
void start_at_static_equilibrium(const Model& model, State& state, Workspace& ws, double tolerance, int max_iterations,
                                 const std::string& scene_path);

}  // namespace incise
