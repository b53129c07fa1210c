#include "engine/polar.h"

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
// d = H^-1 g by a hand-written 3x3 Cholesky (H symmetric); false unless H is
// positive definite. Eigen's LLT took more time than the rest of the iteration.
bool solve_spd3(const Eigen::Matrix3d& H, const Eigen::Vector3d& g, Eigen::Vector3d& d) {
  const double a = H(0, 0);
  if (!(a > 0.0)) return false;
  const double l00 = std::sqrt(a), l10 = H(1, 0) / l00, l20 = H(2, 0) / l00;
  const double b = H(1, 1) - l10 * l10;
  if (!(b > 0.0)) return false;
  const double l11 = std::sqrt(b), l21 = (H(2, 1) - l20 * l10) / l11;
  const double c = H(2, 2) - l20 * l20 - l21 * l21;
  if (!(c > 0.0)) return false;
  const double l22 = std::sqrt(c);
  const double y0 = g[0] / l00, y1 = (g[1] - l10 * y0) / l11, y2 = (g[2] - l20 * y0 - l21 * y1) / l22;
  d[2] = y2 / l22;
  d[1] = (y1 - l21 * d[2]) / l11;
  d[0] = (y0 - l10 * d[1] - l20 * d[2]) / l00;
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
    const Eigen::Vector3d g = Rc.col(0).cross(F.col(0)) + Rc.col(1).cross(F.col(1)) + Rc.col(2).cross(F.col(2));
    const Eigen::Matrix3d B = F * Rc.transpose();
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
    q = Eigen::Quaterniond(Eigen::AngleAxisd(angle, d / angle)) * q;
    q.normalize();
    // Near-quadratic convergence: after a Newton step of 1e-11 the error is at roundoff.
    if ((newton && angle < 1e-11) || angle < 1e-15) {
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
  if (H.diagonal().minCoeff() > 1e-6 * scale && solve_spd3(H, g, d)) return d.norm();
  Eigen::Matrix3d Rf = R;
  extract_rotation(F, Rf);
  const double c = 0.5 * ((R.transpose() * Rf).trace() - 1.0);
  return std::acos(std::clamp(c, -1.0, 1.0));
}

}  // namespace incise
