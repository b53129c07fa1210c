#include "cutting/exact_sign.h"

#include <cmath>
#include <initializer_list>

namespace incise {

namespace {

// a + b = s + e exactly.
inline void two_sum(double a, double b, double& s, double& e) {
  s = a + b;
  const double bv = s - a, av = s - bv;
  e = (a - av) + (b - bv);
}

// a * b = p + e exactly (FMA).
inline void two_prod(double a, double b, double& p, double& e) {
  p = a * b;
  e = std::fma(a, b, -p);
}

// Adds a term to a nonoverlapping expansion (grow-expansion), length n -> n+1.
int grow(double* h, int n, double b) {
  double q = b;
  for (int i = 0; i < n; ++i) {
    double s, e;
    two_sum(q, h[i], s, e);
    h[i] = e;
    q = s;
  }
  h[n] = q;
  return n + 1;
}

// Sign of an expansion: its largest-magnitude nonzero component decides.
int sign_of(const double* h, int n) {
  for (int i = n - 1; i >= 0; --i)
    if (h[i] != 0.0) return h[i] > 0 ? 1 : -1;
  return 0;
}

}  // namespace

int exact_sign_dot_diff(const double x[3], const double p[3], const double n[3]) {
  // (x_k - p_k) = d_k + e_k exactly; (d_k + e_k) n_k = 4 exact products.
  double h[12];
  int len = 0;
  for (int k = 0; k < 3; ++k) {
    double d, e;
    two_sum(x[k], -p[k], d, e);
    double p1, e1, p2, e2;
    two_prod(d, n[k], p1, e1);
    two_prod(e, n[k], p2, e2);
    for (double t : {e2, p2, e1, p1}) len = grow(h, len, t);
  }
  return sign_of(h, len);
}

int exact_sign_sum(double a, double b) {
  double s, e;
  two_sum(a, b, s, e);
  if (s != 0.0) return s > 0 ? 1 : -1;
  return e > 0 ? 1 : (e < 0 ? -1 : 0);
}

}  // namespace incise
