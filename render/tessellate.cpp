#include "render/tessellate.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

namespace incise {
namespace {

// Position (x) and unnormalised normal (n = dx/dxi x dx/deta) of face f at
// barycentric point L, with xi = L1, eta = L2. P(i, d): coordinate d of face node i.
template <class P>
void eval_face(int npf, const double* L, const P& node, double x[3], double n[3]) {
  double N[6], Nxi[6], Neta[6];
  if (npf == 3) {
    N[0] = L[0], N[1] = L[1], N[2] = L[2];
    Nxi[0] = -1, Nxi[1] = 1, Nxi[2] = 0;
    Neta[0] = -1, Neta[1] = 0, Neta[2] = 1;
  } else {  // quadratic triangle: corners L(2L-1), mid-edges 4 Li Lj (edges 0-1, 1-2, 2-0)
    const double a = L[0], b = L[1], c = L[2];
    N[0] = a * (2 * a - 1), N[1] = b * (2 * b - 1), N[2] = c * (2 * c - 1);
    N[3] = 4 * a * b, N[4] = 4 * b * c, N[5] = 4 * c * a;
    Nxi[0] = 1 - 4 * a, Nxi[1] = 4 * b - 1, Nxi[2] = 0, Nxi[3] = 4 * (a - b), Nxi[4] = 4 * c, Nxi[5] = -4 * c;
    Neta[0] = 1 - 4 * a, Neta[1] = 0, Neta[2] = 4 * c - 1, Neta[3] = -4 * b, Neta[4] = 4 * b, Neta[5] = 4 * (a - c);
  }
  double tx[3] = {0, 0, 0}, te[3] = {0, 0, 0};
  for (int d = 0; d < 3; ++d) x[d] = 0;
  for (int i = 0; i < npf; ++i)
    for (int d = 0; d < 3; ++d) {
      const double p = node(i, d);
      x[d] += N[i] * p, tx[d] += Nxi[i] * p, te[d] += Neta[i] * p;
    }
  n[0] = tx[1] * te[2] - tx[2] * te[1];
  n[1] = tx[2] * te[0] - tx[0] * te[2];
  n[2] = tx[0] * te[1] - tx[1] * te[0];
}

}  // namespace

Tessellation build_tessellation(const Surface& s, const DisplayMesh& m, int segments) {
  Tessellation t;
  const FaceGrid fg = face_grid(face_segments(s.order, segments));
  const int npf = s.npf();
  t.segments = fg.segments;
  t.verts_per_face = fg.verts_per_face;
  t.tris_per_face = fg.tris_per_face;
  t.grid = fg.weights;
  // Integer weights w = (n - i - j, i, j) identify a grid vertex on the face edges for sharing.
  auto w = [&fg](int g) { return &fg.steps[3 * static_cast<size_t>(g)]; };
  const int nface = s.nface(), vpf = t.verts_per_face;
  t.tris.reserve(static_cast<size_t>(nface) * t.tris_per_face * 3);
  for (int f = 0; f < nface; ++f) {
    const unsigned base = static_cast<unsigned>(f * vpf);
    for (int v : fg.tris) t.tris.push_back(base + static_cast<unsigned>(v));
  }

  // Smoothing groups. Key: (kind, point a, weight a, point b, weight b) for a
  // vertex on a corner or face edge; interior grid vertices are their own group.
  // Within a key, vertices split into clusters by reference normal (crease).
  struct Cluster {
    double n[3];
    int group;
  };
  std::map<std::array<int, 5>, std::vector<Cluster>> shared;
  const double cos_crease = std::cos(kCreaseDeg * M_PI / 180.0);
  t.group.resize(static_cast<size_t>(nface) * vpf);
  for (int f = 0; f < nface; ++f) {
    const int* fn = &s.face_nodes[static_cast<size_t>(f) * npf];
    auto ref = [&](int i, int d) { return m.X[3 * fn[i] + d]; };
    const int kind = f < s.nboundary ? 0 : 1;
    for (int g = 0; g < vpf; ++g) {
      int nz = 0, ids[3], wts[3];
      for (int k = 0; k < 3; ++k)
        if (w(g)[k] > 0) ids[nz] = fn[k], wts[nz] = w(g)[k], ++nz;
      int& out = t.group[static_cast<size_t>(f) * vpf + g];
      if (nz == 3) {
        out = t.ngroup++;
        continue;
      }
      std::array<int, 5> key{kind, ids[0], wts[0], -1, 0};
      if (nz == 2) {
        if (ids[1] < ids[0]) std::swap(ids[0], ids[1]), std::swap(wts[0], wts[1]);
        key = {kind, ids[0], wts[0], ids[1], wts[1]};
      }
      double x[3], nr[3];
      eval_face(npf, &t.grid[3 * g], ref, x, nr);
      const double len = std::sqrt(nr[0] * nr[0] + nr[1] * nr[1] + nr[2] * nr[2]);
      if (len > 0)
        for (double& c : nr) c /= len;
      auto& clusters = shared[key];
      out = -1;
      for (const Cluster& c : clusters)
        if (c.n[0] * nr[0] + c.n[1] * nr[1] + c.n[2] * nr[2] >= cos_crease) {
          out = c.group;
          break;
        }
      if (out < 0) {
        out = t.ngroup++;
        clusters.push_back({{nr[0], nr[1], nr[2]}, out});
      }
    }
  }
  return t;
}

void tessellate(const Surface& s, const Tessellation& t, const DisplayMesh& m, std::vector<float>& pos,
                std::vector<float>& nrm, std::vector<double>& work) {
  const int nface = s.nface(), vpf = t.verts_per_face, npf = s.npf();
  const size_t nv = static_cast<size_t>(t.nvert());
  pos.resize(3 * nv);
  nrm.resize(3 * nv);
  work.assign(3 * static_cast<size_t>(t.ngroup), 0.0);  // (ngroup, 3) summed normals
  for (int f = 0; f < nface; ++f) {
    const int* fn = &s.face_nodes[static_cast<size_t>(f) * npf];
    auto cur = [&](int i, int d) { return m.x(fn[i], d); };
    for (int g = 0; g < vpf; ++g) {
      const size_t v = static_cast<size_t>(f) * vpf + g;
      double x[3], n[3];
      eval_face(npf, &t.grid[3 * g], cur, x, n);
      // Area-weighted sum: the unnormalised normal scales with the local area.
      double* acc = &work[3 * static_cast<size_t>(t.group[v])];
      for (int d = 0; d < 3; ++d) pos[3 * v + d] = static_cast<float>(x[d]), acc[d] += n[d];
    }
  }
  for (size_t v = 0; v < nv; ++v) {
    const double* a = &work[3 * static_cast<size_t>(t.group[v])];
    const double len = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    for (int d = 0; d < 3; ++d)
      nrm[3 * v + d] = len > 0 ? static_cast<float>(a[d] / len) : (d == 2 ? 1.0f : 0.0f);
  }
}

}  // namespace incise
