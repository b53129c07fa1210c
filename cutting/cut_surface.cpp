#include "cutting/cut_surface.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <functional>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <utility>

#include <Eigen/Dense>
#include <unsupported/Eigen/BVH>

#include "cutting/exact_sign.h"
#include "engine/util/error.h"
#include "engine/util/file_io.h"

namespace incise {

namespace {
using V = Eigen::Vector3d;
V vec(const Vec3& a) { return V(a[0], a[1], a[2]); }
Vec3 arr(const V& a) { return {a[0], a[1], a[2]}; }

// Closest point of triangle (a, b, c) to x (Ericson, "Real-Time Collision
// Detection", 5.1.5) and its feature: 0 the face, 1 + j corner j, 4 + j
// edge j (from corner j to corner j + 1 mod 3).
V closest_on_triangle(const V& x, const V& a, const V& b, const V& c, int* feature) {
  const V ab = b - a, ac = c - a, ap = x - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return *feature = 1, a;
  const V bp = x - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return *feature = 2, b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return *feature = 4, V(a + d1 / (d1 - d3) * ab);
  const V cp = x - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return *feature = 3, c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return *feature = 6, V(a + d2 / (d2 - d6) * ac);
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return *feature = 5, V(b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b));
  const double denom = 1.0 / (va + vb + vc);
  return *feature = 0, V(a + ab * (vb * denom) + ac * (vc * denom));
}

// Exact power-of-two scaling: 2^-e with e the exponent of m (m > 0, finite),
// so values of any magnitude land near 1 without rounding. e is kept above
// -1000: 2^1074 (a subnormal m) would overflow; such values land near 2^-74.
double unit_scale(double m) { return std::ldexp(1.0, -std::max(std::ilogb(m), -1000)); }

// Unnormalized normal (b - a) x (c - a) computed in scaled coordinates: the
// corners are scaled so their differences cannot overflow, the differences so
// the cross product cannot underflow or overflow. Zero for collinear corners.
// *rel: |normal| / (longest edge)^2 in the scaled units (0 for zero area).
V scaled_normal(const V& a, const V& b, const V& c, double* rel = nullptr) {
  if (rel) *rel = 0;
  const double m = std::max({a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff(), c.cwiseAbs().maxCoeff()});
  if (!(m > 0) || !std::isfinite(m)) return V::Zero();
  const double s = unit_scale(m);
  V ab = b * s - a * s, ac = c * s - a * s;
  const double d = std::max(ab.cwiseAbs().maxCoeff(), ac.cwiseAbs().maxCoeff());
  if (!(d > 0)) return V::Zero();
  const double t = unit_scale(d);
  ab *= t, ac *= t;
  const V n = ab.cross(ac);
  if (rel) *rel = n.norm() / std::max({ab.squaredNorm(), ac.squaredNorm(), (ac - ab).squaredNorm()});
  return n;
}

Facet triangle_facet(const V& a, const V& b, const V& c) {
  Facet f;
  f.v = {arr(a), arr(b), arr(c)};
  f.p = arr(a);
  const V n = scaled_normal(a, b, c);
  f.n = arr(n.norm() > 0 ? V(n.normalized()) : V::Zero());
  return f;
}

// Relative area below which a cut facet counts as degenerate: |n| / (longest
// edge)^2 = 2 area / edge^2, i.e. its smallest angle is below about 1e-12 rad.
constexpr double kMinFacetShape = 1e-12;

}  // namespace

bool degenerate_triangle(const double* a, const double* b, const double* c) {
  double rel = 0;
  scaled_normal(V(a[0], a[1], a[2]), V(b[0], b[1], b[2]), V(c[0], c[1], c[2]), &rel);
  return !(rel > kMinFacetShape);
}

