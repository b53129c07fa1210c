#pragma once
// A fill-reducing ordering for the DOFs of a model after a cut, carried over
// from the analysis of an earlier pattern instead of searched again: METIS
// takes 39-44 ms at 10k DOF against 53 ms for the numeric factorization, and
// during a progressive incision every background job meets a new pattern.
#include <vector>

namespace incise {

// perm[k] = the DOF eliminated k-th. Every DOF the earlier factor knows keeps
// its rank; a DOF it does not know (an enriched DOF node, or a second one
// mapped to the same earlier DOF) goes right after the same component of its
// mesh node, so its fill is that node's.
//   nnode:    standard DOF nodes (= mesh nodes; DOF node n < nnode is mesh node n)
//   enr_node: (ndofnode - nnode) mesh node of each enriched DOF node
//   map:      (ndof) the earlier factor's DOF of each current DOF, -1 none
//   old_perm: (earlier ndof) the earlier factor's permutation
std::vector<int> carried_ordering(int nnode, const std::vector<int>& enr_node, const std::vector<int>& map,
                                  const std::vector<int>& old_perm);

}  // namespace incise
