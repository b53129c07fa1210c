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

// Four lanes side by side: each of a 3x3 matrix's entries (Eigen's column-
// major order, (i, j) at i + 3 j) is an Eigen::Array4d over the lanes, so the
// arithmetic of a Newton step runs in vector instructions for the four at
// once, and the per-lane decisions follow it. A lane that has stopped keeps
// computing on values it no longer stores; a padding lane holds the
// identity. Every call pads to 4 lanes, so a gradient's rotation does not
// depend on its neighbours in the call (one code path, the same bits).
constexpr int kLanes = 4;
using Lanes = Eigen::Array4d;

// Eigen's quaternion -> matrix formula (Quaternion::toRotationMatrix).
inline void quaternion_matrices(const Lanes (&q)[4], Lanes (&R)[9]) {
  const Lanes &w = q[0], &x = q[1], &y = q[2], &z = q[3];
  const Lanes tx = 2 * x, ty = 2 * y, tz = 2 * z;
  const Lanes twx = tx * w, twy = ty * w, twz = tz * w, txx = tx * x, txy = ty * x, txz = tz * x, tyy = ty * y,
              tyz = tz * y, tzz = tz * z;
  R[0] = 1 - (tyy + tzz), R[3] = txy - twz, R[6] = txz + twy;
  R[1] = txy + twz, R[4] = 1 - (txx + tzz), R[7] = tyz - twx;
  R[2] = txz - twy, R[5] = tyz + twx, R[8] = 1 - (txx + tyy);
}

// One Newton step of tr(R^T F) from R for every lane: d (the step), its
// length, whether it was a Newton step (H positive definite and not nearly
// flat) and |tr B| (the gradient step's scale otherwise).
// g = axial(B - B^T) with B = F R^T = sum_k f_k r_k^T is the ascent
// direction under R <- exp([d]) R (the step of Mueller et al. 2016); the
// Hessian is -(tr(B) I - sym(B)), positive definite near a maximum, so
// d = (tr(B) I - sym(B))^-1 g converges quadratically. H^-1 g by H's
// cofactors (one division, a short dependency chain: the square roots and
// divisions of a Cholesky took most of the iteration's time); positive
// definite by its leading minors a, ad - b^2 and det H (Sylvester). Both
// steps are computed and one kept (a division by 0 gives an infinity that
// is not kept), so the lanes need no branches.
struct Steps {
  Lanes d[3], angle, trace;
  bool newton[kLanes];
};
inline void newton_steps(const Lanes (&F)[9], const Lanes (&R)[9], const Lanes& scale, Steps& out) {
  Lanes B[9];
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) B[i + 3 * j] = F[i] * R[j] + F[i + 3] * R[j + 3] + F[i + 6] * R[j + 6];
  const Lanes g0 = B[5] - B[7], g1 = B[6] - B[2], g2 = B[1] - B[3];
  const Lanes tr = B[0] + B[4] + B[8];
  const Lanes a = tr - B[0], e = tr - B[4], k = tr - B[8];
  const Lanes b = -0.5 * (B[1] + B[3]), c = -0.5 * (B[2] + B[6]), f = -0.5 * (B[5] + B[7]);
  const Lanes c00 = e * k - f * f, c01 = c * f - b * k, c02 = b * f - c * e;
  const Lanes c11 = a * k - c * c, c12 = b * c - a * f, c22 = a * e - b * b;
  const Lanes det = a * c00 + b * c01 + c * c02;
  const Lanes floor = 1e-6 * scale;
  const Lanes s = det.inverse();
  out.trace = tr.abs();
  const Lanes t = out.trace.inverse();
  const Lanes n0 = s * (c00 * g0 + c01 * g1 + c02 * g2), n1 = s * (c01 * g0 + c11 * g1 + c12 * g2),
              n2 = s * (c02 * g0 + c12 * g1 + c22 * g2);
  for (int l = 0; l < kLanes; ++l) {
    const bool ok = a[l] > floor[l] && e[l] > floor[l] && k[l] > floor[l] && c22[l] > 0.0 && det[l] > 0.0;
    out.newton[l] = ok;
    out.d[0][l] = ok ? n0[l] : t[l] * g0[l];
    out.d[1][l] = ok ? n1[l] : t[l] * g1[l];
    out.d[2][l] = ok ? n2[l] : t[l] * g2[l];
  }
  out.angle = (out.d[0].square() + out.d[1].square() + out.d[2].square()).sqrt();
}

