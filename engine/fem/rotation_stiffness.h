#pragma once
// The rotation (dR/dF) part of the corotated tangent, the term a frozen-R
// tangent R K0 R^T leaves out.
//
// The corotated stress P = 2 mu (F - R) + lambda tr(S - I) R with F = R S
// (book eq. 3.64-3.66 at a point whose R is the polar factor of its own F)
// varies as
//   dP = 2 mu dF + lambda tr(R^T dF) R - c dR,   c = 2 mu - lambda tr(S - I),
// and dR = R [w]x with (tr(S) I - S) w = 2 axial(skew(R^T dF)) (the polar
// decomposition's derivative). The frozen-R tangent keeps only
// 2 mu R sym(R^T dF) + lambda tr(R^T dF) R; the difference, in the
// eigenbasis v_k of S (pair (i, j) = the two other axes), is
//   dP - dP_frozen = sum_k kappa_k <dF, Q_k> Q_k,  Q_k = R [v_k]x / sqrt(2),
//   kappa_k = 2 mu - 2 c / (s_i + s_j)
// (with s the eigenvalues of S; zero at rest, S = I). For an element point of
// weight w and gradients g_a this adds to the element block
//   K_ab += w kappa_k / 2 (u_k x h_a)(u_k x h_b)^T,  u_k = R v_k, h_a = R g_a.
// kappa_k < 0 (compressed pairs) is dropped, which keeps the tangent positive
// semi-definite (the eigenvalue projection of Teran et al. 2005 restricted to
// the rotation modes). Stretched elements then resist the rotations that a
// frozen-R linearisation lets through: on the 10k organ drag that missing
// stiffness kept a strained element wobbling by ~0.1 rad per frame. This is
// the Newton tangent from dP/dF of the stress actually used (the lectures'
// sec. 2.5.3, dq/du), projected. Used only under integrator.tangent
// "consistent" (point_rotation_flags / shared_slot_weights, engine/fem/assemble.h):
// near-incompressible tissue at 30 Hz diverges with it (docs/numerics.md).
#include <cmath>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

namespace incise {

// Z = 2 mu I - 2 c T^-1 with T = tr(S) I - S, S = sym(R^T F), c = 2 mu -
// lambda tr(S - I) (the rotation modes' stiffness, eigenvalues kappa_k on the
// axes of S), and S. False (no rotation term) where T is not positive
// definite (an inverted or degenerate point: some pair s_i + s_j <= 0) or
// every |kappa| is below 1% of mu (a nearly unstrained point: not worth the
// element update; `exact` keeps it: the static solve's Newton tangent).
inline bool rotation_mode_stiffness(const double* R, const double* F, double mu, double lambda, Eigen::Matrix3d& Z,
                                    Eigen::Matrix3d& S, bool exact = false) {
  const Eigen::Map<const Eigen::Matrix3d> Rm(R), Fm(F);
  const Eigen::Matrix3d RtF = Rm.transpose() * Fm;
  S = 0.5 * (RtF + RtF.transpose());
  const double trS = S.trace();
  const double c = 2.0 * mu - lambda * (trS - 3.0);
  Eigen::Matrix3d T = -S;
  T.diagonal().array() += trS;
  const double det = T.determinant();
  const double scale = std::abs(trS) + 1e-300;  // Sylvester's criterion, scaled
  if (!(T(0, 0) > 1e-6 * scale && T(0, 0) * T(1, 1) - T(0, 1) * T(0, 1) > 1e-12 * scale * scale &&
        det > 1e-18 * scale * scale * scale))
    return false;
  Z = (-2.0 * c) * T.inverse();  // cofactors for a fixed 3x3
  Z.diagonal().array() += 2.0 * mu;
  return exact || Z.cwiseAbs().maxCoeff() >= 1e-2 * mu;
}

// For a point with rotation R and gradient F (both column-major 3x3) and
// weight w: three vectors u_k (columns of u (3, 3)) and coef[k] >= 0 with
//   sum_k coef[k] u_k u_k^T = w/2 R Z+ R^T,  Z = 2 mu I - 2 c (tr(S) I - S)^-1,
// Z+ its positive part (Z has the eigenvalues kappa_k on the axes v_k). When
// Z is positive semi-definite (the usual case where rotation terms matter: a
// stretched point) its 3x3 Cholesky factor gives the u_k; otherwise the
// eigen-decomposition of S does (slower, rarer). Returns whether any
// coefficient is positive. `exact`: Z itself, kappa_k < 0 kept (coef may be
// negative; the tangent may then be indefinite: the static solve's Newton).
inline bool rotation_stiffness_modes(const double* R, const double* F, double mu, double lambda, double w, double* u,
                                     double* coef, bool exact = false) {
  const Eigen::Map<const Eigen::Matrix3d> Rm(R);
  Eigen::Matrix3d Z, S;
  if (!rotation_mode_stiffness(R, F, mu, lambda, Z, S, exact)) {
    coef[0] = coef[1] = coef[2] = 0.0;
    return false;
  }
  // Cholesky Z = L L^T, lower.
  const double l00s = Z(0, 0);
  if (l00s > 0.0 && !exact) {
    const double l00 = std::sqrt(l00s), l10 = Z(1, 0) / l00, l20 = Z(2, 0) / l00;
    const double l11s = Z(1, 1) - l10 * l10;
    if (l11s > 0.0) {
      const double l11 = std::sqrt(l11s), l21 = (Z(2, 1) - l20 * l10) / l11;
      const double l22s = Z(2, 2) - l20 * l20 - l21 * l21;
      if (l22s >= 0.0) {
        const Eigen::Vector3d c0(l00, l10, l20), c1(0.0, l11, l21), c2(0.0, 0.0, std::sqrt(l22s));
        Eigen::Map<Eigen::Vector3d>(u + 0) = Rm * c0;
        Eigen::Map<Eigen::Vector3d>(u + 3) = Rm * c1;
        Eigen::Map<Eigen::Vector3d>(u + 6) = Rm * c2;
        coef[0] = coef[1] = coef[2] = 0.5 * w;
        return true;
      }
    }
  }
  // Indefinite: project on the eigenvectors v_k of S (those of Z too).
  const double c = 2.0 * mu - lambda * (S.trace() - 3.0);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(S);
  const Eigen::Vector3d s = es.eigenvalues();
  bool any = false;
  for (int k = 0; k < 3; ++k) {
    const double pair = s[(k + 1) % 3] + s[(k + 2) % 3];
    const double kappa = pair > 1e-8 ? 2.0 * mu - 2.0 * c / pair : 0.0;
    coef[k] = kappa > 0.0 || exact ? 0.5 * w * kappa : 0.0;
    any = any || coef[k] != 0.0;
    Eigen::Map<Eigen::Vector3d>(u + 3 * k) = Rm * es.eigenvectors().col(k);
  }
  return any;
}

// The same term as one symmetric 3x3 matrix Y = sum_k coef[k] u_k u_k^T =
// w/2 R Z+ R^T (column-major), for kernels that fold it into their blocks as
// [h_a]x Y [h_b]x^T. Positive semi-definite Z (checked by its leading minors,
// the Cholesky test of rotation_stiffness_modes) needs no factor: Y =
// w/2 R Z R^T; otherwise the modes' eigen path. Returns whether Y != 0.
// `exact`: Y = w/2 R Z R^T always (rotation_stiffness_modes).
inline bool rotation_stiffness_matrix(const double* R, const double* F, double mu, double lambda, double w,
                                      double* Y, bool exact = false) {
  const Eigen::Map<const Eigen::Matrix3d> Rm(R);
  Eigen::Map<Eigen::Matrix3d> Ym(Y);
  Eigen::Matrix3d Z, S;
  if (!rotation_mode_stiffness(R, F, mu, lambda, Z, S, exact)) {
    Ym.setZero();
    return false;
  }
  const double m2 = Z(0, 0) * Z(1, 1) - Z(0, 1) * Z(0, 1);
  if (exact || (Z(0, 0) > 0.0 && m2 > 0.0 && Z.determinant() >= 0.0)) {
    Ym = (0.5 * w) * (Rm * Z * Rm.transpose());
    return true;
  }
  double u[9], coef[3];
  Ym.setZero();
  if (!rotation_stiffness_modes(R, F, mu, lambda, w, u, coef)) return false;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Map<const Eigen::Vector3d> uk(u + 3 * k);
    Ym += coef[k] * uk * uk.transpose();
  }
  return true;
}

