#include <cmath>

#include "render/instrument_shape.h"

namespace incise {
namespace {

constexpr int kAround = 24;  // segments around an axis
constexpr int kCapRings = 6; // latitude rings per capsule cap

struct Emitter {
  const InstrumentShape& s;
  std::vector<float>& pos;
  std::vector<float>& nrm;
  // One vertex: local point p and local normal n, mapped by the pose.
  void vertex(const double p[3], const double n[3]) {
    const auto& M = s.pose;
    double wn[3], len = 0;
    for (int r = 0; r < 3; ++r) {
      pos.push_back(static_cast<float>(M[r] * p[0] + M[4 + r] * p[1] + M[8 + r] * p[2] + M[12 + r]));
      wn[r] = M[r] * n[0] + M[4 + r] * n[1] + M[8 + r] * n[2];  // rigid pose: the rotation maps normals
      len += wn[r] * wn[r];
    }
    len = len > 0 ? std::sqrt(len) : 1.0;
    for (double c : wn) nrm.push_back(static_cast<float>(c / len));
  }
  void tri(const double* a, const double* na, const double* b, const double* nb, const double* c, const double* nc) {
    vertex(a, na), vertex(b, nb), vertex(c, nc);
  }
};

// Point and normal on a surface of revolution around z: radius r(t) at height z(t).
void ring_point(double r, double z, double nr, double nz, int k, double p[3], double n[3]) {
  const double a = 2.0 * M_PI * k / kAround;
  p[0] = r * std::cos(a), p[1] = r * std::sin(a), p[2] = z;
  n[0] = nr * std::cos(a), n[1] = nr * std::sin(a), n[2] = nz;
}

// Band between two rings (r0, z0, normal (nr0, nz0)) -> (r1, z1, ...), z increasing.
void band(Emitter& e, double r0, double z0, double nr0, double nz0, double r1, double z1, double nr1, double nz1) {
  for (int k = 0; k < kAround; ++k) {
    double p00[3], n00[3], p01[3], n01[3], p10[3], n10[3], p11[3], n11[3];
    ring_point(r0, z0, nr0, nz0, k, p00, n00);
    ring_point(r0, z0, nr0, nz0, k + 1, p01, n01);
    ring_point(r1, z1, nr1, nz1, k, p10, n10);
    ring_point(r1, z1, nr1, nz1, k + 1, p11, n11);
    if (r0 > 0) e.tri(p00, n00, p01, n01, p11, n11);
    if (r1 > 0) e.tri(p00, n00, p11, n11, p10, n10);
  }
}

}  // namespace

void instrument_triangles(const InstrumentShape& s, std::vector<float>& pos, std::vector<float>& nrm) {
  Emitter e{s, pos, nrm};
  const double r = s.radius, h = 0.5 * s.length;
  switch (s.kind) {
    case InstrumentShape::Kind::Cylinder:
      band(e, r, -h, 1, 0, r, h, 1, 0);
      band(e, 0, -h, 0, -1, r, -h, 0, -1);  // bottom disc; winding flips with the normal below
      band(e, r, h, 0, 1, 0, h, 0, 1);      // top disc
      break;
    case InstrumentShape::Kind::Capsule:
      band(e, r, -h, 1, 0, r, h, 1, 0);
      for (int i = 0; i < kCapRings; ++i) {  // caps: latitude phi from the equator to the pole
        const double a0 = 0.5 * M_PI * i / kCapRings, a1 = 0.5 * M_PI * (i + 1) / kCapRings;
        band(e, r * std::cos(a0), h + r * std::sin(a0), std::cos(a0), std::sin(a0), r * std::cos(a1),
             h + r * std::sin(a1), std::cos(a1), std::sin(a1));
        band(e, r * std::cos(a1), -h - r * std::sin(a1), std::cos(a1), -std::sin(a1), r * std::cos(a0),
             -h - r * std::sin(a0), std::cos(a0), -std::sin(a0));
      }
      break;
    case InstrumentShape::Kind::Box: {
      const Vec3& he = s.half_extents;
      for (int axis = 0; axis < 3; ++axis)
        for (int sign = -1; sign <= 1; sign += 2) {
          const int u = (axis + 1) % 3, v = (axis + 2) % 3;  // (u, v, axis) right-handed
          double n[3] = {0, 0, 0}, c[4][3];
          n[axis] = sign;
          const double uv[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
          for (int k = 0; k < 4; ++k) {
            c[k][axis] = sign * he[axis];
            c[k][u] = uv[k][0] * he[u];
            c[k][v] = uv[k][1] * sign * he[v];  // mirrored on the negative side keeps the winding outward
          }
          e.tri(c[0], n, c[1], n, c[2], n);
          e.tri(c[0], n, c[2], n, c[3], n);
        }
      break;
    }
  }
}

}  // namespace incise