inline double frobenius(const double* F) {
  double s = 0.0;
  for (int i = 0; i < 9; ++i) s += F[i] * F[i];
  return std::sqrt(s);
}

// Lane l's F into F (the identity for a padding lane, Fl null); its |F|, 0
// when it has none to iterate on (padding, F zero or not finite).
inline double load_lane(const double* Fl, Lanes (&F)[9], int l) {
  const double scale = Fl ? frobenius(Fl) : 0.0;
  const bool use = scale > 0.0 && std::isfinite(scale);
  for (int i = 0; i < 9; ++i) F[i][l] = use ? Fl[i] : (i % 4 == 0 ? 1.0 : 0.0);
  return use ? scale : 0.0;
}

// Up to 4 rotations (F, R: (n, 9); R in/out); it: as extract_rotation returns.
int extract_lanes(int n, const double* Fin, double* Rout, int* it_out) {
  Lanes F[9], R[9], q[4], scale;
  // active: iterating; from_q: ends as q's matrix; svd: ends by the SVD; the
  // others (padding, F zero or not finite) end as the identity.
  bool active[kLanes], from_q[kLanes] = {false, false, false, false}, svd[kLanes] = {false, false, false, false};
  int done_it[kLanes] = {0, 0, 0, 0};
  for (int l = 0; l < kLanes; ++l) {
    // Scale-free: the iteration compares against |F|.
    scale[l] = load_lane(l < n ? Fin + 9 * l : nullptr, F, l);
    active[l] = scale[l] > 0.0;
    if (!active[l]) scale[l] = 1.0;
    if (l < n && !active[l]) Eigen::Map<Eigen::Matrix3d>(Rout + 9 * l).setIdentity();
    Eigen::Quaterniond qq = Eigen::Quaterniond::Identity();
    if (active[l]) qq = Eigen::Quaterniond(Eigen::Map<const Eigen::Matrix3d>(Rout + 9 * l)).normalized();
    q[0][l] = qq.w(), q[1][l] = qq.x(), q[2][l] = qq.y(), q[3][l] = qq.z();
  }
  constexpr int kMaxIter = 30;
  Steps st;
  for (int it = 0; it < kMaxIter && (active[0] || active[1] || active[2] || active[3]); ++it) {
    quaternion_matrices(q, R);
    newton_steps(F, R, scale, st);
    bool large = false;
    Lanes keep = Lanes::Zero();  // 1 where q stays as it is
    for (int l = 0; l < kLanes; ++l) {
      if (active[l] && ((!st.newton[l] && st.trace[l] < 1e-3 * scale[l]) || !(st.angle[l] < 4.0)))
        active[l] = false, svd[l] = true;  // near a saddle (strongly inverted), or a wild step: the SVD
      else if (active[l] && st.angle[l] == 0.0)
        active[l] = false, from_q[l] = true, done_it[l] = it;
      large = large || (active[l] && st.angle[l] >= 0.1);
      keep[l] = active[l] ? 0.0 : 1.0;
    }
    // Retraction R <- exp([d]) R. Below 0.1 rad the first-order quaternion
    // update (1, d/2) q, normalized, does: it matches exp to second order, so
    // Newton keeps its quadratic rate (Absil et al., Optimization on Matrix
    // Manifolds, sec. 6.3), without the sine and cosine.
    const Lanes h0 = 0.5 * st.d[0], h1 = 0.5 * st.d[1], h2 = 0.5 * st.d[2];
    const Lanes &w = q[0], &x = q[1], &y = q[2], &z = q[3];
    Lanes nq[4] = {w - (h0 * x + h1 * y + h2 * z), x + w * h0 + h1 * z - h2 * y, y + w * h1 + h2 * x - h0 * z,
                   z + w * h2 + h0 * y - h1 * x};
    const Lanes inv = (nq[0].square() + nq[1].square() + nq[2].square() + nq[3].square()).rsqrt();
    for (int l = 0; large && l < kLanes; ++l) {
      if (!active[l] || st.angle[l] < 0.1) continue;
      const double an = st.angle[l];
      const Eigen::Vector3d axis(st.d[0][l] / an, st.d[1][l] / an, st.d[2][l] / an);
      const Eigen::Quaterniond qq =
          (Eigen::Quaterniond(Eigen::AngleAxisd(an, axis)) * Eigen::Quaterniond(w[l], x[l], y[l], z[l])).normalized();
      nq[0][l] = qq.w(), nq[1][l] = qq.x(), nq[2][l] = qq.y(), nq[3][l] = qq.z();
    }
    for (int i = 0; i < 4; ++i) {
      Lanes moved = nq[i] * inv;
      for (int l = 0; large && l < kLanes; ++l)
        if (active[l] && st.angle[l] >= 0.1) moved[l] = nq[i][l];  // normalized above
      q[i] = (keep > 0.5).select(q[i], moved);  // a stopped lane's step may be garbage: not a product
    }
    // Quadratic convergence: after a Newton step of 1e-7 rad the remaining
    // error is of order 1e-14 (the step squared, times a constant near 1 for
    // elements that are not nearly flat): stop there.
    for (int l = 0; l < kLanes; ++l)
      if (active[l] && ((st.newton[l] && st.angle[l] < 1e-7) || st.angle[l] < 1e-15))
        active[l] = false, from_q[l] = true, done_it[l] = it + 1;
  }
  int fallbacks = 0;
  quaternion_matrices(q, R);
  for (int l = 0; l < n; ++l) {
    if (active[l]) svd[l] = true;  // not converged in kMaxIter steps
    if (from_q[l])
      for (int i = 0; i < 9; ++i) Rout[9 * l + i] = R[i][l];
    if (svd[l]) {
      Eigen::Map<Eigen::Matrix3d>(Rout + 9 * l) = rotation_by_svd(Eigen::Map<const Eigen::Matrix3d>(Fin + 9 * l));
      done_it[l] = -1;
      ++fallbacks;
    }
    if (it_out) it_out[l] = done_it[l];
  }
  return fallbacks;
}
}  // namespace

