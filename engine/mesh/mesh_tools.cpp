// Structured beams, tet4 -> tet10, quality report and mesh checks.
#include "engine/mesh/mesh_tools.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <unordered_map>

#include "engine/util/error.h"
#include "engine/util/number_text.h"

namespace incise {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct V3 {
  double x, y, z;
};
V3 node(const Mesh& m, int i) { return {m.X[3 * i], m.X[3 * i + 1], m.X[3 * i + 2]}; }
V3 sub(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
double dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V3 cross(V3 a, V3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
V3 axpy(double s, V3 a, V3 b) { return {b.x + s * a.x, b.y + s * a.y, b.z + s * a.z}; }

// Volume of the corner tet of element e: det[x1-x0, x2-x0, x3-x0] / 6.
double corner_volume(const Mesh& m, int e) {
  const int* t = &m.tet[e * m.npe()];
  V3 x0 = node(m, t[0]);
  return dot(sub(node(m, t[1]), x0), cross(sub(node(m, t[2]), x0), sub(node(m, t[3]), x0))) / 6.0;
}

// Interior dihedral angle at edge (i,j) of a tet whose other corners are k,l:
// angle between k and l seen along the edge.
double dihedral(V3 xi, V3 xj, V3 xk, V3 xl) {
  V3 e = sub(xj, xi);
  double ee = dot(e, e);
  if (ee <= 0) return 0;
  V3 u = sub(xk, xi), v = sub(xl, xi);
  u = axpy(-dot(u, e) / ee, e, u);
  v = axpy(-dot(v, e) / ee, e, v);
  return std::atan2(std::sqrt(dot(cross(u, v), cross(u, v))), dot(u, v));
}

// det J of the tet10 map at barycentric point L, with J = d x / d(L1, L2, L3).
double tet10_detJ(const Mesh& m, int e, const double L[4]) {
  static const double dL[4][3] = {{-1, -1, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const int* t = &m.tet[e * 10];
  double J[3][3] = {};
  auto add = [&](int n, const double g[3]) {
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) J[a][b] += m.X[3 * t[n] + a] * g[b];
  };
  for (int i = 0; i < 4; ++i) {  // corners: N = L (2L - 1)
    double g[3];
    for (int b = 0; b < 3; ++b) g[b] = (4 * L[i] - 1) * dL[i][b];
    add(i, g);
  }
  for (int k = 0; k < 6; ++k) {  // mid-edge nodes: N = 4 Li Lj
    const int i = kTet10Edge[k][0], j = kTet10Edge[k][1];
    double g[3];
    for (int b = 0; b < 3; ++b) g[b] = 4 * (L[i] * dL[j][b] + L[j] * dL[i][b]);
    add(4 + k, g);
  }
  return J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1]) - J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0]) +
         J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0]);
}

// Volume of a tet10 element: det J (a cubic for curved elements) integrated
// exactly by a 3x3x3 Gauss rule on the collapsed cube (Duffy map).
double tet10_volume(const Mesh& m, int e) {
  static const double g[3] = {0.5 - 0.5 * std::sqrt(0.6), 0.5, 0.5 + 0.5 * std::sqrt(0.6)};
  static const double w[3] = {5.0 / 18, 8.0 / 18, 5.0 / 18};
  double vol = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      for (int c = 0; c < 3; ++c) {
        const double u = g[a], v = g[b], s = g[c];
        const double xi = u, eta = v * (1 - u), zeta = s * (1 - u) * (1 - v);
        const double L[4] = {1 - xi - eta - zeta, xi, eta, zeta};
        vol += w[a] * w[b] * w[c] * (1 - u) * (1 - u) * (1 - v) * tet10_detJ(m, e, L);
      }
  return vol;
}

std::string prefix(const Mesh& m) { return m.source.empty() ? std::string("mesh: ") : m.source + ": "; }

// "FILE:LINE: " of element e when the reader recorded its line, else prefix().
std::string element_prefix(const Mesh& m, int e) {
  if (m.source.empty() || static_cast<size_t>(e) >= m.elem_line.size()) return prefix(m);
  return m.source + ":" + std::to_string(m.elem_line[e]) + ": ";
}

std::string element_text(const Mesh& m, int e) {
  std::string s = "element " + std::to_string(e) + " (nodes";
  for (int a = 0; a < m.npe(); ++a) s += " " + std::to_string(m.tet[e * m.npe() + a]);
  if (static_cast<size_t>(e) < m.elem_file_id.size()) s += "; id " + std::to_string(m.elem_file_id[e]) + " in the file";
  return s + ")";
}

