#pragma once
// A cut replaces the Model (a grown DOF set, a new pattern); the Workspace
// carries itself over to the next Model here, so cutting/ never touches the
// solver's internals.
#include <vector>

#include "engine/fem/assemble_parallel.h"
#include "engine/model/model.h"
#include "engine/solve/workspace.h"

namespace incise {

// From `from` to `to` (same mesh, more cuts; `dofnode_map`: for each DOF node
// of `to` the DOF node of `from` carrying the same field, -1 for a new one;
// `changed`: the elements of `to` whose pieces changed):
// - the lagged policy's factors stay and precondition through the map (no
//   analysis in the cut frame, engine/solve/linear_solve.h); every other
//   policy gets a fresh symbolic analysis;
// - the tangent cache (integrator.tangent_reuse) keeps the blocks of the
//   elements the cut left alone, and K their sum;
// - work arrays are sized for `to`, keeping their buffers.
// `plan`: make_assembly_plan(to, ...) made ahead (may be null). `frame`: the State's.
void carry_workspace_over_cut(const Model& from, const Model& to, const std::vector<int>& dofnode_map,
                              const std::vector<int>& changed, AssemblyPlan* plan, int frame, Workspace& ws);

// The frame's contact rows (collision ran before the cut) onto the new
// model's DOF nodes through dofnode_map (new -> old); called by the above.
void carry_contact_rows(const Model& from, const std::vector<int>& dofnode_map, ContactRows& rows);

}  // namespace incise
