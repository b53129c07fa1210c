#include "engine/polar.h"

#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/Cholesky>
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
    Eigen::LLT<Eigen::Matrix3d> llt(H);
    const bool newton = llt.info() == Eigen::Success && H.diagonal().minCoeff() > 1e-6 * scale;
    if (newton) {
      d = llt.solve(g);
    } else {
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

}  // namespace incise
