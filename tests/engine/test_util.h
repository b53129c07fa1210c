#pragma once
// Shared helpers for the engine tests: scenes built in code, dense views.
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "engine/fem/assemble.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/model/model.h"
#include "engine/scene/scene.h"

namespace incise::test {

inline Scene basic_scene(int order, MaterialModel model = MaterialModel::Corotated,
                         RotationMode rot = RotationMode::PerPoint) {
  Scene s;
  s.path = "test-scene";
  s.order = order;
  s.material.model = model;
  s.material.rotation = rot;
  s.material.young = 1000.0;
  s.material.poisson = 0.3;
  s.material.density = 1.0;
  s.gravity = {0.0, 0.0, 0.0};
  return s;
}

inline Region box_region(Vec3 lo, Vec3 hi, const std::string& name = "fixed[0]") {
  Region r;
  r.kind = Region::Kind::Box;
  r.lo = lo;
  r.hi = hi;
  r.json_path = name;
  return r;
}

// |a - b| / |b| (relative L2 difference of two fields of the same size).
inline double rel_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0, n = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    d += (a[i] - b[i]) * (a[i] - b[i]);
    n += b[i] * b[i];
  }
  return std::sqrt(d / n);
}

// The full symmetric matrix from the pattern's upper triangle.
inline Eigen::MatrixXd dense(const Model& m, const std::vector<double>& v) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m.ndof(), m.ndof());
  for (int c = 0; c < m.ndof(); ++c)
    for (int k = m.Ap[c]; k < m.Ap[c + 1]; ++k) {
      A(m.Ai[k], c) = v[k];
      A(c, m.Ai[k]) = v[k];
    }
  return A;
}

// The swing-beam tissue (E = 1e5 Pa, nu = 0.45, rho = 1000, lumped mass) on a
// 0.2 x 0.05 x 0.05 m tet10 beam of nx x nyz x nyz cells, clamped at x = 0.
inline Model tissue_beam(int nx, int nyz) {
  Scene s = basic_scene(2);
  s.material.young = 1e5;
  s.material.poisson = 0.45;
  s.material.density = 1000;
  s.fixed.push_back(box_region({-1e-9, -1, -1}, {1e-9, 1, 1}));
  return build_model(make_beam(0.2, 0.05, 0.05, nx, nyz, nyz, 1), s);
}

// K0 + cM M with the clamped rows and columns replaced by the identity, as
// the dynamic step forms it (cM = 4/dt^2; 3600 at 30 Hz); cM = 0 gives the
// static stiffness.
inline std::vector<double> system_matrix(const Model& m, double cM) {
  std::vector<double> A = m.K0_csc;
  for (int d = 0; d < m.ndof(); ++d) A[m.diag[d]] += cM * m.mass_lumped[d];
  for (int k : m.constrained_entries) A[k] = 0.0;
  for (int d = 0; d < m.ndof(); ++d)
    if (m.constrained[d]) A[m.diag[d]] = 1.0;
  return A;
}

// n values uniform in [-1, 1], reproducible by seed.
inline std::vector<double> random_vector(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> v(n);
  for (double& x : v) x = U(rng);
  return v;
}

// CG on A x = b from x = 0, preconditioned by precond(r, z) (z = P r), until
// |r| <= tol |b| or max_iterations; returns the iterations, *rel_out the
// final relative residual.
template <class Precond>
int preconditioned_cg(const Model& m, const std::vector<double>& A, const std::vector<double>& b,
                      const Precond& precond, int max_iterations, double tol, double* rel_out) {
  const int n = m.ndof();
  std::vector<double> x(n, 0.0), r = b, z(n), p(n), q(n);
  auto dot = [](const std::vector<double>& a, const std::vector<double>& c) {
    double s = 0;
    for (size_t i = 0; i < a.size(); ++i) s += a[i] * c[i];
    return s;
  };
  const double nb = std::sqrt(dot(b, b));
  precond(r.data(), z.data());
  p = z;
  double rz = dot(r, z), rel = 1;
  int it = 0;
  while (it < max_iterations && rel > tol) {
    sym_matvec(m, A.data(), p.data(), q.data());
    ++it;
    const double alpha = rz / dot(p, q);
    for (int i = 0; i < n; ++i) x[i] += alpha * p[i], r[i] -= alpha * q[i];
    rel = std::sqrt(dot(r, r)) / nb;
    precond(r.data(), z.data());
    const double rz_new = dot(r, z);
    for (int i = 0; i < n; ++i) p[i] = z[i] + rz_new / rz * p[i];
    rz = rz_new;
  }
  *rel_out = rel;
  return it;
}

// A swinging tet10 cantilever 2 x 0.4 x 0.4 (E = 2e4, nu = 0.4, rho = 1,
// Rayleigh 0.5 / 0.002, gravity), clamped at x = 0, its free end face
// prescribed to move by (-0.8, 0.6, 0.5) over 0.5 s: a large arc.
inline Scene swing_scene() {
  Scene s = basic_scene(2);
  s.material.young = 2e4;
  s.material.poisson = 0.4;
  s.material.density = 1.0;
  s.material.rayleigh_mass = 0.5;
  s.material.rayleigh_stiffness = 0.002;
  s.gravity = {0, 0, -9.81};
  s.fixed.push_back(box_region({-1, -1, -1}, {0, 2, 2}));
  Prescribed p;
  p.region = box_region({2.0, -1, -1}, {3, 2, 2}, "prescribed[0]");
  p.active = {true, true, true};
  p.displacement = {-0.8, 0.6, 0.5};
  p.ramp = 0.5;
  s.prescribed.push_back(p);
  return s;
}

}  // namespace incise::test
