// engine/util/headroom.h: a growing work array reallocates now and then, not on
// every small growth (each new buffer's pages fault in on first touch).
#include <gtest/gtest.h>

#include <vector>

#include "engine/util/headroom.h"

namespace incise {
namespace {

TEST(Headroom, GrowingByLittleStepsReallocatesRarelyAndKeepsTheValues) {
  std::vector<double> v;
  resize_with_headroom(v, 1000);
  for (int i = 0; i < 1000; ++i) v[i] = i;
  EXPECT_GE(v.capacity(), 1250u);
  int reallocations = 0;
  for (size_t n = 1000; n <= 2000; n += 10) {  // an incision's arrays: +1% a frame
    const double* before = v.data();
    resize_with_headroom(v, n);
    reallocations += v.data() != before;
    ASSERT_EQ(v.size(), n);
  }
  EXPECT_LE(reallocations, 4);  // 1000 -> 2000 in steps of 1%: 1.25^4 > 2
  for (int i = 0; i < 1000; ++i) ASSERT_EQ(v[i], i);
  assign_with_headroom(v, 500, 7.0);  // shrinking keeps the buffer
  EXPECT_EQ(v.size(), 500u);
  EXPECT_EQ(v[499], 7.0);
  EXPECT_GE(v.capacity(), 2000u);
  std::vector<int> src = {1, 2, 3}, dst;
  assign_range_with_headroom(dst, src.begin(), src.end());
  EXPECT_EQ(dst, src);
  EXPECT_GE(dst.capacity(), 3u);
}

}  // namespace
}  // namespace incise
