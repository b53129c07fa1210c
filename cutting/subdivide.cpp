#include "cutting/subdivide.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include <Eigen/Dense>

namespace incise {

namespace {

using V = Eigen::Vector3d;

struct Vertex {
  V r;                      // local coordinates
  std::vector<double> phi;  // every cut's level set here
};

// A planar convex polygon on the boundary of a cell, with its tag.
struct Face {
  std::vector<int> v;  // pool ids, in order around the polygon
  signed char tag;
};

// A convex part of the element: the intersection of the tetrahedron with one
// side of every cut applied so far. Cutting keeps it convex, so k cuts make at
// most sum_{i<=3} C(k, i) cells (the cells of an arrangement of k planes), not
// 2^k, whatever the cuts' order or how close they lie to one another.
struct Cell {
  std::vector<Face> faces;
  std::vector<signed char> side;  // per cut processed so far
};

// Outward-ordered corners of face k of a tet (opposite corner k).
constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

double tet_volume(const V& a, const V& b, const V& c, const V& d) {
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

class Splitter {
 public:
  Splitter(std::vector<Vertex>& pool, double zero_tol) : pool_(pool), tol_(zero_tol) {}

  void start_cut(int c) {
    cut_ = c;
    edge_point_.clear();  // crossings are shared by the cells of one cut
  }

  // Splits cell `cell` by the current cut into its + and - parts (or passes it
  // on whole, with its side, when the plane does not cross it).
  void split(const Cell& cell, std::vector<Cell>& out) {
    int npos = 0, nneg = 0;
    for (const Face& f : cell.faces)
      for (int i : f.v) {
        const int s = sign(i);
        npos += s > 0;
        nneg += s < 0;
      }
    if (npos == 0 || nneg == 0) {
      Cell u = cell;
      u.side.push_back(npos > 0 ? 1 : (nneg > 0 ? -1 : 1));
      out.push_back(std::move(u));
      return;
    }
    for (int sgn : {1, -1}) out.push_back(part(cell, sgn));
  }

 private:
  std::vector<Vertex>& pool_;
  double tol_;
  int cut_ = 0;
  std::map<std::pair<int, int>, int> edge_point_;  // crossing point of an edge (pool ids)

  int sign(int i) const {
    const double f = pool_[i].phi[cut_];
    return std::abs(f) <= tol_ ? 0 : (f > 0 ? 1 : -1);
  }

  int crossing(int a, int b) {
    // Interpolate from the lower id so both faces sharing the edge get the same point.
    if (a > b) std::swap(a, b);
    const auto key = std::make_pair(a, b);
    if (auto it = edge_point_.find(key); it != edge_point_.end()) return it->second;
    const double fa = pool_[a].phi[cut_], fb = pool_[b].phi[cut_];
    const double t = fa / (fa - fb);
    Vertex v;
    v.r = pool_[a].r + t * (pool_[b].r - pool_[a].r);
    v.phi.resize(pool_[a].phi.size());
    for (size_t k = 0; k < v.phi.size(); ++k) v.phi[k] = pool_[a].phi[k] + t * (pool_[b].phi[k] - pool_[a].phi[k]);
    v.phi[cut_] = 0.0;
    pool_.push_back(std::move(v));
    const int id = static_cast<int>(pool_.size()) - 1;
    edge_point_[key] = id;
    return id;
  }

  // The part of a cell on side sgn: each face clipped (Sutherland-Hodgman),
  // closed by the cut polygon made of the vertices on the plane.
  Cell part(const Cell& cell, int sgn) {
    Cell out;
    out.side = cell.side;
    out.side.push_back(static_cast<signed char>(sgn));
    std::vector<int> on_plane;
    for (const Face& f : cell.faces) {
      Face p{{}, f.tag};
      const size_t n = f.v.size();
      for (size_t j = 0; j < n; ++j) {
        const int a = f.v[j], b = f.v[(j + 1) % n];
        const int sa = sign(a), sb = sign(b);
        if (sgn * sa >= 0) p.v.push_back(a);
        if (sa == 0) on_plane.push_back(a);
        if (sa * sb < 0) {
          const int x = crossing(a, b);
          p.v.push_back(x);
          on_plane.push_back(x);
        }
      }
      if (p.v.size() >= 3) out.faces.push_back(std::move(p));
    }
    std::sort(on_plane.begin(), on_plane.end());
    on_plane.erase(std::unique(on_plane.begin(), on_plane.end()), on_plane.end());
    if (on_plane.size() >= 3) {
      // The cut polygon is convex: order it by angle around its centroid.
      V cen = V::Zero();
      for (int i : on_plane) cen += pool_[i].r;
      cen /= static_cast<double>(on_plane.size());
      int far = on_plane[0];
      for (int i : on_plane)
        if ((pool_[i].r - cen).squaredNorm() > (pool_[far].r - cen).squaredNorm()) far = i;
      const V e1 = (pool_[far].r - cen).normalized();
      V n = V::Zero();  // Newell-free: the largest cross product about the centroid
      for (int i : on_plane) {
        const V c = e1.cross(pool_[i].r - cen);
        if (c.squaredNorm() > n.squaredNorm()) n = c;
      }
      const V e2 = n.normalized().cross(e1);
      std::sort(on_plane.begin(), on_plane.end(), [&](int a, int b) {
        const V da = pool_[a].r - cen, db = pool_[b].r - cen;
        return std::atan2(da.dot(e2), da.dot(e1)) < std::atan2(db.dot(e2), db.dot(e1));
      });
      out.faces.push_back({on_plane, kSubFaceCut});
    }
    return out;
  }
};

// Tetrahedralizes a convex cell by coning its faces (fans) to the mean of its
// vertices; face 3 of each sub-tet (opposite the apex) lies on the cell face.
void cone(const Cell& cell, std::vector<Vertex>& pool, SubTets& out) {
  std::vector<int> ids;
  for (const Face& f : cell.faces) ids.insert(ids.end(), f.v.begin(), f.v.end());
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  V q = V::Zero();
  for (int i : ids) q += pool[i].r;
  q /= static_cast<double>(ids.size());
  for (const Face& p : cell.faces)
    for (size_t j = 1; j + 1 < p.v.size(); ++j) {
      std::array<V, 4> x = {pool[p.v[0]].r, pool[p.v[j]].r, pool[p.v[j + 1]].r, q};
      double vol = tet_volume(x[0], x[1], x[2], x[3]);
      if (vol == 0.0) continue;
      if (vol < 0) {
        std::swap(x[1], x[2]);  // face 3 stays opposite q
        vol = -vol;
      }
      for (const V& r : x)
        for (int d = 0; d < 3; ++d) out.rst.push_back(r[d]);
      const signed char tags[4] = {kSubFaceInside, kSubFaceInside, kSubFaceInside, p.tag};
      out.face.insert(out.face.end(), tags, tags + 4);
      out.side.insert(out.side.end(), cell.side.begin(), cell.side.end());
      out.volume.push_back(vol);
    }
}

}  // namespace

SubTets subdivide_tet(const std::vector<double>& phi, int ncut, const std::vector<int>& only) {
  std::vector<Vertex> pool(4);
  const V corners[4] = {V(0, 0, 0), V(1, 0, 0), V(0, 1, 0), V(0, 0, 1)};
  double scale = 0.0;
  for (int k = 0; k < 4; ++k) {
    pool[k].r = corners[k];
    pool[k].phi.resize(ncut);
    for (int c = 0; c < ncut; ++c) {
      pool[k].phi[c] = phi[4 * c + k];
      scale = std::max(scale, std::abs(phi[4 * c + k]));
    }
  }
  // Interpolated values this close to zero are on the plane: it keeps the
  // second cut from making slivers of roundoff size at the first cut's points.
  Splitter splitter(pool, 1e-14 * scale);
  std::vector<Cell> cells(1);
  for (int k = 0; k < 4; ++k) cells[0].faces.push_back({{kFace[k][0], kFace[k][1], kFace[k][2]}, static_cast<signed char>(k)});
  // A cut within kMergeGap of an earlier one over the whole element is that
  // cut here (same or opposite orientation): it takes the earlier cut's sides
  // instead of splitting off a slab 1e-12 thick, whose DOFs would have a
  // support of roundoff size (cutting twice in one place is ordinary use).
  constexpr double kMergeGap = 1e-9;
  std::vector<int> twin(ncut, -1), twin_sign(ncut, 1);
  for (int c = 0; c < ncut; ++c)
    for (int e = 0; e < c && twin[c] < 0; ++e) {
      if (!only.empty() && (only[2 * c] >= 0 || only[2 * e] >= 0)) continue;
      for (int sg : {1, -1}) {
        double gap = 0.0, size = 0.0;
        for (int k = 0; k < 4; ++k) {
          gap = std::max(gap, std::abs(phi[4 * c + k] - sg * phi[4 * e + k]));
          size = std::max({size, std::abs(phi[4 * c + k]), std::abs(phi[4 * e + k])});
        }
        if (gap <= kMergeGap * size) {
          twin[c] = twin[e] >= 0 ? twin[e] : e;
          twin_sign[c] = sg * (twin[e] >= 0 ? twin_sign[e] : 1);
          break;
        }
      }
    }
  for (int c = 0; c < ncut; ++c) {
    if (twin[c] >= 0) {
      for (Cell& t : cells) t.side.push_back(static_cast<signed char>(twin_sign[c] * t.side[twin[c]]));
      continue;
    }
    splitter.start_cut(c);
    std::vector<Cell> next;
    next.reserve(cells.size() * 2);
    for (Cell& t : cells) {
      if (!only.empty() && only[2 * c] >= 0 && t.side[only[2 * c]] != only[2 * c + 1]) {
        t.side.push_back(0);
        next.push_back(std::move(t));
        continue;
      }
      splitter.split(t, next);
    }
    cells.swap(next);
  }
  SubTets out;
  out.ncut = ncut;
  for (const Cell& cell : cells) cone(cell, pool, out);
  return out;
}

}  // namespace incise
