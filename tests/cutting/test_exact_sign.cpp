// Exact orientation: decided without tolerance, independent of scale.
#include <cmath>

#include <gtest/gtest.h>

#include "cutting/exact_sign.h"

namespace incise {
namespace {

TEST(ExactSign, PointsOnAndNearAPlane) {
  const double p[3] = {0.1, 0.2, 0.3}, n[3] = {0.3, -0.7, 0.2};
  EXPECT_EQ(exact_sign_dot_diff(p, p, n), 0);
  // one ulp off the point along x: sign of n_x
  const double x[3] = {std::nextafter(0.1, 1.0), 0.2, 0.3};
  EXPECT_EQ(exact_sign_dot_diff(x, p, n), 1);
  const double y[3] = {0.1, std::nextafter(0.2, 1.0), 0.3};
  EXPECT_EQ(exact_sign_dot_diff(y, p, n), -1);
  // a point constructed on the plane in floating point is usually not exactly
  // on it; the exact answer agrees with a long-double check of the residual
  const double t = 0.37;
  const double z[3] = {0.1 + t * 0.7, 0.2 + t * 0.3, 0.3};
  long double r = 0;
  for (int k = 0; k < 3; ++k) r += ((long double)z[k] - p[k]) * n[k];
  const int s = exact_sign_dot_diff(z, p, n);
  if (std::abs((double)r) > 1e-18) {
    EXPECT_EQ(s, r > 0 ? 1 : -1);
  }
}

TEST(ExactSign, CancellationThatFloatingPointGetsWrong) {
  // (x - p) . n = 1e20 + 1 - 1e20 = 1: plain double evaluation rounds the
  // 1 away and returns 0 (the "on the surface" answer); the exact sign is +1.
  const double p[3] = {0, 0, 0}, n[3] = {1.0, 1.0, 1.0};
  const double x[3] = {1e20, 1.0, -1e20};
  volatile double plain = x[0] * n[0] + x[1] * n[1];
  plain = plain + x[2] * n[2];
  EXPECT_EQ(plain, 0.0);
  EXPECT_EQ(exact_sign_dot_diff(x, p, n), 1);
  const double y[3] = {1e20, -1.0, -1e20};
  EXPECT_EQ(exact_sign_dot_diff(y, p, n), -1);
  // the difference x - p is exact too: p far from x
  const double q[3] = {1.0, 0.0, 0.0}, xs[3] = {1.0 + std::ldexp(1.0, -52), 0.0, 0.0};
  EXPECT_EQ(exact_sign_dot_diff(xs, q, n), 1);
  EXPECT_EQ(exact_sign_sum(1e300, -1e300), 0);
  EXPECT_EQ(exact_sign_sum(0.1, -0.1), 0);
  EXPECT_EQ(exact_sign_sum(std::nextafter(0.1, 1.0), -0.1), 1);
}

}  // namespace
}  // namespace incise
