#include "collision/narrowphase.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

namespace incise {
namespace {

using Eigen::Vector3d;

// Closest points of segments [p1, q1] and [p2, q2] (Ericson 2005, sec. 5.1.9):
// s, t their parameters; returns the squared distance.
double closest_segment_segment(const Vector3d& p1, const Vector3d& q1, const Vector3d& p2, const Vector3d& q2,
                               double& s, double& t) {
  const Vector3d d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  if (a <= 0 && e <= 0) {
    s = t = 0;
  } else if (a <= 0) {
    s = 0;
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 0) {
      t = 0;
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), denom = a * e - b * b;
      s = denom > 0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;  // parallel: any s, then t
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return (p1 + s * d1 - (p2 + t * d2)).squaredNorm();
}

}  // namespace

Vector3d closest_point_on_triangle(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c,
                                   double bary[3]) {
  // Voronoi regions of the vertices, edges and face, in that order.
  auto set = [&](double l0, double l1, double l2) {
    bary[0] = l0, bary[1] = l1, bary[2] = l2;
    return Vector3d(l0 * a + l1 * b + l2 * c);
  };
  const Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return set(1, 0, 0);
  const Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return set(0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);  // d1 - d3 = |ab|^2 > 0 here
    return set(1 - v, v, 0);
  }
  const Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return set(0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return set(1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return set(0, 1 - w, w);
  }
  const double sum = va + vb + vc;
  if (!(sum > 0)) return set(1, 0, 0);  // zero area: every region test failed on roundoff
  const double v = vb / sum, w = vc / sum;
  return set(1 - v - w, v, w);
}

Vector3d nearest_on_segment(const Vector3d& a, const Vector3d& b, const Vector3d& x) {
  const Vector3d ab = b - a;
  const double l2 = ab.squaredNorm();
  if (!(l2 > 0)) return a;
  return a + std::clamp((x - a).dot(ab) / l2, 0.0, 1.0) * ab;
}

double closest_segment_triangle(const Vector3d& p, const Vector3d& q, const Vector3d& v0, const Vector3d& v1,
                                const Vector3d& v2, double& t, double bary[3]) {
  double bt[3];
  t = 0;
  double best = (closest_point_on_triangle(p, v0, v1, v2, bary) - p).squaredNorm();
  if ((q - p).squaredNorm() <= 0) return best;
  // The segment through the face: distance 0 at the crossing.
  const Vector3d n = (v1 - v0).cross(v2 - v0);
  const double sp = n.dot(p - v0), sq = n.dot(q - v0);
  if (sp != sq && ((sp <= 0 && sq >= 0) || (sp >= 0 && sq <= 0))) {
    const double tc = sp / (sp - sq);
    const Vector3d x = p + tc * (q - p);
    // Barycentric coordinates of x in the plane (Ericson sec. 3.4).
    const Vector3d e0 = v1 - v0, e1 = v2 - v0, ex = x - v0;
    const double d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), dx0 = ex.dot(e0), dx1 = ex.dot(e1);
    const double den = d00 * d11 - d01 * d01;
    if (den > 0) {
      const double l1 = (d11 * dx0 - d01 * dx1) / den, l2 = (d00 * dx1 - d01 * dx0) / den, l0 = 1 - l1 - l2;
      if (l0 >= 0 && l1 >= 0 && l2 >= 0) {
        t = tc, bary[0] = l0, bary[1] = l1, bary[2] = l2;
        return 0.0;
      }
    }
  }
  const double dq = (closest_point_on_triangle(q, v0, v1, v2, bt) - q).squaredNorm();
  if (dq < best) best = dq, t = 1, std::copy(bt, bt + 3, bary);
  const Vector3d* v[3] = {&v0, &v1, &v2};
  for (int k = 0; k < 3; ++k) {
    double s, u;
    const double d = closest_segment_segment(p, q, *v[k], *v[(k + 1) % 3], s, u);
    if (d < best) {
      best = d, t = s;
      bary[k] = 1 - u, bary[(k + 1) % 3] = u, bary[(k + 2) % 3] = 0;
    }
  }
  return best;
}