int extract_rotations(int count, const double* F, double* R, int* iterations) {
  int fallbacks = 0;
  for (int k = 0; k < count; k += kLanes)
    fallbacks += extract_lanes(std::min(kLanes, count - k), F + 9 * static_cast<size_t>(k), R + 9 * static_cast<size_t>(k),
                               iterations ? iterations + k : nullptr);
  return fallbacks;
}

int extract_rotation(const Eigen::Matrix3d& F, Eigen::Matrix3d& R) {
  int it = 0;
  extract_lanes(1, F.data(), R.data(), &it);
  return it;
}

void rotation_angles_to(int count, const double* Fin, const double* Rin, double* out) {
  Lanes F[9], R[9], scale;
  Steps st;
  for (int k0 = 0; k0 < count; k0 += kLanes) {
    const int n = std::min(kLanes, count - k0);
    const double* Fk = Fin + 9 * static_cast<size_t>(k0);
    const double* Rk = Rin + 9 * static_cast<size_t>(k0);
    for (int l = 0; l < kLanes; ++l) {
      scale[l] = load_lane(l < n ? Fk + 9 * l : nullptr, F, l);
      for (int i = 0; i < 9; ++i) R[i][l] = scale[l] > 0.0 ? Rk[9 * l + i] : (i % 4 == 0 ? 1.0 : 0.0);
    }
    const Lanes real = scale;
    scale = (scale > 0.0).select(scale, Lanes::Ones());
    newton_steps(F, R, scale, st);
    for (int l = 0; l < n; ++l) {
      double& a = out[k0 + l];
      if (!(real[l] > 0.0)) {
        a = 0.0;
        continue;
      }
      // The one-step estimate is second-order accurate for small angles only;
      // past 0.5 rad (or near a singular H, where it can read thousands of
      // radians) the exact angle below is taken.
      a = st.angle[l];
      if (st.newton[l] && a < 0.5) continue;
      const Eigen::Map<const Eigen::Matrix3d> Rl(Rk + 9 * l);
      Eigen::Matrix3d Rf = Rl;
      extract_lanes(1, Fk + 9 * l, Rf.data(), nullptr);
      a = std::acos(std::clamp(0.5 * ((Rl.transpose() * Rf).trace() - 1.0), -1.0, 1.0));
    }
  }
}

double rotation_angle_to(const Eigen::Matrix3d& F, const Eigen::Matrix3d& R) {
  double a = 0.0;
  rotation_angles_to(1, F.data(), R.data(), &a);
  return a;
}

std::vector<double> identity_rotations(int nrot) {
  std::vector<double> R(9 * static_cast<size_t>(nrot), 0.0);
  for (int r = 0; r < nrot; ++r) R[9 * r] = R[9 * r + 4] = R[9 * r + 8] = 1.0;
  return R;
}

}  // namespace incise
