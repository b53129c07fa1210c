#pragma once
// Exact signs of small polynomial expressions in double precision inputs,
// by error-free transformations (two-sum, two-product via FMA) and expansion
// arithmetic (Shewchuk 1997). Used where a cut's degenerate cases (a node on
// the surface, an edge or face in it) must be decided without a tolerance
// that could flip with the model's scale.
namespace incise {

// Sign (-1, 0, +1) of (x - p) . n, computed exactly.
int exact_sign_dot_diff(const double x[3], const double p[3], const double n[3]);

// Sign of a + b, exactly (no rounding to zero).
int exact_sign_sum(double a, double b);

}  // namespace incise
