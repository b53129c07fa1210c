#include "engine/fem/polar.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/SVD>

namespace incise {

namespace {
Eigen::Matrix3d rotation_by_svd(const Eigen::Matrix3d& F) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  const Eigen::Matrix3d V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0) U.col(2) *= -1.0;  // singular values sorted: flip smallest
  return U * V.transpose();
}
// d = H^-1 g for symmetric H by its cofactors (one division, a short
// dependency chain: the square roots and divisions of a Cholesky took most of
// the iteration's time); false unless H is positive definite (its leading
// minors a, ad - b^2 and det H, Sylvester's criterion).
bool solve_spd3(const Eigen::Matrix3d& H, const Eigen::Vector3d& g, Eigen::Vector3d& d) {
  const double a = H(0, 0), b = H(1, 0), c = H(2, 0), e = H(1, 1), f = H(2, 1), k = H(2, 2);
  const double c00 = e * k - f * f, c01 = c * f - b * k, c02 = b * f - c * e;
  const double c11 = a * k - c * c, c12 = b * c - a * f, c22 = a * e - b * b;
  const double det = a * c00 + b * c01 + c * c02;
  if (!(a > 0.0 && c22 > 0.0 && det > 0.0)) return false;
  const double s = 1.0 / det;
  d[0] = s * (c00 * g[0] + c01 * g[1] + c02 * g[2]);
  d[1] = s * (c01 * g[0] + c11 * g[1] + c12 * g[2]);
  d[2] = s * (c02 * g[0] + c12 * g[1] + c22 * g[2]);
  return true;
}

}  // namespace

int extract_rotation(const Eigen::Matrix3d& F, Eigen::Matrix3d& R) {
  // Scale-free: the iteration below compares against |F|.
  const double scale = F.norm();
  if (!(scale > 0.0) || !std::isfinite(scale)) {
    R.setIdentity();
    return 0;
  }
  Eigen::Quaterniond q(R);
  q.normalize();
  constexpr int kMaxIter = 30;
  for (int it = 0; it < kMaxIter; ++it) {
    const Eigen::Matrix3d Rc = q.toRotationMatrix();
    // Ascent direction of tr(R^T F) under R <- exp([d]) R: g = sum_k r_k x f_k
    // (the step of Mueller et al. 2016). Newton on the same objective: its
    // Hessian is -(tr(B) I - sym(B)) with B = F R^T, positive definite near a
    // maximum, so d = (tr(B) I - sym(B))^-1 g converges quadratically.
    // g = axial(B - B^T) with B = F R^T = sum_k f_k r_k^T.
    const Eigen::Matrix3d B = F * Rc.transpose();
    const Eigen::Vector3d g(B(2, 1) - B(1, 2), B(0, 2) - B(2, 0), B(1, 0) - B(0, 1));
    const Eigen::Matrix3d H = B.trace() * Eigen::Matrix3d::Identity() - 0.5 * (B + B.transpose());
    Eigen::Vector3d d;
    const bool newton = H.diagonal().minCoeff() > 1e-6 * scale && solve_spd3(H, g, d);
    if (!newton) {
      const double denom = std::abs(B.trace());
      if (denom < 1e-3 * scale) break;  // near a saddle (strongly inverted): take the SVD
      d = g / denom;
    }
    const double angle = d.norm();
    if (!(angle < 4.0)) break;
    if (angle == 0.0) {
      R = Rc;
      return it;
    }
    // Retraction R <- exp([d]) R. Below 0.1 rad the first-order quaternion
    // update (1, d/2) q, normalized, does: it matches exp to second order, so
    // Newton keeps its quadratic rate (Absil et al., Optimization on Matrix
    // Manifolds, sec. 6.3), without the sine and cosine.
    if (angle < 0.1) {
      const Eigen::Vector3d h = 0.5 * d;
      q = Eigen::Quaterniond(q.w() - h.dot(q.vec()), q.x() + q.w() * h[0] + h[1] * q.z() - h[2] * q.y(),
                             q.y() + q.w() * h[1] + h[2] * q.x() - h[0] * q.z(),
                             q.z() + q.w() * h[2] + h[0] * q.y() - h[1] * q.x());
    } else {
      q = Eigen::Quaterniond(Eigen::AngleAxisd(angle, d / angle)) * q;
    }
    q.normalize();
    // Quadratic convergence: after a Newton step of 1e-7 rad the remaining
    // error is of order 1e-14 (the step squared, times a constant near 1 for
    // elements that are not nearly flat): stop there.
    if ((newton && angle < 1e-7) || angle < 1e-15) {
      R = q.toRotationMatrix();
      return it + 1;
    }
  }
  R = rotation_by_svd(F);
  return -1;
}

double rotation_angle_to(const Eigen::Matrix3d& F, const Eigen::Matrix3d& R) {
  const double scale = F.norm();
  if (!(scale > 0.0) || !std::isfinite(scale)) return 0.0;
  const Eigen::Vector3d g = R.col(0).cross(F.col(0)) + R.col(1).cross(F.col(1)) + R.col(2).cross(F.col(2));
  const Eigen::Matrix3d B = F * R.transpose();
  const Eigen::Matrix3d H = B.trace() * Eigen::Matrix3d::Identity() - 0.5 * (B + B.transpose());
  Eigen::Vector3d d;
  // The one-step estimate is second-order accurate for small angles only;
  // past 0.5 rad (or near a singular H, where it can read thousands of
  // radians) the exact angle below is taken.
  if (H.diagonal().minCoeff() > 1e-6 * scale && solve_spd3(H, g, d) && d.norm() < 0.5) return d.norm();
  Eigen::Matrix3d Rf = R;
  extract_rotation(F, Rf);
  const double c = 0.5 * ((R.transpose() * Rf).trace() - 1.0);
  return std::acos(std::clamp(c, -1.0, 1.0));
}

std::vector<double> identity_rotations(int nrot) {
  std::vector<double> R(9 * static_cast<size_t>(nrot), 0.0);
  for (int r = 0; r < nrot; ++r) R[9 * r] = R[9 * r + 4] = R[9 * r + 8] = 1.0;
  return R;
}

}  // namespace incise