bool round_triangle_contact(const Vector3d& p, const Vector3d& q, double r, const Vector3d& v0, const Vector3d& v1,
                            const Vector3d& v2, TriangleContact& out, bool edges_geometric, bool outside_tissue) {
  Vector3d n = (v1 - v0).cross(v2 - v0);
  const double len = n.norm();
  if (!(len > 0)) return false;
  n /= len;
  double t;
  const double d2 = closest_segment_triangle(p, q, v0, v1, v2, t, out.bary);
  if (!(d2 < r * r)) return false;
  out.point = out.bary[0] * v0 + out.bary[1] * v1 + out.bary[2] * v2;
  const Vector3d y = p + t * (q - p);
  const double d = std::sqrt(d2), s = (y - out.point).dot(n);
  const bool interior = out.bary[0] > 0 && out.bary[1] > 0 && out.bary[2] > 0;
  // The capsule's side (not an end) nearest an edge or corner of the face:
  // the axis passes beside the face, not through it, whichever side of the
  // face's plane it lies on. The face rule there took a face touching a
  // pressed shaft (its plane tilted a little past the axis) for one the
  // probe came through and pushed it 1.3 cm, below the tip: 100 N and 366
  // inverted points under a 1 cm capsule pressed 2 cm. edges_geometric:
  // every round part so (under triangle rows the face rule pushed the small
  // triangles folded over a 5-8 mm sphere pressed 1.35 cm below it: 282-1103
  // inverted points). docs/benchmarks.md, "A probe's shaft".
  const bool beside = !interior && (edges_geometric || (t > 0 && t < 1));
  out.face_rule = false;
  if ((s > 0 || beside || outside_tissue) && d > 1e-9 * r && (!interior || outside_tissue)) {
    out.normal = (out.point - y) / d;  // off an edge or a corner: the geometric direction
    out.depth = r - d;
  } else if (s > 0 && d > 1e-9 * r) {
    out.normal = -n;  // over the face: the same, without dividing by a tiny d
    out.depth = r - s;
  } else {
    // To the tangent plane, parallel to the face, of the part of the tool
    // within r of the point: r - min (z - x) . n_out over the axis points z
    // within r of x (an interval, not empty since d < r). A sphere: r - s.
    // Over the whole axis (both ends) a shaft's far end decided: a face a
    // pressed 5 cm shaft pierced near its top, or whose plane its end cap
    // crossed beside a block's wall, was pushed down the shaft's length
    // (5-6 cm rows; 100 N and 366 inverted points under a 1 cm capsule
    // pressed 2 cm: docs/benchmarks.md, "A probe's shaft"). Bounded by 2r.
    const Vector3d e = q - p, w = p - out.point;
    const double L2 = e.squaredNorm();
    double t0 = 0.0, t1 = 0.0;
    if (L2 > 0) {  // |w + tau e| <= r
      const double b = w.dot(e), disc = std::max(0.0, b * b - L2 * (w.squaredNorm() - r * r)), root = std::sqrt(disc);
      t0 = std::clamp((-b - root) / L2, 0.0, 1.0);
      t1 = std::clamp((-b + root) / L2, 0.0, 1.0);
    }
    out.normal = -n;
    out.depth = r - std::min((w + t0 * e).dot(n), (w + t1 * e).dot(n));
    out.face_rule = true;
  }
  return out.depth > 0;
}

