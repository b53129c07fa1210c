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

struct Tet {
  std::array<int, 4> v;                  // into the vertex pool
  std::array<signed char, 4> face;       // tags, face k opposite vertex k
  std::vector<signed char> side;         // per cut processed so far
};

// Outward-ordered corners of face k of a tet (opposite corner k).
constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

double tet_volume(const V& a, const V& b, const V& c, const V& d) {
  return (b - a).dot((c - a).cross(d - a)) / 6.0;
}

class Splitter {
 public:
  Splitter(std::vector<Vertex>& pool, double zero_tol) : pool_(pool), tol_(zero_tol) {}

  // Splits tet t by cut c into tets on the + side and the - side.
  void split(const Tet& t, int c, std::vector<Tet>& out) {
    std::array<double, 4> f;
    std::array<int, 4> s;
    int npos = 0, nneg = 0;
    for (int k = 0; k < 4; ++k) {
      f[k] = pool_[t.v[k]].phi[c];
      s[k] = std::abs(f[k]) <= tol_ ? 0 : (f[k] > 0 ? 1 : -1);
      npos += s[k] > 0;
      nneg += s[k] < 0;
    }
    if (npos == 0 || nneg == 0) {
      Tet u = t;
      u.side.push_back(npos > 0 ? 1 : (nneg > 0 ? -1 : 1));
      out.push_back(u);
      return;
    }
    edge_point_.clear();
    for (int sgn : {1, -1}) part(t, f, s, sgn, out);
  }

 private:
  std::vector<Vertex>& pool_;
  double tol_;
  std::map<std::pair<int, int>, int> edge_point_;  // crossing point of an edge (pool ids)

  int crossing(int a, int b, double fa, double fb) {
    const auto key = std::make_pair(std::min(a, b), std::max(a, b));
    if (auto it = edge_point_.find(key); it != edge_point_.end()) return it->second;
    // Interpolate from the lower id so both faces sharing the edge get the same point.
    if (a > b) {
      std::swap(a, b);
      std::swap(fa, fb);
    }
    const double t = fa / (fa - fb);
    Vertex v;
    v.r = pool_[a].r + t * (pool_[b].r - pool_[a].r);
    v.phi.resize(pool_[a].phi.size());
    for (size_t k = 0; k < v.phi.size(); ++k) v.phi[k] = pool_[a].phi[k] + t * (pool_[b].phi[k] - pool_[a].phi[k]);
    pool_.push_back(std::move(v));
    const int id = static_cast<int>(pool_.size()) - 1;
    edge_point_[key] = id;
    return id;
  }

