// The CHOLMOD block recycler (engine/solve/block_recycler.h): large blocks come
// back to the next request they fit, grown blocks keep their contents,
// calloc-style requests are zero even on a reused block, and a factorization
// through the installed hooks still solves.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "engine/solve/block_recycler.h"
#include "engine/fem/assemble.h"
#include "engine/solve/cholmod_solver.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

constexpr size_t kMiB = size_t{1} << 20;

TEST(BlockRecycler, FreedLargeBlockServesTheNextRequestItFits) {
  const size_t size = 41 * kMiB + 12345;  // larger than any other block of the process
  void* a = recycler::allocate(size);
  ASSERT_NE(a, nullptr);
  std::memset(a, 0x5a, size);
  recycler::release(a);
  const RecyclerStats before = cholmod_block_recycler_stats();
  void* b = recycler::allocate(size - 1000);  // a little smaller: the same block
  EXPECT_EQ(b, a);
  EXPECT_EQ(cholmod_block_recycler_stats().reused, before.reused + 1);
  recycler::release(b);
  // Less than half of the kept block's capacity: a new block, the kept one stays.
  void* c = recycler::allocate(size / 3);
  EXPECT_NE(c, a);
  recycler::release(c);
}

TEST(BlockRecycler, GrowsAKeptBlockForALargerRequestKeepingNothingStale) {
  const size_t size = 43 * kMiB + 777;
  void* a = recycler::allocate(size);
  ASSERT_NE(a, nullptr);
  recycler::release(a);
  const RecyclerStats before = cholmod_block_recycler_stats();
  // 1.5x: beyond the 1/8 headroom, within twice the kept block: grown, not fresh.
  void* b = recycler::allocate(size + size / 2);
  ASSERT_NE(b, nullptr);
  const RecyclerStats after = cholmod_block_recycler_stats();
  EXPECT_EQ(after.grown, before.grown + 1);
  EXPECT_EQ(after.fresh, before.fresh);
  recycler::release(b);
}

TEST(BlockRecycler, ZeroedRequestOnADirtyReusedBlockIsZero) {
  const size_t n = (45 * kMiB) / sizeof(double);
  auto* a = static_cast<double*>(recycler::allocate(n * sizeof(double)));
  ASSERT_NE(a, nullptr);
  for (size_t k = 0; k < n; ++k) a[k] = 1.0 + static_cast<double>(k);
  recycler::release(a);
  auto* b = static_cast<double*>(recycler::allocate_zeroed(n, sizeof(double)));
  ASSERT_EQ(b, a);  // the dirty block came back
  size_t nonzero = 0;
  for (size_t k = 0; k < n; ++k) nonzero += b[k] != 0.0;
  EXPECT_EQ(nonzero, 0u);
  recycler::release(b);
  EXPECT_EQ(recycler::allocate_zeroed(SIZE_MAX / 2, 4), nullptr);  // count * size overflows
}

TEST(BlockRecycler, ReallocateKeepsContentsSmallAndLarge) {
  for (const size_t size : {size_t{100}, 3 * kMiB}) {
    auto* a = static_cast<unsigned char*>(recycler::allocate(size));
    ASSERT_NE(a, nullptr);
    for (size_t k = 0; k < size; ++k) a[k] = static_cast<unsigned char>(k * 7 + 1);
    auto* b = static_cast<unsigned char*>(recycler::reallocate(a, 4 * size));
    ASSERT_NE(b, nullptr);
    size_t wrong = 0;
    for (size_t k = 0; k < size; ++k) wrong += b[k] != static_cast<unsigned char>(k * 7 + 1);
    EXPECT_EQ(wrong, 0u) << size;
    // Shrinking keeps the block.
    EXPECT_EQ(recycler::reallocate(b, size / 2), b);
    recycler::release(b);
  }
  // A null block reallocates as a new one.
  void* c = recycler::reallocate(nullptr, 64);
  ASSERT_NE(c, nullptr);
  recycler::release(c);
}

TEST(BlockRecycler, FactorizationsThroughTheHooksSolve) {
  // The same beam system factorized by two solvers in turn, the second on the
  // first one's blocks where the recycler is installed (not under ASan): the
  // same accuracy, and the large blocks were reused.
  const Model m = test::tissue_beam(12, 3);
  const std::vector<double> A = test::system_matrix(m, 3600.0);
  const int n = m.ndof();
  const std::vector<double> b = test::random_vector(n, 7);
  const RecyclerStats before = cholmod_block_recycler_stats();
  for (int round = 0; round < 2; ++round) {
    CholmodSolver s;
    s.analyze(n, m.Ap, m.Ai);
    s.factorize(A.data());
    std::vector<double> x(n), r(n);
    s.solve(b.data(), x.data());
    sym_matvec(m, A.data(), x.data(), r.data());
    double rn = 0, bn = 0;
    for (int d = 0; d < n; ++d) rn += (r[d] - b[d]) * (r[d] - b[d]), bn += b[d] * b[d];
    EXPECT_LT(std::sqrt(rn / bn), 1e-10) << "round " << round;
  }
  const RecyclerStats after = cholmod_block_recycler_stats();
  if (install_cholmod_block_recycler()) EXPECT_GT(after.reused + after.grown, before.reused + before.grown);
  else EXPECT_EQ(after.fresh, before.fresh);  // off: nothing goes through it
}

}  // namespace
}  // namespace incise
