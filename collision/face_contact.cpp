#include "collision/face_contact.h"

#include <algorithm>
#include <cmath>

#include "collision/narrowphase.h"

namespace incise {
namespace {

constexpr int kSubdivide = 4;  // sub-triangles per triangle edge: 16 samples per triangle

// w = depth^3 (face_contact.h, p = 3). Measured on organ_instruments and a
// coarse block (2.5 cm faces under a 1 cm probe): p = 1 and 2 settle
// smoothest but let the face's deepest point in by 1.3 and 0.9 mm; 4 and
// more start to chatter again on the coarse faces (2-10% frame to frame).
double weight(double depth) { return depth * depth * depth; }

}  // namespace

void weight_round_face_contact(const TissueSurface& s, const ToolPart& part, const double* u, TissueContact& c) {
  if (part.kind == ToolPart::Kind::Box || s.nface <= 0) return;
  const double r = part.radius;
  const int tpf = s.ntri() / s.nface, k = kSubdivide;
  double W = 0.0, rst[3] = {0, 0, 0};
  Eigen::Vector3d n_sum(0, 0, 0), n_face(0, 0, 0);  // n_face: the face's outward normal times twice its area
  const auto add = [&](double w, const Eigen::Vector3d& g, double d, const int* tv, const double b[3]) {
    W += w;
    if (d > 0) n_sum += (w / d) * g;
    for (int q = 0; q < 3; ++q)
      rst[q] += w * (b[0] * s.vert_rst[3 * tv[0] + q] + b[1] * s.vert_rst[3 * tv[1] + q] + b[2] * s.vert_rst[3 * tv[2] + q]);
  };
  for (int t = c.face * tpf; t < (c.face + 1) * tpf; ++t) {  // a face's triangles are contiguous
    const int* tv = &s.tri[3 * static_cast<size_t>(t)];
    Eigen::Vector3d v[3];
    for (int j = 0; j < 3; ++j) v[j] = Eigen::Vector3d(s.x[3 * tv[j]], s.x[3 * tv[j] + 1], s.x[3 * tv[j] + 2]);
    n_face += (v[1] - v[0]).cross(v[2] - v[0]);
    const double area = 0.5 * (v[1] - v[0]).cross(v[2] - v[0]).norm() / (k * k);  // of one sub-triangle
    // The k^2 sub-triangles' centroids: upward ones at barycentric
    // ((i + 1/3) / k, (j + 1/3) / k), downward ones at ((i + 2/3) / k, (j + 2/3) / k).
    double deepest = 0.0;  // of this triangle's samples
    for (int i = 0; i < k; ++i)
      for (int j = 0; i + j < k; ++j)
        for (int down = 0; down < 2 && !(down && i + j > k - 2); ++down) {
          const double shift = down ? 2.0 / 3.0 : 1.0 / 3.0;
          const double b[3] = {1.0 - (i + shift) / k - (j + shift) / k, (i + shift) / k, (j + shift) / k};
          const Eigen::Vector3d x = b[0] * v[0] + b[1] * v[1] + b[2] * v[2];
          const Eigen::Vector3d g = x - nearest_on_segment(part.a, part.b, x);
          const double d = g.norm(), depth = r - d;
          if (!(depth > 0)) continue;
          deepest = std::max(deepest, depth);
          add(area * weight(depth), g, d, tv, b);
        }
    // The triangle's own deepest point (continuous in the tool's pose: the
    // nearest point of a triangle, not the argmax over a face's triangles,
    // which jumps) for what the samples miss: a touch between samples.
    double b[3], tt;
    const double d2 = closest_segment_triangle(part.a, part.b, v[0], v[1], v[2], tt, b);
    const double d = std::sqrt(d2), depth = r - d;
    if (!(depth > 0)) continue;
    const Eigen::Vector3d x = b[0] * v[0] + b[1] * v[1] + b[2] * v[2];
    add(area * std::max(0.0, weight(depth) - weight(deepest)), x - (part.a + tt * (part.b - part.a)), d, tv, b);
  }
  if (!(W > 0)) return;
  for (int q = 0; q < 3; ++q) rst[q] /= W;
  // A face's vertices all lie in one element and piece (TissueSurface), so
  // rst_f is a point of that element's face.
  const PointWeights pw = s.point_weights(c.elem, c.piece, rst, c.side);
  double X[3], xm[3];
  s.reference_position(c.elem, rst, X);
  point_position(pw, X, u, xm);
  const Eigen::Vector3d x(xm[0], xm[1], xm[2]);
  const Eigen::Vector3d g = x - nearest_on_segment(part.a, part.b, x);
  const double d = g.norm();
  // The axis on the far side of the point, seen along the samples' normals
  // or behind the face's plane (a probe pushed in deeper than the face: a
  // 5 mm probe jabbed 1 cm a frame): the geometric direction would pull the
  // tissue out through the tool (the rows pushed the face outward, the force
  // fell to 0.03 N and the probe ended inside at 0 N); the narrowphase's
  // face rule (-n_out) stays.
  if (!(d > 1e-9 * r) || !(g.dot(n_sum) > 0) || !(g.dot(n_face) < 0)) return;
  for (int q = 0; q < 3; ++q) {
    c.rst[q] = rst[q];
    c.point[q] = xm[q];
    c.normal[q] = g[q] / d;
  }
  c.depth = r - d;
  c.weights = pw;
}

}  // namespace incise
