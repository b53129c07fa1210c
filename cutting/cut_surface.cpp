#include "cutting/cut_surface.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include <Eigen/Dense>

#include "cutting/exact_sign.h"
#include "engine/util/error.h"
#include "engine/util/file_io.h"

namespace incise {

namespace {
using V = Eigen::Vector3d;
V vec(const Vec3& a) { return V(a[0], a[1], a[2]); }
Vec3 arr(const V& a) { return {a[0], a[1], a[2]}; }

// Distance from x to triangle (a, b, c) (Ericson, closest point on triangle).
double triangle_distance(const V& x, const V& a, const V& b, const V& c) {
  const V ab = b - a, ac = c - a, ap = x - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return (x - a).norm();
  const V bp = x - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return (x - b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (x - (a + d1 / (d1 - d3) * ab)).norm();
  const V cp = x - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return (x - c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (x - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return (x - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  const double denom = 1.0 / (va + vb + vc);
  return (x - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
}

Facet triangle_facet(const V& a, const V& b, const V& c) {
  Facet f;
  f.v = {arr(a), arr(b), arr(c)};
  f.p = arr(a);
  const V n = (b - a).cross(c - a);
  f.n = arr(n.norm() > 0 ? V(n.normalized()) : n);
  return f;
}
}  // namespace

CutSurface::CutSurface(std::vector<Facet> facets, std::string name) : facets_(std::move(facets)), name_(std::move(name)) {
  // Facets of zero area (a degenerate polygon or sweep) carry no surface.
  facets_.erase(std::remove_if(facets_.begin(), facets_.end(),
                               [](const Facet& f) { return !(vec(f.n).norm() > 0.5); }),
                facets_.end());
}

int CutSurface::nearest_facet(const double x[3]) const {
  int best = 0;
  double bd = 1e300;
  const V xv(x[0], x[1], x[2]);
  for (size_t k = 0; k < facets_.size(); ++k) {
    const Facet& f = facets_[k];
    const double d = f.unbounded ? std::abs((xv - vec(f.p)).dot(vec(f.n)))
                                 : triangle_distance(xv, vec(f.v[0]), vec(f.v[1]), vec(f.v[2]));
    if (d < bd) {
      bd = d;
      best = static_cast<int>(k);
    }
  }
  return best;
}

// [preprint] eq. (72), against the nearest facet's plane.
CutSurface::Value CutSurface::value(const double x[3]) const {
  if (facets_.empty()) return {1.0, 1};
  const Facet& f = facets_[nearest_facet(x)];
  const double phi = (x[0] - f.p[0]) * f.n[0] + (x[1] - f.p[1]) * f.n[1] + (x[2] - f.p[2]) * f.n[2];
  const int s = exact_sign_dot_diff(x, f.p.data(), f.n.data());
  // phi is rounded, s is exact: keep them consistent (phi = 0 iff s = 0).
  double ph = s == 0 ? 0.0 : (phi * s > 0 ? phi : s * 1e-300);
  return {ph, s};
}

bool CutSurface::covers(const double y[3], double tol) const {
  const V x(y[0], y[1], y[2]);
  tol *= 1.0 + slack_;
  for (const Facet& f : facets_) {
    if (f.unbounded) return true;
    if (triangle_distance(x, vec(f.v[0]), vec(f.v[1]), vec(f.v[2])) <= tol) return true;
  }
  return false;
}

std::vector<Facet> read_triangle_surface(const std::string& path) {
  const bool stl = path.size() > 4 && (path.substr(path.size() - 4) == ".stl" || path.substr(path.size() - 4) == ".STL");
  const bool obj = path.size() > 4 && (path.substr(path.size() - 4) == ".obj" || path.substr(path.size() - 4) == ".OBJ");
  if (!stl && !obj) throw Error(path + ": unsupported cut surface format; allowed: .obj, .stl (ASCII)");
  std::istringstream is(read_input_file(path, kMaxTableBytes, "cut surface"));
  std::vector<Facet> facets;
  std::vector<V> verts;
  std::string line;
  std::vector<V> tri;
  for (int lineno = 1; std::getline(is, line); ++lineno) {
    std::istringstream ls(line);
    std::string key;
    if (!(ls >> key)) continue;
    auto fail = [&](const std::string& what) { throw Error(path + ":" + std::to_string(lineno) + ": " + what); };
    if (obj && key == "v") {
      double a, b, c;
      if (!(ls >> a >> b >> c) || !std::isfinite(a) || !std::isfinite(b) || !std::isfinite(c))
        fail("vertex needs three finite coordinates");
      verts.emplace_back(a, b, c);
    } else if (obj && key == "f") {
      std::vector<int> ids;
      std::string tok;
      while (ls >> tok) {
        const int id = std::atoi(tok.substr(0, tok.find('/')).c_str());
        const int idx = id < 0 ? static_cast<int>(verts.size()) + id : id - 1;
        if (idx < 0 || idx >= static_cast<int>(verts.size()))
          fail("face references vertex " + tok + ", but only " + std::to_string(verts.size()) + " are defined");
        ids.push_back(idx);
      }
      if (ids.size() < 3) fail("face needs at least 3 vertices");
      for (size_t k = 1; k + 1 < ids.size(); ++k) facets.push_back(triangle_facet(verts[ids[0]], verts[ids[k]], verts[ids[k + 1]]));
    } else if (stl && key == "vertex") {
      double a, b, c;
      if (!(ls >> a >> b >> c) || !std::isfinite(a) || !std::isfinite(b) || !std::isfinite(c))
        fail("vertex needs three finite coordinates");
      tri.emplace_back(a, b, c);
      if (tri.size() == 3) {
        facets.push_back(triangle_facet(tri[0], tri[1], tri[2]));
        tri.clear();
      }
    } else if (stl && key == "solid" && lineno == 1) {
      continue;
    }
  }
  if (facets.empty()) throw Error(path + ": no triangles found");
  return facets;
}

std::unique_ptr<CutSurface> make_cut_surface(const CutSpec& c, double t) {
  std::vector<Facet> facets;
  switch (c.type) {
    case CutSpec::Type::Plane: {
      Facet f;
      f.unbounded = true;
      f.p = c.point;
      f.n = c.normal;
      facets.push_back(f);
      break;
    }
    case CutSpec::Type::Polygon: {
      // Newell normal and centroid: one plane for all fan triangles, so the
      // exact sign is taken against the same plane everywhere.
      V n = V::Zero(), cen = V::Zero();
      const size_t np = c.points.size();
      for (size_t k = 0; k < np; ++k) {
        const V a = vec(c.points[k]), b = vec(c.points[(k + 1) % np]);
        n += V((a.y() - b.y()) * (a.z() + b.z()), (a.z() - b.z()) * (a.x() + b.x()), (a.x() - b.x()) * (a.y() + b.y()));
        cen += a;
      }
      cen /= static_cast<double>(np);
      if (!(n.norm() > 0)) throw Error(c.json_path + ": polygon has zero area");
      n.normalize();
      double size = 0;
      for (const auto& q : c.points) size = std::max(size, (vec(q) - cen).norm());
      for (size_t k = 0; k < np; ++k) {
        const double off = std::abs((vec(c.points[k]) - cen).dot(n));
        if (off > 1e-6 * size)
          throw Error(c.json_path + ".points[" + std::to_string(k) + "]: polygon is not planar (off its plane by " +
                      std::to_string(off) + ")");
        // The fan from the centroid covers the polygon only when it is convex.
        const V a = vec(c.points[k]), b = vec(c.points[(k + 1) % np]), d = vec(c.points[(k + 2) % np]);
        if ((b - a).cross(d - b).dot(n) < -1e-12 * size * size)
          throw Error(c.json_path + ".points: polygon must be convex; the turn at points[" +
                      std::to_string((k + 1) % np) + "] goes the other way (split a concave cut into convex polygons)");
      }
      for (size_t k = 0; k < np; ++k) {
        Facet f;
        f.v = {arr(cen), c.points[k], c.points[(k + 1) % np]};
        f.p = arr(cen);
        f.n = arr(n);
        facets.push_back(f);
      }
      break;
    }
    case CutSpec::Type::Mesh:
      facets = read_triangle_surface(c.file);
      break;
    case CutSpec::Type::Swept: {
      const double s = c.duration > 0 ? std::clamp((t - c.at_time) / c.duration, 0.0, 1.0) : 1.0;
      if (s <= 0.0) return nullptr;
      const V a0 = vec(c.edge_start[0]), b0 = vec(c.edge_start[1]);
      const V a1 = a0 + s * (vec(c.edge_end[0]) - a0), b1 = b0 + s * (vec(c.edge_end[1]) - b0);
      // The swept quad (a0, b0, b1, a1) as two triangles. When the whole
      // sweep is planar (the blade moves within its own plane, the usual
      // incision) both share the plane of the full sweep, computed from
      // vectors that do not depend on the progress s: the level sets, and so
      // the layout, then stay bit-identical while the blade advances inside
      // an element, and nothing is rebuilt.
      Facet f1 = triangle_facet(a0, b0, b1), f2 = triangle_facet(a0, b1, a1);
      const V aE = vec(c.edge_end[0]), bE = vec(c.edge_end[1]);
      const V nf = (b0 - a0).cross(bE - b0);
      const double len = nf.norm(), scale = (b0 - a0).norm() * std::max((bE - b0).norm(), (aE - a0).norm());
      const bool planar = len > 1e-9 * scale && std::abs((aE - a0).dot(nf)) <= 1e-9 * len * scale;
      if (planar) {
        for (Facet* f : {&f1, &f2}) {
          f->p = arr(a0);
          f->n = arr(nf / len);
        }
      }
      facets = {f1, f2};
      break;
    }
  }
  auto surf = std::make_unique<CutSurface>(std::move(facets), c.json_path);
  if (surf->facets().empty()) return nullptr;
  return surf;
}

std::unique_ptr<CutSurface> make_swept_surface(const std::vector<double>& swept, const std::vector<double>& swept_tool,
                                               int tool, const std::string& name) {
  std::vector<Facet> facets;
  for (size_t t = 0; t < swept_tool.size(); ++t) {
    if (static_cast<int>(swept_tool[t]) != tool) continue;
    const double* v = &swept[9 * t];
    facets.push_back(triangle_facet(V(v[0], v[1], v[2]), V(v[3], v[4], v[5]), V(v[6], v[7], v[8])));
  }
  auto surf = std::make_unique<CutSurface>(std::move(facets), name);
  if (surf->facets().empty()) return nullptr;
  // The layout's tolerance is 1e-9 of the element size: reach 1e-2 of it.
  surf->set_cover_slack(1e7);
  return surf;
}

}  // namespace incise
