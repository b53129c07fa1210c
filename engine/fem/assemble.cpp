#include "engine/fem/assemble.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Core>

#include "engine/fem/node_block_matvec.h"
#include "engine/fem/polar.h"
#include "engine/fem/rotation_stiffness.h"

namespace incise {

namespace {
using Mat3 = Eigen::Matrix3d;
using Vec3d = Eigen::Vector3d;

// G = F - I = sum_a u_a (x) grad_a over the element's DOF nodes (F = sum_a
// x_a (x) grad_a and sum_a X_a (x) grad_a = I; summing positions loses
// |X| / h digits: assemble_parallel.cpp, add_identity).
Mat3 displacement_gradient(const Model& m, int e, const double* u, const double* grad) {
  Mat3 F = Mat3::Zero();
  const int b = m.elem_dof_ptr[e], n = m.elem_dof_ptr[e + 1] - b;
  for (int a = 0; a < n; ++a) {
    const int node = m.elem_dof_node[b + a];
    const Vec3d ua(u[3 * node], u[3 * node + 1], u[3 * node + 2]);
    F += ua * Vec3d(grad[3 * a], grad[3 * a + 1], grad[3 * a + 2]).transpose();
  }
  return F;
}

// The corotated strain sym(R^T F) - I from G = F - I, as sym(R^T G + R^T - I)
// (no cancellation against I).
Mat3 corotated_strain(const Mat3& R, const Mat3& G) {
  const Mat3 E = R.transpose() * G + R.transpose() - Mat3::Identity();
  return 0.5 * (E + E.transpose());
}

// Corotated stress sig' (in the unrotated frame) at one point.
Mat3 corotated_stress(const Model& m, const Mat3& R, const Mat3& G) {
  const Mat3 eps = corotated_strain(R, G);
  return 2.0 * m.mu * eps + m.lambda * eps.trace() * Mat3::Identity();
}
}  // namespace

std::vector<char> point_rotation_flags(const Model& m) { return point_rotation_flags(m, m.consistent_tangent); }

std::vector<char> point_rotation_flags(const Model& m, bool consistent) {
  std::vector<char> own(m.qp_rot.size(), 0);
  if (m.material.model == MaterialModel::Linear || !consistent) return own;
  std::vector<int> users(m.nrot, 0);
  for (int r : m.qp_rot) ++users[r];
  for (size_t q = 0; q < own.size(); ++q) own[q] = users[m.qp_rot[q]] == 1;
  return own;
}

std::vector<double> shared_slot_weights(const Model& m) { return shared_slot_weights(m, m.consistent_tangent); }

std::vector<double> shared_slot_weights(const Model& m, bool consistent) {
  std::vector<double> W(m.nrot, 0.0);
  if (m.material.model == MaterialModel::Linear || !consistent) return W;
  std::vector<int> users(m.nrot, 0);
  for (int r : m.qp_rot) ++users[r];
  // A small piece's extension points (Model::qp_extension) are left out: the
  // term is evaluated at the slot's own F, and theirs (the piece's field
  // across its element) differs; with them in, a slit 1e-3 h beside a node
  // layer under the realtime preset took 2.20 Newton and 14 CG iterations a
  // frame against 1.73 and 6 without the extension (1.77 and 7 now).
  for (size_t q = 0; q < m.qp_rot.size(); ++q)
    if (users[m.qp_rot[q]] > 1 && !m.qp_extension[q]) W[m.qp_rot[q]] += m.qp_weight[q];
  return W;
}

int update_rotations(const Model& m, const double* u, double* R) { return update_rotations(m, u, R, 0, m.nrot); }

int update_rotations(const Model& m, const double* u, double* R, int r_begin, int r_end) {
  if (m.material.model == MaterialModel::Linear) {
    for (int r = r_begin; r < r_end; ++r) Eigen::Map<Mat3>(R + 9 * r).setIdentity();
    return 0;
  }
  int fallbacks = 0;
  for (int r = r_begin; r < r_end; ++r) {
    const Mat3 F = Mat3::Identity() + displacement_gradient(m, m.rot_elem[r], u, &m.rot_grad[m.rot_grad_ptr[r]]);
    Mat3 Rr = Eigen::Map<const Mat3>(R + 9 * r);
    if (extract_rotation(F, Rr) < 0) ++fallbacks;
    Eigen::Map<Mat3>(R + 9 * r) = Rr;
  }
  return fallbacks;
}

void assemble_internal(const Model& m, const double* u, const double* R, double* f_int, double* K) {
  std::fill(f_int, f_int + m.ndof(), 0.0);
  if (K) std::fill(K, K + m.nnz(), 0.0);
  // Per-thread scratch kept across calls: no allocation per frame.
  thread_local std::vector<double> Kloc;  // blocks a <= b, 9 each (row-major within a block)
  thread_local std::vector<double> h;     // (n, 3) rotated gradients
  thread_local std::vector<double> t;     // (n, 3, 3) rotation-mode vectors
  const std::vector<char> own_rot = K ? point_rotation_flags(m) : std::vector<char>();
  const std::vector<double> slot_w = K ? shared_slot_weights(m) : std::vector<double>();
  std::vector<int> done;  // shared slots of the element already given their term
  for (int e = 0; e < m.nelem; ++e) {
    const int b0 = m.elem_dof_ptr[e], n = m.elem_dof_ptr[e + 1] - b0;
    const int nblk = n * (n + 1) / 2;
    if (K) Kloc.assign(9 * nblk, 0.0);
    h.resize(3 * n);
    t.resize(9 * n);
    done.clear();
    for (int q = m.elem_qp_ptr[e]; K && q < m.elem_qp_ptr[e + 1]; ++q) {
      const int r = m.qp_rot[q];
      if (slot_w[r] <= 0.0 || std::find(done.begin(), done.end(), r) != done.end()) continue;
      done.push_back(r);
      const Mat3 Fbar = Mat3::Identity() + displacement_gradient(m, e, u, &m.rot_grad[m.rot_grad_ptr[r]]);
      add_slot_rotation_stiffness(n, R + 9 * r, Fbar.data(), &m.rot_grad[m.rot_grad_ptr[r]], m.mu, m.lambda, slot_w[r],
                                  Kloc.data(), h.data(), t.data());
    }
    for (int q = m.elem_qp_ptr[e]; q < m.elem_qp_ptr[e + 1]; ++q) {
      const double w = m.qp_weight[q];
      const double* g = &m.qp_grad[m.qp_grad_ptr[q]];
      const Eigen::Map<const Mat3> Rq(R + 9 * m.qp_rot[q]);
      const Mat3 G = displacement_gradient(m, e, u, g);
      const Mat3 F = Mat3::Identity() + G;
      const Mat3 P = w * (Rq * corotated_stress(m, Rq, G));  // w R sig'
      for (int a = 0; a < n; ++a) {
        const Vec3d ga(g[3 * a], g[3 * a + 1], g[3 * a + 2]);
        const Vec3d fa = P * ga;
        const int node = m.elem_dof_node[b0 + a];
        for (int i = 0; i < 3; ++i) f_int[3 * node + i] += fa[i];
        const Vec3d ha = Rq * ga;
        for (int i = 0; i < 3; ++i) h[3 * a + i] = ha[i];
      }
      if (!K) continue;
      double* blk = Kloc.data();
      for (int a = 0; a < n; ++a) {
        const double* ha = &h[3 * a];
        const double* ga = &g[3 * a];
        for (int bb = a; bb < n; ++bb, blk += 9) {
          const double* hb = &h[3 * bb];
          const double* gb = &g[3 * bb];
          const double gg = m.mu * (ga[0] * gb[0] + ga[1] * gb[1] + ga[2] * gb[2]);
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
              blk[3 * i + j] += w * (m.lambda * ha[i] * hb[j] + m.mu * hb[i] * ha[j] + (i == j ? gg : 0.0));
        }
      }
      double uk[9], coef[3];
      if (own_rot[q] && rotation_stiffness_modes(Rq.data(), F.data(), m.mu, m.lambda, w, uk, coef))
        add_rotation_stiffness(n, h.data(), uk, coef, Kloc.data(), t.data());
    }
    if (!K) continue;
    const int* sc = &m.elem_scatter[m.elem_scatter_ptr[e]];
    for (int k = 0; k < 9 * nblk; ++k)
      if (sc[k] >= 0) K[sc[k]] += Kloc[k];
  }
}

void sym_matvec(const Model& m, const double* A, const double* x, double* y) {
  std::fill(y, y + m.ndof(), 0.0);
  node_block_matvec(m.Ap.data(), m.Ai.data(), A, x, 0, m.ndofnode, 0, y, y);
}

void element_von_mises(const Model& m, const double* u, const double* R, double* vm) {
  for (int e = 0; e < m.nelem; ++e) {
    Mat3 s = Mat3::Zero();
    double vol = 0.0;
    for (int q = m.elem_qp_ptr[e]; q < m.elem_qp_ptr[e + 1]; ++q) {
      const Eigen::Map<const Mat3> Rq(R + 9 * m.qp_rot[q]);
      s += m.qp_weight[q] * corotated_stress(m, Rq, displacement_gradient(m, e, u, &m.qp_grad[m.qp_grad_ptr[q]]));
      vol += m.qp_weight[q];
    }
    s /= vol;
    const Mat3 dev = s - s.trace() / 3.0 * Mat3::Identity();
    vm[e] = std::sqrt(1.5 * (dev.array() * dev.array()).sum());
  }
}

}  // namespace incise

namespace incise {
double elastic_energy(const Model& m, const double* u, const double* R) {
  double E = 0.0;
  for (int e = 0; e < m.nelem; ++e)
    for (int q = m.elem_qp_ptr[e]; q < m.elem_qp_ptr[e + 1]; ++q) {
      const Eigen::Map<const Mat3> Rq(R + 9 * m.qp_rot[q]);
      const Mat3 eps = corotated_strain(Rq, displacement_gradient(m, e, u, &m.qp_grad[m.qp_grad_ptr[q]]));
      E += m.qp_weight[q] * (m.mu * (eps.array() * eps.array()).sum() + 0.5 * m.lambda * eps.trace() * eps.trace());
    }
  return E;
}
}  // namespace incise
