#pragma once
// Static equilibrium f_int(u) = f_ext: Newton's method on the consistent
// corotated tangent (the frozen-rotation tangent R K0 R^T plus the rotation
// term dR/du of engine/fem/rotation_stiffness.h, whatever integrator.tangent
// says; [book] eq. (3.53) without inertia), with a backtracking line search
// on the residual norm, prescribed displacements at their final values (or
// at their values at `time` >= 0).
#include <string>
#include <vector>

#include "engine/model/model.h"
#include "engine/dynamics/state.h"
#include "engine/solve/workspace.h"

namespace incise {

struct StaticResult {
  int iterations = 0;
  double residual = 0.0;  // ||r_free|| / reference (see below)
  bool converged = false;
  std::vector<double> residuals;  // relative residual before each iteration (residuals[0]: at the start)
  int shortened = 0;      // iterations whose step the line search shortened
  double smallest_step = 1.0;  // shortest step length taken (1: every step was a full Newton step)
  int stalled = 0;        // iterations where no step length passed the line search (the shortest was taken)
  int projected = 0;      // iterations whose exact tangent was indefinite: the projected one was taken
  int shifted = 0;        // 1 once a tangent was singular with enrichment: enriched diagonals raised from then on
  int inverted_points = 0;  // cubature points inverted at the solution (SVD fallbacks of the last assembly)
};

// The line search (static_solve.cpp): alpha halves from 1 at most this many
// times.
inline constexpr int kStaticLineSearchHalvings = 10;
// Relative raise of the enriched DOFs' diagonals once Cholesky refuses a
// tangent with enrichment (solve_static: a sliver's near-null modes).
inline constexpr double kStaticEnrichedShift = 1e-10;

// Solves into state.u (state and ws must be init_state'd). Converged when
// ||f_ext - f_int(u)|| on the free DOFs <= tolerance * max(||f_ext||, ||r_0||),
// r_0 the first residual (covers load-free, displacement-driven problems).
// A linear model converges in one solve; a corotated one quadratically once
// near the solution: the tangent is the exact one (rotation_stiffness.h,
// `exact`: compressed rotation modes kept), and where that is indefinite
// (Cholesky fails) the iteration takes the projected one (counted).
StaticResult solve_static(const Model& model, State& state, Workspace& ws, double tolerance, int max_iterations,
                          double time = -1.0);

// One line on what the solve did: the residual per iteration, the line
// search's shortened steps and the shortest, projected tangents, inverted
// points at the end.
std::string static_report(const StaticResult& result);

// What to do about a solve that did not converge, from its residuals: while
// they still fall, more iterations ("raise static.max_iterations"); once they
// have stopped falling (the last half of the iterations lowered the best
// residual by less than 10x), more iterations do not help: stalled near
// double precision's floor (below 1e-5: a stiff or tiny body's internal
// forces cancel to roundoff there), a tolerance that loose; stalled higher,
// no equilibrium was found near the start (a load too large for the
// material).
std::string static_failure_advice(const StaticResult& result);

// The scene key `initial: "static"` (issue 20): the State at frame 0 becomes
// the static equilibrium under the loads and the prescribed values at t = 0,
// at rest (v = 0, a from the forces left, ~0), so a hanging organ starts
// hanging instead of falling from its unstressed shape. Throws naming the
// scene, the iterations and the residual when it does not converge.
void start_at_static_equilibrium(const Model& model, State& state, Workspace& ws, double tolerance, int max_iterations,
                                 const std::string& scene_path);

}  // namespace incise
