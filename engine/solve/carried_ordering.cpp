#include "engine/solve/carried_ordering.h"

#include <algorithm>
#include <climits>
#include <tuple>

#include "engine/util/error.h"

namespace incise {

std::vector<int> carried_ordering(int nnode, const std::vector<int>& enr_node, const std::vector<int>& map,
                                  const std::vector<int>& old_perm) {
  const int ndof = static_cast<int>(map.size());
  if (ndof % 3 != 0 || 3 * (nnode + static_cast<int>(enr_node.size())) != ndof)
    throw Error("carried_ordering: " + std::to_string(ndof) + " DOFs for " + std::to_string(nnode) + " + " +
                std::to_string(enr_node.size()) + " DOF nodes");
  std::vector<int> rank(old_perm.size(), INT_MAX);
  for (size_t k = 0; k < old_perm.size(); ++k) rank[old_perm[k]] = static_cast<int>(k);
  const auto known = [&](int d) { return map[d] >= 0 && map[d] < static_cast<int>(rank.size()) ? rank[map[d]] : INT_MAX; };
  // (rank of the DOF or of its mesh node's same component, 0 known / 1 new, DOF)
  std::vector<std::tuple<int, int, int>> key(ndof);
  for (int d = 0; d < ndof; ++d) {
    const int r = known(d);
    if (r != INT_MAX) {
      key[d] = {r, 0, d};
      continue;
    }
    const int node = d / 3;
    const int mesh_node = node < nnode ? node : enr_node[node - nnode];
    key[d] = {known(3 * mesh_node + d % 3), 1, d};
  }
  std::sort(key.begin(), key.end());
  std::vector<int> perm(ndof);
  for (int k = 0; k < ndof; ++k) perm[k] = std::get<2>(key[k]);
  return perm;
}

}  // namespace incise