// Adds sum_k coef[k] (u_k x h_a)(u_k x h_b)^T to the element blocks a <= b
// (row-major 3x3 each, in the order (0,0), (0,1), ..., (1,1), ...) for n nodes
// with rotated gradients h (n, 3). t is scratch (3 n, 3).
inline void add_rotation_stiffness(int n, const double* h, const double* u, const double* coef, double* blocks,
                                   double* t) {
  for (int k = 0; k < 3; ++k) {
    const double* uk = u + 3 * k;
    for (int a = 0; a < n; ++a) {
      const double* ha = h + 3 * a;
      double* ta = t + 9 * a + 3 * k;
      ta[0] = uk[1] * ha[2] - uk[2] * ha[1];
      ta[1] = uk[2] * ha[0] - uk[0] * ha[2];
      ta[2] = uk[0] * ha[1] - uk[1] * ha[0];
    }
  }
  double* blk = blocks;
  for (int a = 0; a < n; ++a) {
    const double* ta = t + 9 * a;
    double ca[9];
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 3; ++i) ca[3 * k + i] = coef[k] * ta[3 * k + i];
    for (int b = a; b < n; ++b, blk += 9) {
      const double* tb = t + 9 * b;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          blk[3 * i + j] += ca[i] * tb[j] + ca[3 + i] * tb[3 + j] + ca[6 + i] * tb[6 + j];
    }
  }
}

// The term for a rotation slot that several points share (one rotation per
// element or per cut piece, the polar factor of the volume-averaged gradient
// F of the slot's points, total weight W, averaged gradients gbar (n, 3)):
// the point formula with F, W and gbar standing for the slot's points. Exact
// for constant-gradient elements, an approximation (still positive
// semi-definite) otherwise. hbar (n, 3) and t (n, 3, 3) are scratch.
inline void add_slot_rotation_stiffness(int n, const double* R, const double* F, const double* gbar, double mu,
                                        double lambda, double W, double* blocks, double* hbar, double* t,
                                        bool exact = false) {
  double u[9], coef[3];
  if (!rotation_stiffness_modes(R, F, mu, lambda, W, u, coef, exact)) return;
  for (int a = 0; a < n; ++a) {
    const double g0 = gbar[3 * a], g1 = gbar[3 * a + 1], g2 = gbar[3 * a + 2];
    hbar[3 * a] = R[0] * g0 + R[3] * g1 + R[6] * g2;
    hbar[3 * a + 1] = R[1] * g0 + R[4] * g1 + R[7] * g2;
    hbar[3 * a + 2] = R[2] * g0 + R[5] * g1 + R[8] * g2;
  }
  add_rotation_stiffness(n, hbar, u, coef, blocks, t);
}

}  // namespace incise