double round_exit_distance(const Vector3d& a, const Vector3d& b, double r, const Vector3d& x, const Vector3d& n) {
  double best = -std::numeric_limits<double>::infinity();
  // |w + s n| = r for an end sphere (w = x - centre), n a unit vector.
  for (const Vector3d* c : {&a, &b}) {
    const Vector3d w = x - *c;
    const double h = w.dot(n), disc = h * h - (w.squaredNorm() - r * r);
    if (disc >= 0) best = std::max(best, -h + std::sqrt(disc));
  }
  const Vector3d ab = b - a;
  const double L = ab.norm();
  if (!(L > 0)) return best;
  // The cylinder's side: |w_perp + s n_perp| = r, its axial coordinate in [0, L].
  const Vector3d e = ab / L, w = x - a;
  const Vector3d np = n - n.dot(e) * e, wp = w - w.dot(e) * e;
  const double A = np.squaredNorm(), B = wp.dot(np), disc = B * B - A * (wp.squaredNorm() - r * r);
  if (A > 0 && disc >= 0) {
    const double s = (-B + std::sqrt(disc)) / A, axial = (w + s * n).dot(e);
    if (axial >= 0 && axial <= L) best = std::max(best, s);
  }
  return best;
}

bool box_triangle_contact(const Vector3d& c, const Eigen::Matrix3d& R, const Vector3d& half, const Vector3d& v0,
                          const Vector3d& v1, const Vector3d& v2, TriangleContact& out) {
  Vector3d n = (v1 - v0).cross(v2 - v0);
  const double len = n.norm();
  if (!(len > 0)) return false;
  n /= len;
  // The box points over the triangle, in box coordinates y (b = c + R y), as
  // G y <= h: rows 0-5 the box faces (+-axis k), rows 6-8 the triangle's prism
  // along n (inward edge normals m_i = n x (v_i+1 - v_i), m_i . (b - v_i) >= 0).
  Eigen::Matrix<double, 9, 3> G = Eigen::Matrix<double, 9, 3>::Zero();
  double h[9];
  for (int k = 0; k < 3; ++k) {
    G(2 * k, k) = 1, G(2 * k + 1, k) = -1;
    h[2 * k] = h[2 * k + 1] = half[k];
  }
  const Vector3d* v[3] = {&v0, &v1, &v2};
  double scale = half.maxCoeff();
  for (int i = 0; i < 3; ++i) {
    Vector3d m = n.cross(*v[(i + 1) % 3] - *v[i]);
    const double ml = m.norm();
    if (!(ml > 0)) return false;
    m /= ml;
    G.row(6 + i) = -(R.transpose() * m).transpose();
    h[6 + i] = m.dot(c - *v[i]);
    scale = std::max(scale, (c - *v[i]).norm());
  }
  const Vector3d f = R.transpose() * n;
  const double tol = 1e-12 * scale;
  // Minimum of f . y at the vertices: every triple of independent constraints.
  double best = std::numeric_limits<double>::infinity();
  Vector3d ybest(0, 0, 0);
  for (int i = 0; i < 9; ++i)
    for (int j = i + 1; j < 9; ++j) {
      if (j < 6 && j == i + 1 && i % 2 == 0) continue;  // opposite faces of the box
      for (int k = j + 1; k < 9; ++k) {
        if (k < 6 && k == j + 1 && j % 2 == 0) continue;
        Eigen::Matrix3d M;
        M << G.row(i), G.row(j), G.row(k);
        const double det = M.determinant();
        if (std::abs(det) < 1e-12) continue;  // rows are unit vectors: (nearly) dependent planes
        const Vector3d y = M.inverse() * Vector3d(h[i], h[j], h[k]);
        if (((G * y).array() <= Eigen::Map<const Eigen::Array<double, 9, 1>>(h) + tol).all() && f.dot(y) < best) {
          best = f.dot(y);
          ybest = y;
        }
      }
    }
  if (!std::isfinite(best)) return false;  // no box point over the triangle
  out.depth = n.dot(v0) - (n.dot(c) + best);
  if (!(out.depth > 0)) return false;
  const Vector3d b = c + R * ybest;
  out.point = closest_point_on_triangle(b + out.depth * n, v0, v1, v2, out.bary);
  out.normal = -n;
  return true;
}

}  // namespace incise
