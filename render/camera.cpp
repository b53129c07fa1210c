#include "render/camera.h"

#include <algorithm>
#include <cmath>

namespace incise {
namespace {

Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 add(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3 scale(const Vec3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3 unit(const Vec3& a) {
  const double l = std::sqrt(dot(a, a));
  return l > 0 ? scale(a, 1.0 / l) : a;
}

// Right and true-up axes of a view; up is replaced when parallel to the view.
void view_axes(const Camera& c, Vec3& fwd, Vec3& right, Vec3& up) {
  fwd = unit(sub(c.target, c.eye));
  Vec3 u = c.up;
  if (std::sqrt(dot(cross(fwd, unit(u)), cross(fwd, unit(u)))) < 1e-6)
    u = std::fabs(fwd[2]) < 0.9 ? Vec3{0, 0, 1} : Vec3{0, 1, 0};
  right = unit(cross(fwd, u));
  up = cross(right, fwd);
}

}  // namespace

Camera frame_camera(const RenderSettings& r, const Vec3& lo, const Vec3& hi) {
  Camera c;
  c.fov_deg = r.fov_deg;
  c.up = r.camera_up;
  const Vec3 centre = scale(add(lo, hi), 0.5);
  const double radius = std::max(0.5 * std::sqrt(dot(sub(hi, lo), sub(hi, lo))), 1e-9);
  c.target = r.camera_target ? *r.camera_target : centre;
  if (r.camera_position) {
    c.eye = *r.camera_position;
  } else {
    // Fit the bounding sphere into the narrower of the two fields of view.
    const double aspect = static_cast<double>(r.width) / r.height;
    const double half_v = 0.5 * r.fov_deg * M_PI / 180.0;
    const double half = std::min(half_v, std::atan(std::tan(half_v) * aspect));
    const double dist = 1.05 * radius / std::sin(half);
    Vec3 dir = unit(Vec3{1.0, -1.6, 0.9});
    if (std::fabs(dot(dir, unit(c.up))) > 0.99) dir = unit(Vec3{1.0, -1.6, 0.0});
    c.eye = add(c.target, scale(dir, dist));
  }
  const double dist = std::sqrt(dot(sub(c.eye, centre), sub(c.eye, centre)));
  c.near = std::max(dist - 3.0 * radius, 1e-3 * (dist + radius));
  c.far = dist + 10.0 * radius;  // room for instruments beyond the tissue
  Vec3 fwd, right, up;
  view_axes(c, fwd, right, up);
  // Default light from above-left of the camera, travelling into the scene.
  c.light = r.light_direction ? unit(*r.light_direction) : unit(add(add(fwd, scale(up, -0.6)), scale(right, 0.4)));
  return c;
}

std::array<float, 16> view_projection(const Camera& c, double aspect) {
  Vec3 f, s, u;
  view_axes(c, f, s, u);
  // View: rows s, u, -f; translation -R eye.
  double V[16] = {s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0,
                  -dot(s, c.eye), -dot(u, c.eye), dot(f, c.eye), 1};
  const double t = 1.0 / std::tan(0.5 * c.fov_deg * M_PI / 180.0);
  const double n = c.near, fa = c.far;
  double P[16] = {t / aspect, 0, 0, 0, 0, t, 0, 0, 0, 0, (fa + n) / (n - fa), -1, 0, 0, 2 * fa * n / (n - fa), 0};
  std::array<float, 16> out{};
  for (int col = 0; col < 4; ++col)
    for (int row = 0; row < 4; ++row) {
      double acc = 0;
      for (int k = 0; k < 4; ++k) acc += P[k * 4 + row] * V[col * 4 + k];
      out[col * 4 + row] = static_cast<float>(acc);
    }
  return out;
}

}  // namespace incise