namespace {

// A planar polygon validated as a cut (simple, convex, planar, positive area):
// its centroid and unit normal. Computed in scaled coordinates so a tiny or a
// huge polygon gives the same answer as one of unit size. fail(k, what)
// reports a problem at point k (-1: the polygon as a whole) and does not
// return; point(k) names point k inside a message ("points[3]").
template <class Fail, class Point>
void polygon_plane(const std::vector<V>& pts, V& cen_out, V& n_out, Fail fail, Point point) {
  const size_t np = pts.size();
  double m = 0;
  for (const V& q : pts) m = std::max(m, q.cwiseAbs().maxCoeff());
  if (!(m > 0)) fail(-1, "polygon has zero area (all its points are at the origin)");
  const double s = unit_scale(m);
  V cen = V::Zero();
  for (const V& q : pts) cen += q * s;
  cen /= static_cast<double>(np);
  std::vector<V> d(np);
  double dm = 0;
  for (size_t k = 0; k < np; ++k) dm = std::max(dm, (d[k] = pts[k] * s - cen).cwiseAbs().maxCoeff());
  if (!(dm > 0)) fail(-1, "polygon has zero area (all its points coincide)");
  const double t = unit_scale(dm);
  for (V& q : d) q *= t;
  for (size_t k = 0; k < np; ++k)
    if (d[k] == d[(k + 1) % np])
      fail(-1, "polygon repeats a point: " + point(k) + " and the next one coincide; remove one");
  V n = V::Zero();  // Newell normal
  for (size_t k = 0; k < np; ++k) {
    const V& a = d[k];
    const V& b = d[(k + 1) % np];
    n += V((a.y() - b.y()) * (a.z() + b.z()), (a.z() - b.z()) * (a.x() + b.x()), (a.x() - b.x()) * (a.y() + b.y()));
  }
  double size = 0;
  for (const V& q : d) size = std::max(size, q.norm());
  if (!(n.norm() > kMinFacetShape * size * size)) fail(-1, "polygon has zero area (its points are collinear)");
  n.normalize();
  for (size_t k = 0; k < np; ++k) {
    const double off = std::abs(d[k].dot(n));
    if (off > 1e-6 * size) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.3g of its size", off / size);
      fail(static_cast<int>(k), std::string("polygon is not planar (off its plane by ") + buf + ")");
    }
    // The fan from the centroid covers the polygon only when it is convex.
    const V& a = d[k];
    const V& b = d[(k + 1) % np];
    const V& c = d[(k + 2) % np];
    if ((b - a).cross(c - b).dot(n) < -1e-12 * size * size)
      fail(-1, "polygon must be convex; the turn at " + point((k + 1) % np) +
                   " goes the other way (split a concave cut into convex polygons)");
  }
  // Convex turns everywhere and simple only when it winds once around its
  // centroid (a pentagram turns one way at every point but winds twice).
  const V u = (std::abs(n.x()) < 0.9 ? V(1, 0, 0) : V(0, 1, 0)).cross(n).normalized(), w = n.cross(u);
  double turn = 0;
  for (size_t k = 0; k < np; ++k) {
    const V& a = d[k];
    const V& b = d[(k + 1) % np];
    turn += std::atan2(a.dot(u) * b.dot(w) - a.dot(w) * b.dot(u), a.dot(u) * b.dot(u) + a.dot(w) * b.dot(w));
  }
  const double windings = std::abs(turn) / (2 * 3.14159265358979323846);
  if (!(std::abs(windings - 1.0) < 0.25)) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0f", windings);
    fail(-1, std::string("polygon is not simple: its edges cross (it winds ") + buf + " times around its centre)");
  }
  cen_out = cen / s;
  n_out = n;
}

// Largest OBJ face this reader accepts (fan-triangulated; docs/scene-format.md).
constexpr size_t kMaxObjFaceVertices = 16;
}  // namespace

struct CutSurface::FacetTree {
  using Bvh = Eigen::KdBVH<double, 3, int>;
  Bvh bvh;

  // Depth first over the tree, on a fixed stack (Eigen's BVMinimize and
  // BVIntersect allocate a queue per query: the layout asks one per corner
  // node, and on the liver demo's few-facet strokes they cost more than the
  // scan saved). The tree is balanced (median splits): its depth is about
  // log2(facets) and the stack holds at most one entry a level more, so 128
  // entries never fill (the `top < kStack` tests only guard the array).
  static constexpr int kStack = 128;

  // The least `bound(box)` first; a box is opened while its bound is below
  // best() (which the objects taken lower).
  template <class Bound, class Best, class Take>
  void nearest(const Bound& bound, const Best& best, const Take& take) const {
    int node[kStack];
    double low[kStack];
    int top = 0;
    node[top] = bvh.getRootIndex();
    low[top++] = -std::numeric_limits<double>::infinity();
    while (top > 0) {
      --top;
      if (!(low[top] < best())) continue;
      Bvh::VolumeIterator vb = nullptr, ve = nullptr;
      Bvh::ObjectIterator ob = nullptr, oe = nullptr;
      bvh.getChildren(node[top], vb, ve, ob, oe);
      for (; ob != oe; ++ob) take(*ob);
      const int nv = static_cast<int>(ve - vb);
      double b[2];
      for (int i = 0; i < nv; ++i) b[i] = bound(bvh.getVolume(vb[i]));
      // farther first, so that the nearer is opened next
      const int first = nv == 2 && b[1] > b[0] ? 1 : 0;
      for (int j = 0; j < nv; ++j) {
        const int i = nv == 2 ? (j == 0 ? first : 1 - first) : j;
        if (b[i] < best() && top < kStack) {
          node[top] = vb[i];
          low[top++] = b[i];
        }
      }
    }
  }

