#pragma once
// Shared helpers for the engine tests: scenes built in code, dense views.
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "engine/model.h"
#include "engine/scene.h"

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

}  // namespace incise::test