// Where det J of a tet10 must be positive besides its 10 nodes: the 4-point
// rule the stiffness is integrated with (engine/fem/element.cpp
// cubature_tet4(); engine/mesh may not include engine/fem, so the points are
// repeated here and a test compares them) and the 27 points tet10_volume()
// integrates with. det J is a cubic: positive at the nodes alone does not keep
// a curved element from folding inside.
struct DetJPoint {
  double L[4];
  const char* kind;
};
const std::vector<DetJPoint>& tet10_check_points() {
  static const std::vector<DetJPoint> pts = [] {
    std::vector<DetJPoint> p;
    for (int k = 0; k < 4; ++k) {  // corners
      DetJPoint q{{0, 0, 0, 0}, "corner"};
      q.L[k] = 1;
      p.push_back(q);
    }
    for (const auto& ed : kTet10Edge) {  // mid-edge nodes
      DetJPoint q{{0, 0, 0, 0}, "mid-edge node"};
      q.L[ed[0]] = q.L[ed[1]] = 0.5;
      p.push_back(q);
    }
    const double a = 0.5854101966249685, b = 0.1381966011250105;  // (5 + 3 sqrt 5) / 20, (5 - sqrt 5) / 20
    for (int k = 0; k < 4; ++k) {
      DetJPoint q{{b, b, b, b}, "stiffness quadrature point"};
      q.L[k] = a;
      p.push_back(q);
    }
    const double g[3] = {0.5 - 0.5 * std::sqrt(0.6), 0.5, 0.5 + 0.5 * std::sqrt(0.6)};
    for (double u : g)
      for (double v : g)
        for (double w : g) {
          const double xi = u, eta = v * (1 - u), zeta = w * (1 - u) * (1 - v);
          p.push_back({{1 - xi - eta - zeta, xi, eta, zeta}, "volume quadrature point"});
        }
    return p;
  }();
  return pts;
}

std::string num(double v) { return number_text(v, 3); }

}  // namespace

Mesh make_beam(double lx, double ly, double lz, int nx, int ny, int nz, int order) {
  if (!(lx > 0 && ly > 0 && lz > 0) || !std::isfinite(lx) || !std::isfinite(ly) || !std::isfinite(lz))
    throw Error("make_beam: lengths must be positive and finite, got " + num(lx) + " " + num(ly) + " " + num(lz));
  if (nx < 1 || ny < 1 || nz < 1)
    throw Error("make_beam: cell counts must be >= 1, got " + std::to_string(nx) + " " + std::to_string(ny) + " " +
                std::to_string(nz));
  if (order != 1 && order != 2) throw Error("make_beam: order must be 1 or 2, got " + std::to_string(order));
  Mesh m;
  auto coord = [](int i, int n, double l) { return i == n ? l : l * i / n; };
  auto id = [&](int i, int j, int k) { return i + (nx + 1) * (j + (ny + 1) * k); };
  m.X.reserve(3 * (nx + 1) * (ny + 1) * (nz + 1));
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i) m.X.insert(m.X.end(), {coord(i, nx, lx), coord(j, ny, ly), coord(k, nz, lz)});
  // Kuhn split: one tet per axis permutation (a,b,c), along the path
  // 0 -> e_a -> e_a+e_b -> 1 of the cube. Every cube face is cut along its
  // diagonal through the face's lowest corner, so neighbours conform. The
  // volume sign is the permutation's sign; odd ones swap their last two nodes.
  static const int perm[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
  m.tet.reserve(24 * nx * ny * nz);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (int p = 0; p < 6; ++p) {
          int c[3] = {0, 0, 0}, v[4];
          v[0] = id(i, j, k);
          for (int s = 0; s < 3; ++s) {
            c[perm[p][s]] = 1;
            v[s + 1] = id(i + c[0], j + c[1], k + c[2]);
          }
          if (p >= 3) std::swap(v[2], v[3]);
          m.tet.insert(m.tet.end(), v, v + 4);
        }
  return order == 2 ? raise_to_tet10(m) : m;
}