  // Whether take(facet) holds for a facet in a box that `open` admits.
  template <class Open, class Take>
  bool any(const Open& open, const Take& take) const {
    int node[kStack];
    int top = 0;
    node[top++] = bvh.getRootIndex();
    while (top > 0) {
      Bvh::VolumeIterator vb = nullptr, ve = nullptr;
      Bvh::ObjectIterator ob = nullptr, oe = nullptr;
      bvh.getChildren(node[--top], vb, ve, ob, oe);
      for (; ob != oe; ++ob)
        if (take(*ob)) return true;
      for (; vb != ve; ++vb)
        if (open(bvh.getVolume(*vb)) && top < kStack) node[top++] = *vb;
    }
    return false;
  }
};

CutSurface::CutSurface(std::vector<Facet> facets, std::string name) : facets_(std::move(facets)), name_(std::move(name)) {
  // Facets of zero area (a degenerate polygon or sweep) carry no surface.
  facets_.erase(std::remove_if(facets_.begin(), facets_.end(),
                               [](const Facet& f) { return !(vec(f.n).norm() > 0.5); }),
                facets_.end());
  centre_.assign(facets_.size(), Vec3{});
  radius_.assign(facets_.size(), std::numeric_limits<double>::infinity());
  for (size_t k = 0; k < facets_.size(); ++k) {
    if (facets_[k].unbounded) continue;
    const V c = (vec(facets_[k].v[0]) + vec(facets_[k].v[1]) + vec(facets_[k].v[2])) / 3.0;
    double r = 0;
    for (const Vec3& v : facets_[k].v) r = std::max(r, (vec(v) - c).norm());
    centre_[k] = arr(c);
    radius_[k] = r;
  }
  std::vector<std::pair<std::array<Vec3, 2>, int>> edges;  // (sorted end points, 3 facet + edge)
  for (size_t k = 0; k < facets_.size(); ++k)
    for (int j = 0; j < 3 && !facets_[k].unbounded; ++j) {
      std::array<Vec3, 2> e = {facets_[k].v[j], facets_[k].v[(j + 1) % 3]};
      if (e[1] < e[0]) std::swap(e[0], e[1]);
      edges.push_back({e, static_cast<int>(3 * k + j)});
    }
  std::sort(edges.begin(), edges.end());
  // Pseudonormals (value()): an edge's is the sum of the normals of the
  // facets that share it, a corner's the sum over the facets around it of
  // normal times angle there. Matched by exact coordinates, as the boundary
  // below; the facets of one patch share one winding (orient_consistently).
  // Sorted vectors, not maps: a scalpel's surface is rebuilt every cut frame.
  edge_normal_.assign(facets_.size(), {});
  corner_normal_.assign(facets_.size(), {});
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    V sum = V::Zero();
    for (; j < edges.size() && edges[j].first == edges[i].first; ++j) sum += vec(facets_[edges[j].second / 3].n);
    for (size_t q = i; q < j; ++q) edge_normal_[edges[q].second / 3][edges[q].second % 3] = arr(sum);
    i = j;
  }
  {
    std::vector<std::pair<Vec3, int>> corners;  // (position, 3 facet + corner)
    for (size_t k = 0; k < facets_.size(); ++k)
      for (int j = 0; j < 3 && !facets_[k].unbounded; ++j) corners.push_back({facets_[k].v[j], static_cast<int>(3 * k + j)});
    std::sort(corners.begin(), corners.end());
    for (size_t i = 0; i < corners.size();) {
      size_t j = i;
      V sum = V::Zero();
      for (; j < corners.size() && corners[j].first == corners[i].first; ++j) {
        const Facet& f = facets_[corners[j].second / 3];
        const int c = corners[j].second % 3;
        const V p = vec(f.v[c]), u = vec(f.v[(c + 1) % 3]) - p, w = vec(f.v[(c + 2) % 3]) - p;
        sum += std::atan2(u.cross(w).norm(), u.dot(w)) * vec(f.n);
      }
      for (size_t q = i; q < j; ++q) corner_normal_[corners[q].second / 3][corners[q].second % 3] = arr(sum);
      i = j;
    }
  }
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j].first == edges[i].first) ++j;
    if (j == i + 1) {
      const Facet& f = facets_[edges[i].second / 3];
      const V a = vec(edges[i].first[0]), b = vec(edges[i].first[1]);
      V m = (b - a).cross(vec(f.n));
      V c = vec(f.v[0]) + vec(f.v[1]) + vec(f.v[2]);
      c /= 3.0;
      if (m.norm() > 0) {
        m.normalize();
        if (m.dot(c - a) > 0) m = -m;
        boundary_.push_back({arr(a), arr(b), arr(m)});
      }
    }
    i = j;
  }
  const bool plane = std::any_of(facets_.begin(), facets_.end(), [](const Facet& f) { return f.unbounded; });
  if (!plane && facets_.size() >= kTreeFacets) {
    std::vector<int> ids(facets_.size());
    std::vector<Eigen::AlignedBox3d> boxes(facets_.size());
    for (size_t k = 0; k < facets_.size(); ++k) {
      ids[k] = static_cast<int>(k);
      for (const Vec3& v : facets_[k].v) boxes[k].extend(vec(v));  // exact: min and max of the corners
    }
    tree_ = std::make_shared<const FacetTree>(FacetTree{FacetTree::Bvh(ids.begin(), ids.end(), boxes.begin(), boxes.end())});
  }
}