  void part(const Tet& t, const std::array<double, 4>& f, const std::array<int, 4>& s, int sgn,
            std::vector<Tet>& out) {
    struct Poly {
      std::vector<int> v;
      signed char tag;
    };
    std::vector<Poly> polys;
    std::vector<int> on_plane;  // zero vertices and crossings: the cut polygon
    std::vector<int> all;
    for (int k = 0; k < 4; ++k) {
      // Sutherland-Hodgman clip of face k to sgn * phi >= 0.
      Poly p{{}, t.face[k]};
      for (int j = 0; j < 3; ++j) {
        const int a = kFace[k][j], b = kFace[k][(j + 1) % 3];
        const bool ina = sgn * s[a] >= 0, inb = sgn * s[b] >= 0;
        if (ina) p.v.push_back(t.v[a]);
        if (s[a] * s[b] < 0) p.v.push_back(crossing(t.v[a], t.v[b], f[a], f[b]));
        (void)inb;
      }
      if (p.v.size() >= 3) polys.push_back(p);
    }
    for (int k = 0; k < 4; ++k) {
      if (s[k] == 0) on_plane.push_back(t.v[k]);
      if (sgn * s[k] >= 0) all.push_back(t.v[k]);
      for (int j = k + 1; j < 4; ++j)
        if (s[k] * s[j] < 0) {
          const int x = crossing(t.v[k], t.v[j], f[k], f[j]);
          on_plane.push_back(x);
          all.push_back(x);
        }
    }
    if (on_plane.size() >= 3) {
      // Order the cut polygon by angle around its centroid in the plane.
      V cen = V::Zero();
      for (int i : on_plane) cen += pool_[i].r;
      cen /= static_cast<double>(on_plane.size());
      V n = (pool_[on_plane[1]].r - pool_[on_plane[0]].r).cross(pool_[on_plane[2]].r - pool_[on_plane[0]].r);
      for (size_t i = 3; i < on_plane.size() && n.norm() == 0; ++i)
        n = (pool_[on_plane[1]].r - pool_[on_plane[0]].r).cross(pool_[on_plane[i]].r - pool_[on_plane[0]].r);
      V e1 = (pool_[on_plane[0]].r - cen);
      if (e1.norm() == 0 && on_plane.size() > 1) e1 = pool_[on_plane[1]].r - cen;
      e1.normalize();
      const V e2 = n.normalized().cross(e1);
      std::sort(on_plane.begin(), on_plane.end(), [&](int a, int b) {
        const V da = pool_[a].r - cen, db = pool_[b].r - cen;
        return std::atan2(da.dot(e2), da.dot(e1)) < std::atan2(db.dot(e2), db.dot(e1));
      });
      polys.push_back({on_plane, kSubFaceCut});
    }
    V q = V::Zero();
    for (int i : all) q += pool_[i].r;
    q /= static_cast<double>(all.size());
    Vertex qv;
    qv.r = q;
    qv.phi.assign(pool_[t.v[0]].phi.size(), 0.0);
    for (int i : all)
      for (size_t k = 0; k < qv.phi.size(); ++k) qv.phi[k] += pool_[i].phi[k] / all.size();
    pool_.push_back(qv);
    const int qi = static_cast<int>(pool_.size()) - 1;
    for (const Poly& p : polys)
      for (size_t j = 1; j + 1 < p.v.size(); ++j) {
        Tet u;
        u.v = {p.v[0], p.v[j], p.v[j + 1], qi};
        u.face = {kSubFaceInside, kSubFaceInside, kSubFaceInside, p.tag};
        const double vol = tet_volume(pool_[u.v[0]].r, pool_[u.v[1]].r, pool_[u.v[2]].r, pool_[u.v[3]].r);
        if (vol == 0.0) continue;
        if (vol < 0) std::swap(u.v[1], u.v[2]);  // face 3 stays opposite q
        u.side = t.side;
        u.side.push_back(static_cast<signed char>(sgn));
        out.push_back(u);
      }
  }
};

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
  std::vector<Tet> tets(1);
  tets[0].v = {0, 1, 2, 3};
  tets[0].face = {0, 1, 2, 3};
  for (int c = 0; c < ncut; ++c) {
    std::vector<Tet> next;
    for (const Tet& t : tets) {
      if (!only.empty() && only[2 * c] >= 0 && t.side[only[2 * c]] != only[2 * c + 1]) {
        Tet u = t;
        u.side.push_back(0);
        next.push_back(u);
        continue;
      }
      splitter.split(t, c, next);
    }
    tets.swap(next);
  }
  SubTets out;
  out.ncut = ncut;
  for (const Tet& t : tets) {
    for (int k = 0; k < 4; ++k)
      for (int d = 0; d < 3; ++d) out.rst.push_back(pool[t.v[k]].r[d]);
    out.face.insert(out.face.end(), t.face.begin(), t.face.end());
    out.side.insert(out.side.end(), t.side.begin(), t.side.end());
    out.volume.push_back(tet_volume(pool[t.v[0]].r, pool[t.v[1]].r, pool[t.v[2]].r, pool[t.v[3]].r));
  }
  return out;
}

}  // namespace incise
