// carry_contact_rows (engine/solve/workspace_carry.cpp): the frame's contact
// rows, found on the model before a cut, move onto the new DOF numbering.
#include <gtest/gtest.h>

#include "engine/model/model.h"
#include "engine/solve/workspace_carry.h"

namespace incise {
namespace {

TEST(WorkspaceCarry, ContactRowsFollowTheirDofNodesOverACut) {
  Model from;
  from.nnode = 4;
  from.ndofnode = 6;  // 4 mesh nodes, enriched DOF nodes 4 and 5
  // The new model: mesh nodes keep their ids, new node 5 carries old 4, old 5
  // is gone (its piece was the node's home after the cut), 4 and 6 are new.
  const std::vector<int> map = {0, 1, 2, 3, -1, 4, -1};
  ContactRows rows;
  const double p[3] = {0, 0, 0}, d[3] = {0, 0, 1};
  rows.begin_row(RowKind::Contact, 1e-3, 0, p, d);
  rows.add(3 * 1 + 2, 0.5);   // mesh node 1, z
  rows.add(3 * 4 + 0, 0.25);  // old enriched node 4, x
  rows.add(3 * 5 + 1, 0.125); // old enriched node 5: dropped
  rows.begin_row(RowKind::Grasp, -2e-3, 1, p, d);
  rows.add(3 * 3 + 1, 1.0);
  carry_contact_rows(from, map, rows);
  ASSERT_EQ(rows.nrow(), 2);
  EXPECT_EQ(rows.ptr, (std::vector<int>{0, 2, 3}));
  EXPECT_EQ(rows.dof, (std::vector<int>{3 * 1 + 2, 3 * 5 + 0, 3 * 3 + 1}));
  EXPECT_EQ(rows.coef, (std::vector<double>{0.5, 0.25, 1.0}));
  EXPECT_EQ(rows.target, (std::vector<double>{1e-3, -2e-3}));
  EXPECT_EQ(rows.tool, (std::vector<int>{0, 1}));
}

}  // namespace
}  // namespace incise