double CutSurface::front_distance(const double x[3]) const {
  const V xv(x[0], x[1], x[2]);
  double best = 1e300, psi = 1e300;
  for (const Edge& e : boundary_) {
    const V a = vec(e.a), ab = vec(e.b) - a;
    const double t = std::clamp((xv - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    const double d = (xv - (a + t * ab)).norm();
    if (d < best) {
      best = d;
      psi = (xv - a).dot(vec(e.m));
    }
  }
  return psi;
}

namespace {
// Far above the roundoff of a box's or a triangle's distance to x (a few
// ulps of the coordinates involved), as in lower_bound: a box the queries
// skip holds no facet they would have taken.
// (4e-12: it covers the slack that triangle_distance leaves a closest point
// outside the facet's box, below.)
double box_margin(const Eigen::AlignedBox3d& b, const V& x) {
  return 4e-12 * (x.cwiseAbs().maxCoeff() + b.min().cwiseAbs().maxCoeff() + b.max().cwiseAbs().maxCoeff());
}
}  // namespace

// The distance from x to facet k's triangle, with its closest point kept in
// the facet's box (to 1e-12 of its coordinates) and bounding sphere (to 1e-9
// of its radius). A true closest point lies in both; roundoff leaves ulps,
// which this does not touch. But on a sliver (fuzzed polygons fan over
// coordinates to 1e180) cancellation in the barycentric formula can put it
// outside both, nearer to x than any point of the triangle; a facet the
// bounds skip (lower_bound, the tree's boxes) would then be one a scan
// takes. Not seen in a run: found by reading the bounds. Kept in both, the
// distance is never below either bound, so every query takes what the scan
// over all facets takes.
double CutSurface::triangle_distance(size_t k, const double x[3]) const {
  const Facet& f = facets_[k];
  const V xv(x[0], x[1], x[2]), a = vec(f.v[0]), b = vec(f.v[1]), c = vec(f.v[2]);
  int feature = 0;
  V p = closest_on_triangle(xv, a, b, c, &feature);
  const V lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
  const double slack = 1e-12 * (lo.cwiseAbs().maxCoeff() + hi.cwiseAbs().maxCoeff());
  if ((p.array() < lo.array() - slack).any() || (p.array() > hi.array() + slack).any()) p = p.cwiseMax(lo).cwiseMin(hi);
  const V o = vec(centre_[k]);
  const double r = radius_[k], po = (p - o).norm();
  if (po > r * (1.0 + 1e-9)) p = o + (p - o) * (r / po);  // toward the centre: stays in the box
  return (xv - p).norm();
}

double CutSurface::facet_distance(size_t k, const double x[3]) const {
  const Facet& f = facets_[k];
  if (!f.unbounded) return triangle_distance(k, x);
  const V xv(x[0], x[1], x[2]);
  return std::abs((xv - vec(f.p)).dot(vec(f.n)));
}

// A lower bound of the distance from x to facet k's triangle, less a margin
// far above the roundoff of triangle_distance, so that a facet it skips is
// farther than the one compared with, to the last bit.
double CutSurface::lower_bound(const double x[3], size_t k) const {
  const V xv(x[0], x[1], x[2]), c = vec(centre_[k]);
  const double d = (xv - c).norm();
  // 1e-12 of the coordinates is far above 16 epsilon of them (roundoff());
  // 2e-9 r covers the closest point's slack off the sphere (triangle_distance).
  return d - radius_[k] * (1.0 + 2e-9) - 1e-12 * (d + radius_[k] + xv.cwiseAbs().maxCoeff() + c.cwiseAbs().maxCoeff());
}

int CutSurface::nearest_facet(const double x[3]) const {
  int best = 0;
  double bd = 1e300;
  // Facet k is taken when nearer than the best so far, or as near with a
  // lower index: the first facet of least distance, in whatever order the
  // facets are visited. A facet whose lower bound is above bd is farther.
  const auto visit = [&](size_t k) {
    if (lower_bound(x, k) > bd) return;
    const double d = facet_distance(k, x);
    if (d < bd || (d == bd && static_cast<int>(k) < best)) {
      bd = d;
      best = static_cast<int>(k);
    }
  };
  if (!tree_) {
    for (size_t k = 0; k < facets_.size(); ++k) visit(k);
    return best;
  }
  const V xv(x[0], x[1], x[2]);
  tree_->nearest([&](const Eigen::AlignedBox3d& b) { return b.exteriorDistance(xv) - box_margin(b, xv); },
                 [&] { return bd; }, [&](int k) { visit(static_cast<size_t>(k)); });
  return best;
}

double CutSurface::distance(const double x[3]) const {
  if (facets_.empty()) return 1e300;
  return facet_distance(static_cast<size_t>(nearest_facet(x)), x);
}

// [preprint] eq. (72), against the nearest facet's plane, where the nearest
// point of the surface is inside that facet. Where it is on an edge or a
// corner, the planes of the facets that meet there disagree in a wedge
// behind them (below a V's fold either arm's plane put some points on the
// wrong side, and the sign flipped from node to node: the V cut nothing):
// the sign is then the pseudonormal's, and phi the distance to that point.
CutSurface::Value CutSurface::value(const double x[3]) const {
  if (facets_.empty()) return {1.0, 1};
  const int k = nearest_facet(x);
  const Facet& f = facets_[k];
  const double phi = (x[0] - f.p[0]) * f.n[0] + (x[1] - f.p[1]) * f.n[1] + (x[2] - f.p[2]) * f.n[2];
  const int s = exact_sign_dot_diff(x, f.p.data(), f.n.data());
  if (!f.unbounded) {
    int feature = 0;
    const V xv(x[0], x[1], x[2]);
    const V c = closest_on_triangle(xv, vec(f.v[0]), vec(f.v[1]), vec(f.v[2]), &feature);
    if (feature > 0) {
      const V pn = vec(feature < 4 ? corner_normal_[k][feature - 1] : edge_normal_[k][feature - 4]);
      const double d = (xv - c).dot(pn);
      const int ps = d > 0 ? 1 : d < 0 ? -1 : 0;
      if (ps != 0 && ps != s) return {ps * (xv - c).norm(), ps};
    }
  }
  // phi is rounded, s is exact: keep them consistent (phi = 0 iff s = 0).
  double ph = s == 0 ? 0.0 : (phi * s > 0 ? phi : s * 1e-300);
  return {ph, s};
}

namespace {
// The roundoff of triangle_distance(x, facet): a few ulps of the largest
// coordinate involved. Added to a caller's tolerance (1e-9 h): a triangle
// spanning +-1e6 m through a 1 cm body loses 1e-9 m, 1e-7 h, to roundoff,
// and covered nothing (the cut "cut nothing"); at tissue scale it is 1e-17 m.
double roundoff(const V& x, const Facet& f) {
  double m = x.cwiseAbs().maxCoeff();
  for (const Vec3& v : f.v) m = std::max({m, std::abs(v[0]), std::abs(v[1]), std::abs(v[2])});
  return 16.0 * std::numeric_limits<double>::epsilon() * m;
}
}  // namespace

bool CutSurface::facet_crosses(size_t k, const double a[3], const double b[3], double tol) const {
  const V xa(a[0], a[1], a[2]), xb(b[0], b[1], b[2]), ab = xb - xa;
  const Facet& f = facets_[k];
  if (f.unbounded) return true;
  // The crossing point y lies on a-b: skip a facet whose sphere is
  // farther than tol from the whole segment.
  const double t = ab.squaredNorm() > 0 ? std::clamp((vec(centre_[k]) - xa).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
  const V y0 = xa + t * ab;
  if (lower_bound(y0.data(), k) > tol) return false;
  const V n = vec(f.n), p = vec(f.p);
  const double da = (xa - p).dot(n), db = (xb - p).dot(n);
  if ((da > 0 && db > 0) || (da < 0 && db < 0) || da == db) return false;
  const V y = xa + da / (da - db) * (xb - xa);
  return triangle_distance(k, y.data()) <= tol + roundoff(y, f);
}

bool CutSurface::crosses_segment(const double a[3], const double b[3], double tol) const {
  if (!tree_) {
    for (size_t k = 0; k < facets_.size(); ++k)
      if (facet_crosses(k, a, b, tol)) return true;
    return false;
  }
  // The crossing point lies in the segment's box and within tol (plus
  // roundoff) of its facet: only boxes that meet the segment's box grown
  // by that can hold it.
  Eigen::AlignedBox3d seg(V(a[0], a[1], a[2]));
  seg.extend(V(b[0], b[1], b[2]));
  const double seg_size = seg.min().cwiseAbs().maxCoeff() + seg.max().cwiseAbs().maxCoeff();
  const auto open = [&](const Eigen::AlignedBox3d& box) {
    // (the margin as box_margin's, over the segment's and the box's coordinates)
    const double grow = tol + 4e-12 * (seg_size + box.min().cwiseAbs().maxCoeff() + box.max().cwiseAbs().maxCoeff());
    return ((seg.min().array() - grow) <= box.max().array()).all() &&
           ((seg.max().array() + grow) >= box.min().array()).all();
  };
  return tree_->any(open, [&](int k) { return facet_crosses(static_cast<size_t>(k), a, b, tol); });
}

bool CutSurface::facet_covers(size_t k, const double y[3], double tol) const {
  const Facet& f = facets_[k];
  if (f.unbounded) return true;
  // Beyond what the test below takes (its roundoff() is at most this
  // bound's 1e-12 margin; both are far below the tolerances used).
  if (lower_bound(y, k) > tol) return false;
  const V x(y[0], y[1], y[2]);
  return triangle_distance(k, y) <= tol + roundoff(x, f);
}

bool CutSurface::covers(const double y[3], double tol) const {
  tol *= 1.0 + slack_;
  if (!tree_) {
    for (size_t k = 0; k < facets_.size(); ++k)
      if (facet_covers(k, y, tol)) return true;
    return false;
  }
  const V x(y[0], y[1], y[2]);
  return tree_->any([&](const Eigen::AlignedBox3d& box) { return box.exteriorDistance(x) <= tol + box_margin(box, x); },
                    [&](int k) { return facet_covers(static_cast<size_t>(k), y, tol); });
}

namespace {
// Turns the triangles of each connected patch (neighbours across edges that
// exactly two triangles share, vertices matched exactly) to the winding of
// its first triangle in the file. The level set's sign is each facet's
// normal: a surface exported with mixed winding (as meshing tools do) put
// neighbouring facets' sides opposite, so the sign flipped from node to node
// and a plane written that way separated nothing. Returns how many were
// turned; throws for a surface with no consistent winding (a Moebius strip).
int orient_consistently(std::vector<Facet>& facets, const std::string& path) {
  std::map<Vec3, int> ids;
  std::vector<std::array<int, 3>> tri(facets.size());
  for (size_t f = 0; f < facets.size(); ++f)
    for (int k = 0; k < 3; ++k) tri[f][k] = ids.emplace(facets[f].v[k], static_cast<int>(ids.size())).first->second;
  // Each undirected edge's triangles, and the direction each runs it in.
  std::map<std::pair<int, int>, std::vector<std::pair<int, bool>>> edges;
  for (size_t f = 0; f < facets.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = tri[f][k], b = tri[f][(k + 1) % 3];
      edges[{std::min(a, b), std::max(a, b)}].emplace_back(static_cast<int>(f), a < b);
    }
  std::vector<signed char> flip(facets.size(), -1);  // -1 unvisited, 0 kept, 1 turned
  int turned = 0;
  for (size_t seed = 0; seed < facets.size(); ++seed) {
    if (flip[seed] >= 0) continue;
    flip[seed] = 0;
    std::vector<int> stack{static_cast<int>(seed)};
    while (!stack.empty()) {
      const int f = stack.back();
      stack.pop_back();
      for (int k = 0; k < 3; ++k) {
        const int a = tri[f][k], b = tri[f][(k + 1) % 3];
        const auto& users = edges[{std::min(a, b), std::max(a, b)}];
        if (users.size() != 2) continue;  // a boundary or non-manifold edge: no neighbour to follow
        const auto& [g, g_forward] = users[0].first == f ? users[1] : users[0];
        const bool f_forward = (a < b) != (flip[f] == 1);
        // Consistent neighbours run a shared edge in opposite directions.
        const signed char want = (g_forward == f_forward) ? 1 : 0;
        if (flip[g] < 0) {
          flip[g] = want;
          turned += want;
          stack.push_back(g);
        } else if (flip[g] != want) {
          throw Error(path + ": the triangles have no consistent winding (a non-orientable surface, such as a Moebius "
                             "strip): a cut needs two sides");
        }
      }
    }
  }
  for (size_t f = 0; f < facets.size(); ++f)
    if (flip[f] == 1) {
      std::swap(facets[f].v[1], facets[f].v[2]);
      for (double& c : facets[f].n) c = -c;
    }
  return turned;
}
}  // namespace

std::vector<Facet> read_triangle_surface(const std::string& path) {
  const bool stl = path.size() > 4 && (path.substr(path.size() - 4) == ".stl" || path.substr(path.size() - 4) == ".STL");
  const bool obj = path.size() > 4 && (path.substr(path.size() - 4) == ".obj" || path.substr(path.size() - 4) == ".OBJ");
  if (!stl && !obj) throw Error(path + ": unsupported cut surface format; allowed: .obj, .stl (ASCII)");
  std::istringstream is(read_input_file(path, kMaxTableBytes, "cut surface"));
  std::vector<Facet> facets;
  std::vector<V> verts;
  std::string line;
  std::vector<V> tri;  // STL: the vertices of the open facet
  int tri_line = 0;
  auto add = [&](const V& a, const V& b, const V& c, const std::function<void(const std::string&)>& fail) {
    double rel = 0;
    scaled_normal(a, b, c, &rel);
    if (!(rel > kMinFacetShape))
      fail(rel == 0 ? "triangle has zero area (its corners are collinear or repeated); remove it"
                    : "triangle is degenerate (a sliver: its smallest angle is below 1e-12 rad); remove it");
    facets.push_back(triangle_facet(a, b, c));
  };
  int lineno = 1;
  for (; std::getline(is, line); ++lineno) {
    std::istringstream ls(line);
    std::string key;
    if (!(ls >> key)) continue;
    const std::function<void(const std::string&)> fail = [&](const std::string& what) {
      throw Error(path + ":" + std::to_string(lineno) + ": " + what);
    };
    if (obj && key == "v") {
      double a, b, c;
      if (!(ls >> a >> b >> c) || !std::isfinite(a) || !std::isfinite(b) || !std::isfinite(c))
        fail("vertex needs three finite coordinates");
      verts.emplace_back(a, b, c);
    } else if (obj && key == "f") {
      std::vector<size_t> ids;
      std::string tok;
      while (ls >> tok) {
        if (ids.size() == kMaxObjFaceVertices)
          fail("face lists more than " + std::to_string(kMaxObjFaceVertices) +
               " vertices; allowed: 3 to " + std::to_string(kMaxObjFaceVertices) + " (triangulate larger polygons)");
        // "v", "v/vt", "v//vn" or "v/vt/vn": 1-based, or negative counting back from the last vertex.
        const std::string v = tok.substr(0, tok.find('/'));
        long long id = 0;
        const auto r = std::from_chars(v.data(), v.data() + v.size(), id);
        if (r.ec != std::errc() || r.ptr != v.data() + v.size())
          fail("face vertex " + tok.substr(0, 40) + " is not an integer index in range");
        const long long n = static_cast<long long>(verts.size());
        if (id == 0 || id > n || id < -n)
          fail("face references vertex " + tok.substr(0, 40) + ", but only " + std::to_string(verts.size()) +
               " are defined (indices are 1.." + std::to_string(n) + ", or -1..-" + std::to_string(n) + " counting back)");
        ids.push_back(static_cast<size_t>(id < 0 ? n + id : id - 1));
      }
      if (ids.size() < 3) fail("face needs at least 3 vertices, got " + std::to_string(ids.size()));
      if (ids.size() == 3) {
        add(verts[ids[0]], verts[ids[1]], verts[ids[2]], fail);
        continue;
      }
      // A larger face must be a planar convex polygon, so that its fan covers it.
      std::vector<V> pts;
      for (size_t i : ids) pts.push_back(verts[i]);
      V cen, n;
      polygon_plane(
          pts, cen, n,
          [&](int k, const std::string& what) {
            fail(k < 0 ? "face: " + what : "face vertex " + std::to_string(k + 1) + ": " + what);
          },
          [](size_t k) { return "its vertex " + std::to_string(k + 1); });
      for (size_t k = 1; k + 1 < ids.size(); ++k) {
        double rel = 0;
        scaled_normal(pts[0], pts[k], pts[k + 1], &rel);
        if (rel > kMinFacetShape) facets.push_back(triangle_facet(pts[0], pts[k], pts[k + 1]));  // (collinear corners: no area)
      }
    } else if (stl && key == "vertex") {
      double a, b, c;
      if (!(ls >> a >> b >> c) || !std::isfinite(a) || !std::isfinite(b) || !std::isfinite(c))
        fail("vertex needs three finite coordinates");
      if (tri.size() == 3) fail("a facet lists more than 3 vertices; ASCII STL facets are triangles");
      if (tri.empty()) tri_line = lineno;
      tri.emplace_back(a, b, c);
    } else if (stl && (key == "endloop" || key == "endfacet")) {
      if (key == "endfacet" && tri.empty()) continue;  // closed at its endloop
      if (tri.size() != 3)
        fail("a facet ends after " + std::to_string(tri.size()) + " vertices; ASCII STL facets are triangles (3 vertices)");
      const int at = lineno;
      lineno = tri_line;  // degenerate: name the facet's first vertex
      add(tri[0], tri[1], tri[2], fail);
      lineno = at;
      tri.clear();
    } else if (stl && key == "solid" && lineno == 1) {
      continue;
    }
  }
  if (!tri.empty())
    throw Error(path + ":" + std::to_string(tri_line) + ": the file ends inside a facet (" + std::to_string(tri.size()) +
                " of 3 vertices, no endloop)");
  if (facets.empty()) throw Error(path + ": no triangles found");
  if (const int turned = orient_consistently(facets, path); turned > 0) {
    static std::mutex m;
    static std::set<std::string> told;  // once per file (it is read at load and again when it cuts)
    const std::lock_guard<std::mutex> lock(m);
    if (told.insert(path).second)
      std::fprintf(stderr,
                   "warning: %s: %d of %zu triangles were wound against their neighbours and were turned to match "
                   "(each connected patch takes its first triangle's winding, which sets the cut's sides)\n",
                   path.c_str(), turned, facets.size());
  }
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
      // Centroid and Newell normal: one plane for all fan triangles, so the
      // exact sign is taken against the same plane everywhere.
      std::vector<V> pts;
      for (const Vec3& q : c.points) pts.push_back(vec(q));
      V cen, n;
      polygon_plane(
          pts, cen, n,
          [&](int k, const std::string& what) {
            throw Error(c.json_path + (k < 0 ? ".points" : ".points[" + std::to_string(k) + "]") + ": " + what);
          },
          [](size_t k) { return "points[" + std::to_string(k) + "]"; });
      const size_t np = c.points.size();
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
                                               int tool, const std::string& name,
                                               const std::vector<std::pair<size_t, size_t>>& ranges) {
  std::vector<Facet> facets;
  size_t own = 0, r = 0;  // the tool's triangles so far; the range they are in or before
  for (size_t t = 0; t < swept_tool.size(); ++t) {
    if (static_cast<int>(swept_tool[t]) != tool) continue;
    const size_t k = own++;
    while (r < ranges.size() && k >= ranges[r].second) ++r;
    if (!ranges.empty() && (r == ranges.size() || k < ranges[r].first)) continue;
    const double* v = &swept[9 * t];
    // A band's triangle of no area (an edge moved by roundoff, or along
    // itself) has no plane: its level set would be noise.
    if (degenerate_triangle(v, v + 3, v + 6)) continue;
    facets.push_back(triangle_facet(V(v[0], v[1], v[2]), V(v[3], v[4], v[5]), V(v[6], v[7], v[8])));
  }
  auto surf = std::make_unique<CutSurface>(std::move(facets), name);
  if (surf->facets().empty()) return nullptr;
  // The layout's tolerance is 1e-9 of the element size: reach 1e-2 of it.
  surf->set_cover_slack(1e7);
  return surf;
}

}  // namespace incise
