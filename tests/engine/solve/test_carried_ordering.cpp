// engine/solve/carried_ordering.h: the ordering of a cut model's DOFs carried over
// from an earlier factor's permutation.
#include <algorithm>
#include <numeric>

#include <gtest/gtest.h>

#include "engine/solve/carried_ordering.h"
#include "engine/util/error.h"

namespace incise {
namespace {

// Three mesh nodes (DOFs 0-8) the earlier factor knew, eliminated in the node
// order 2, 0, 1; one enriched DOF node (DOFs 9-11) on mesh node 0.
TEST(CarriedOrdering, KnownDofsKeepTheirRankAndNewOnesFollowTheirMeshNode) {
  const std::vector<int> old_perm = {6, 7, 8, 0, 1, 2, 3, 4, 5};
  std::vector<int> map(12, -1);
  std::iota(map.begin(), map.begin() + 9, 0);
  const std::vector<int> perm = carried_ordering(3, {0}, map, old_perm);
  const std::vector<int> expect = {6, 7, 8, 0, 9, 1, 10, 2, 11, 3, 4, 5};
  EXPECT_EQ(perm, expect);
}

// The earlier factor numbered its DOFs differently (the map is not the
// identity), and one current DOF node it does not know is a standard one.
TEST(CarriedOrdering, MappedNumberingAndUnknownDofsGiveAPermutation) {
  const std::vector<int> old_perm = {3, 4, 5, 0, 1, 2};  // earlier: 2 DOF nodes, node 1 first
  // current: mesh nodes 0, 1, 2 and an enriched node on mesh node 1; mesh node
  // 0 is the earlier node 1, mesh node 1 the earlier node 0, mesh node 2 is new.
  const std::vector<int> map = {3, 4, 5, 0, 1, 2, -1, -1, -1, -1, -1, -1};
  const std::vector<int> perm = carried_ordering(3, {1}, map, old_perm);
  std::vector<int> sorted = perm;
  std::sort(sorted.begin(), sorted.end());
  std::vector<int> all(12);
  std::iota(all.begin(), all.end(), 0);
  EXPECT_EQ(sorted, all) << "a permutation of the current DOFs";
  const std::vector<int> head = {0, 1, 2, 3, 9, 4, 10, 5, 11};
  EXPECT_EQ(std::vector<int>(perm.begin(), perm.begin() + 9), head);
  EXPECT_EQ(std::vector<int>(perm.begin() + 9, perm.end()), (std::vector<int>{6, 7, 8})) << "no rank: last";
}

TEST(CarriedOrdering, ASizeMismatchIsAnError) {
  try {
    carried_ordering(3, {0, 1}, std::vector<int>(12, -1), {});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("12 DOFs for 3 + 2 DOF nodes"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace incise