Mesh lower_to_tet4(const Mesh& mesh) {
  if (mesh.order == 1) return mesh;
  const int ntet = mesh.ntet();
  std::vector<int> id(static_cast<size_t>(mesh.nnode()), -1);
  for (int e = 0; e < ntet; ++e)
    for (int a = 0; a < 4; ++a) id[static_cast<size_t>(mesh.tet[10 * static_cast<size_t>(e) + a])] = 0;
  Mesh r;
  r.order = 1;
  r.source = mesh.source;
  r.elem_file_id = mesh.elem_file_id;  // same elements, same order
  r.elem_line = mesh.elem_line;
  int n = 0;
  for (int v = 0; v < mesh.nnode(); ++v) {
    if (id[static_cast<size_t>(v)] < 0) continue;
    id[static_cast<size_t>(v)] = n++;
    r.X.insert(r.X.end(), mesh.X.begin() + 3 * static_cast<long>(v), mesh.X.begin() + 3 * static_cast<long>(v) + 3);
  }
  r.tet.resize(4 * static_cast<size_t>(ntet));
  for (int e = 0; e < ntet; ++e)
    for (int a = 0; a < 4; ++a) r.tet[4 * static_cast<size_t>(e) + a] = id[static_cast<size_t>(mesh.tet[10 * static_cast<size_t>(e) + a])];
  return r;
}

Mesh raise_to_tet10(const Mesh& mesh) {
  if (mesh.order == 2) return mesh;
  const int ntet = mesh.ntet();
  Mesh r;
  r.order = 2;
  r.source = mesh.source;
  r.elem_file_id = mesh.elem_file_id;  // same elements, same order
  r.elem_line = mesh.elem_line;
  r.X = mesh.X;
  r.tet.resize(10 * static_cast<size_t>(ntet));
  std::unordered_map<std::uint64_t, int> mid;  // (lower, higher corner id) -> mid-edge node
  mid.reserve(2 * static_cast<size_t>(ntet) + 16);
  for (int e = 0; e < ntet; ++e) {
    const int* t = &mesh.tet[4 * e];
    for (int a = 0; a < 4; ++a) r.tet[10 * e + a] = t[a];
    for (int k = 0; k < 6; ++k) {
      const int i = t[kTet10Edge[k][0]], j = t[kTet10Edge[k][1]];
      const std::uint64_t key = (std::uint64_t(std::min(i, j)) << 32) | std::uint32_t(std::max(i, j));
      auto [it, added] = mid.emplace(key, r.nnode());
      if (added)
        for (int c = 0; c < 3; ++c) r.X.push_back(0.5 * (mesh.X[3 * i + c] + mesh.X[3 * j + c]));
      r.tet[10 * e + 4 + k] = it->second;
    }
  }
  return r;
}

MeshQuality mesh_quality(const Mesh& mesh) {
  MeshQuality q;
  q.nnode = mesh.nnode();
  q.ntet = mesh.ntet();
  if (q.ntet == 0) return q;
  q.min_volume = INFINITY;
  q.max_volume = -INFINITY;
  q.min_dihedral_deg = INFINITY;
  q.max_dihedral_deg = -INFINITY;
  static const int opp[6][2] = {{2, 3}, {0, 3}, {1, 3}, {1, 2}, {0, 2}, {0, 1}};  // other corners of kTet10Edge[k]
  for (int e = 0; e < q.ntet; ++e) {
    const double v = mesh.order == 2 ? tet10_volume(mesh, e) : corner_volume(mesh, e);
    q.min_volume = std::min(q.min_volume, v);
    q.max_volume = std::max(q.max_volume, v);
    q.total_volume += v;
    const int* t = &mesh.tet[e * mesh.npe()];
    double lo = INFINITY, hi = -INFINITY;
    for (int k = 0; k < 6; ++k) {
      double a = dihedral(node(mesh, t[kTet10Edge[k][0]]), node(mesh, t[kTet10Edge[k][1]]), node(mesh, t[opp[k][0]]),
                          node(mesh, t[opp[k][1]])) *
                 180.0 / kPi;
      lo = std::min(lo, a);
      hi = std::max(hi, a);
    }
    if (lo < q.min_dihedral_deg) q.min_dihedral_deg = lo, q.worst_tet = e;
    q.max_dihedral_deg = std::max(q.max_dihedral_deg, hi);
  }
  return q;
}

std::string format_quality(const MeshQuality& q) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "nodes %d, tetrahedra %d\n"
                "volume: total %.6g, min %.3g, max %.3g\n"
                "dihedral angles: min %.2f deg (element %d), max %.2f deg\n",
                q.nnode, q.ntet, q.total_volume, q.min_volume, q.max_volume, q.min_dihedral_deg, q.worst_tet,
                q.max_dihedral_deg);
  return buf;
}

CoincidentNodes coincident_nodes(const Mesh& m) {
  std::vector<char> used(m.nnode(), 0);
  for (int n : m.tet)
    if (n >= 0 && n < m.nnode()) used[n] = 1;
  std::vector<int> ids;
  for (int i = 0; i < m.nnode(); ++i)
    if (used[i]) ids.push_back(i);
  const auto key = [&](int i) { return std::array<double, 3>{m.X[3 * i], m.X[3 * i + 1], m.X[3 * i + 2]}; };
  std::sort(ids.begin(), ids.end(), [&](int i, int j) { return key(i) != key(j) ? key(i) < key(j) : i < j; });
  CoincidentNodes c;
  for (size_t k = 1; k < ids.size(); ++k)
    if (key(ids[k]) == key(ids[k - 1])) {
      if (c.count++ == 0) c.a = std::min(ids[k - 1], ids[k]), c.b = std::max(ids[k - 1], ids[k]);
    }
  return c;
}

void check_mesh(const Mesh& m) {
  const std::string pre = prefix(m);
  if (m.order != 1 && m.order != 2) throw Error(pre + "order must be 1 (tet4) or 2 (tet10), got " + std::to_string(m.order));
  if (m.X.size() % 3) throw Error(pre + "X has " + std::to_string(m.X.size()) + " values, not a multiple of 3");
  if (m.tet.size() % m.npe())
    throw Error(pre + "tet has " + std::to_string(m.tet.size()) + " entries, not a multiple of " + std::to_string(m.npe()));
  for (size_t i = 0; i < m.X.size(); ++i)
    if (!std::isfinite(m.X[i]))
      throw Error(pre + "node " + std::to_string(i / 3) + " has a non-finite coordinate " + num(m.X[i]));
  const int npe = m.npe(), nnode = m.nnode();
  for (int e = 0; e < m.ntet(); ++e)
    for (int a = 0; a < npe; ++a) {
      const int n = m.tet[e * npe + a];
      if (n < 0 || n >= nnode)
        throw Error(pre + "element " + std::to_string(e) + " references node " + std::to_string(n) + ", but only " +
                    std::to_string(nnode) + " nodes are defined");
    }
  for (int e = 0; e < m.ntet(); ++e) {
    const double v = corner_volume(m, e);
    const int* t = &m.tet[e * npe];
    double l2 = 0;  // longest edge squared, to judge "nearly zero"
    for (const auto& ed : kTet10Edge) {
      V3 d = sub(node(m, t[ed[0]]), node(m, t[ed[1]]));
      l2 = std::max(l2, dot(d, d));
    }
    if (v <= 0)
      throw Error(element_prefix(m, e) + element_text(m, e) + " has volume " + num(v) +
                  " <= 0: inverted or degenerate; reorder its nodes or fix the mesh");
    if (v <= 1e-12 * l2 * std::sqrt(l2))
      throw Error(element_prefix(m, e) + element_text(m, e) + " has volume " + num(v) + ", nearly zero for its longest edge " +
                  num(std::sqrt(l2)) + ": degenerate; fix the mesh");
    if (npe != 10) continue;
    const std::vector<DetJPoint>& pts = tet10_check_points();
    for (size_t p = 0; p < pts.size(); ++p) {
      const double dj = tet10_detJ(m, e, pts[p].L);
      if (dj > 0) continue;
      char where[128];
      if (p < 10)
        std::snprintf(where, sizeof where, "at its node %d (%s)", static_cast<int>(p), pts[p].kind);
      else
        std::snprintf(where, sizeof where, "at a %s (barycentric %.4g %.4g %.4g %.4g)", pts[p].kind, pts[p].L[0],
                      pts[p].L[1], pts[p].L[2], pts[p].L[3]);
      throw Error(element_prefix(m, e) + element_text(m, e) + " has Jacobian determinant " + num(dj) + " <= 0 " + where +
                  ": the element folds (mid-edge nodes misplaced, too curved, or in the wrong order; expected "
                  "4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3) 8:(1,3) 9:(2,3))");
    }
  }
}

std::vector<std::array<double, 4>> tet10_check_points_barycentric() {
  std::vector<std::array<double, 4>> out;
  for (const DetJPoint& p : tet10_check_points()) out.push_back({p.L[0], p.L[1], p.L[2], p.L[3]});
  return out;
}

}  // namespace incise
