#include "cutting/xfem_layout.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numeric>

#include "cutting/subdivide.h"

namespace incise {

namespace {

enum Status : unsigned char { kAway = 0, kCut = 1, kFront = 2 };

struct UnionFind {
  std::vector<int> p;
  explicit UnionFind(int n) : p(n) { std::iota(p.begin(), p.end(), 0); }
  int find(int x) { return p[x] == x ? x : p[x] = find(p[x]); }
  void join(int a, int b) { p[find(a)] = find(b); }
};

struct Piece {
  int elem;
  std::vector<std::pair<int, signed char>> sides;  // (cut, side) for the cuts that split the element
  std::vector<int> subtets;                        // into the element's SubTets (empty: the whole element)
  double fraction;
};

// Area (in the face's barycentric plane, full face = 1/2) of the part of a
// face where every constraint s * phi >= 0 holds; phi3: phi at the 3 corners.
double overlap_area(const std::vector<std::pair<std::array<double, 3>, int>>& constraints) {
  std::vector<std::array<double, 2>> poly = {{0, 0}, {1, 0}, {0, 1}};  // (l1, l2); l0 = 1 - l1 - l2
  for (const auto& [phi3, s] : constraints) {
    auto f = [&](const std::array<double, 2>& p) {
      return s * ((1 - p[0] - p[1]) * phi3[0] + p[0] * phi3[1] + p[1] * phi3[2]);
    };
    std::vector<std::array<double, 2>> out;
    for (size_t i = 0; i < poly.size(); ++i) {
      const auto& a = poly[i];
      const auto& b = poly[(i + 1) % poly.size()];
      const double fa = f(a), fb = f(b);
      if (fa >= 0) out.push_back(a);
      if ((fa > 0 && fb < 0) || (fa < 0 && fb > 0)) {
        const double t = fa / (fa - fb);
        out.push_back({a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])});
      }
    }
    poly.swap(out);
    if (poly.size() < 3) return 0.0;
  }
  double area = 0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const auto& a = poly[i];
    const auto& b = poly[(i + 1) % poly.size()];
    area += a[0] * b[1] - a[1] * b[0];
  }
  return 0.5 * std::abs(area);
}

}  // namespace

CutLayout compute_cut_layout(const Model& base, const std::vector<const CutSurface*>& cuts, CutReport* report) {
  const Mesh& mesh = base.mesh;
  const int npe = mesh.npe(), nt = mesh.ntet(), nn = mesh.nnode(), ncut = static_cast<int>(cuts.size());
  auto node = [&](int e, int a) { return mesh.tet[static_cast<size_t>(e) * npe + a]; };
  CutReport rep;

  // Level sets at the corner nodes (exact signs, phi == 0 iff on the surface).
  std::vector<char> is_corner(nn, 0);
  for (int e = 0; e < nt; ++e)
    for (int k = 0; k < 4; ++k) is_corner[node(e, k)] = 1;
  std::vector<double> phi(static_cast<size_t>(ncut) * nn, 0.0);
  std::vector<signed char> sgn(static_cast<size_t>(ncut) * nn, 0);
  for (int c = 0; c < ncut; ++c)
    for (int i = 0; i < nn; ++i)
      if (is_corner[i]) {
        const auto v = cuts[c]->value(&mesh.X[3 * i]);
        phi[static_cast<size_t>(c) * nn + i] = v.phi;
        sgn[static_cast<size_t>(c) * nn + i] = static_cast<signed char>(v.sign);
      }
  auto h_of = [&](int e) {
    double h = 0;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        double d2 = 0;
        for (int d = 0; d < 3; ++d) d2 += std::pow(mesh.X[3 * node(e, a) + d] - mesh.X[3 * node(e, b) + d], 2);
        h = std::max(h, std::sqrt(d2));
      }
    return h;
  };

  // Classification: per element, the cuts that split it (fully crossed), then
  // cuts that end on one of those inside the element (a T junction), which
  // split only the side of that cut where they are on the surface.
  struct ElemCut {
    int cut;
    int only = -1;      // index into the element's list of the cut it ends on
    int only_side = 0;  // side of that cut it splits
  };
  std::vector<std::vector<ElemCut>> cuts_of(nt);
  for (int e = 0; e < nt; ++e) {
    const double tol = 1e-9 * h_of(e);
    struct Crossing {
      double y[3];
      double l[4];  // barycentric position in the element
      bool covered;
    };
    std::vector<std::pair<int, std::vector<Crossing>>> partial;
    for (int c = 0; c < ncut; ++c) {
      int npos = 0, nneg = 0;
      for (int k = 0; k < 4; ++k) {
        const int s = sgn[static_cast<size_t>(c) * nn + node(e, k)];
        npos += s > 0;
        nneg += s < 0;
      }
      if (npos == 0 || nneg == 0) continue;
      std::vector<Crossing> xs;
      bool all = true;
      for (int a = 0; a < 4; ++a) {
        const int ia = node(e, a);
        const double fa = phi[static_cast<size_t>(c) * nn + ia];
        if (fa == 0.0) {
          Crossing x{{mesh.X[3 * ia], mesh.X[3 * ia + 1], mesh.X[3 * ia + 2]}, {0, 0, 0, 0}, false};
          x.l[a] = 1.0;
          x.covered = cuts[c]->covers(x.y, tol);
          all = all && x.covered;
          xs.push_back(x);
        }
        for (int b = a + 1; b < 4; ++b) {
          const int ib = node(e, b);
          const double fb = phi[static_cast<size_t>(c) * nn + ib];
          if (!((fa > 0 && fb < 0) || (fa < 0 && fb > 0))) continue;
          const double t = fa / (fa - fb);
          Crossing x{{0, 0, 0}, {0, 0, 0, 0}, false};
          for (int d = 0; d < 3; ++d) x.y[d] = mesh.X[3 * ia + d] + t * (mesh.X[3 * ib + d] - mesh.X[3 * ia + d]);
          x.l[a] = 1.0 - t;
          x.l[b] = t;
          x.covered = cuts[c]->covers(x.y, tol);
          all = all && x.covered;
          xs.push_back(x);
        }
      }
      if (all) cuts_of[e].push_back({c});
      else partial.push_back({c, xs});
    }
    for (const auto& [c, xs] : partial) {
      bool placed = false;
      const int nfull = static_cast<int>(cuts_of[e].size());
      for (int j = 0; j < nfull && !placed; ++j) {
        if (cuts_of[e][j].only >= 0) continue;
        const int cj = cuts_of[e][j].cut;
        double scale = 0;
        for (int k = 0; k < 4; ++k) scale = std::max(scale, std::abs(phi[static_cast<size_t>(cj) * nn + node(e, k)]));
        for (int side : {1, -1}) {
          // covered crossings strictly on `side` of cut cj, uncovered ones not
          bool ok = true, any = false;
          for (const Crossing& x : xs) {
            double f = 0;
            for (int k = 0; k < 4; ++k) f += x.l[k] * phi[static_cast<size_t>(cj) * nn + node(e, k)];
            const double sf = side * f;
            if (x.covered) {
              any = any || sf > 1e-12 * scale;
              ok = ok && sf >= -1e-12 * scale;
            } else {
              ok = ok && sf <= 1e-12 * scale;
            }
          }
          if (ok && any) {
            cuts_of[e].push_back({c, j, side});
            placed = true;
            break;
          }
        }
      }
      if (!placed) ++rep.front_elements;
    }
  }

  // Faces: interior pairs, and faces lying exactly on a covered surface.
  struct FacePair { int e, ke, f, kf; };
  std::vector<FacePair> pairs(base.tet_face_pair.size() / 4);  // the mesh's, found once (Model::tet_face_pair)
  for (size_t p = 0; p < pairs.size(); ++p)
    pairs[p] = {base.tet_face_pair[4 * p], base.tet_face_pair[4 * p + 1], base.tet_face_pair[4 * p + 2],
                base.tet_face_pair[4 * p + 3]};
  CutLayout L;
  L.elem_face_cut.assign(4 * static_cast<size_t>(nt), 0);
  std::vector<char> separated(pairs.size(), 0);
  for (size_t p = 0; p < pairs.size(); ++p) {
    const auto& fp = pairs[p];
    const int tri[3] = {node(fp.e, kTetFace[fp.ke][0]), node(fp.e, kTetFace[fp.ke][1]),
                        node(fp.e, kTetFace[fp.ke][2])};
    const double tol = 1e-9 * h_of(fp.e);
    for (int c = 0; c < ncut && !separated[p]; ++c) {
      bool in_plane = true;
      for (int i : tri) in_plane = in_plane && sgn[static_cast<size_t>(c) * nn + i] == 0;
      if (!in_plane) continue;
      double cen[3] = {0, 0, 0};
      bool covered = true;
      for (int i : tri) {
        covered = covered && cuts[c]->covers(&mesh.X[3 * i], tol);
        for (int d = 0; d < 3; ++d) cen[d] += mesh.X[3 * i + d] / 3.0;
      }
      if (covered && cuts[c]->covers(cen, tol)) separated[p] = 1;
    }
    if (separated[p]) {
      L.elem_face_cut[4 * fp.e + fp.ke] = L.elem_face_cut[4 * fp.f + fp.kf] = 1;
      ++rep.separated_faces;
    }
  }

  // Pieces.
  std::vector<Piece> pieces;
  std::vector<int> elem_piece_ptr(1, 0);
  std::vector<SubTets> subs(nt);
  for (int e = 0; e < nt; ++e) {
    if (cuts_of[e].empty()) {
      pieces.push_back({e, {}, {}, 1.0});
    } else {
      const int nc = static_cast<int>(cuts_of[e].size());
      std::vector<double> ph(4 * static_cast<size_t>(nc));
      std::vector<int> only(2 * static_cast<size_t>(nc));
      for (int j = 0; j < nc; ++j) {
        for (int k = 0; k < 4; ++k) ph[4 * j + k] = phi[static_cast<size_t>(cuts_of[e][j].cut) * nn + node(e, k)];
        only[2 * j] = cuts_of[e][j].only;
        only[2 * j + 1] = cuts_of[e][j].only_side;
      }
      subs[e] = subdivide_tet(ph, nc, only);
      std::map<std::vector<signed char>, std::vector<int>> groups;
      for (int t = 0; t < subs[e].size(); ++t)
        groups[std::vector<signed char>(subs[e].side.begin() + t * nc, subs[e].side.begin() + (t + 1) * nc)].push_back(t);
      ++rep.cut_elements;
      for (const auto& [sv, ts] : groups) {
        double frac = 0;
        for (int t : ts) frac += 6.0 * subs[e].volume[t];
        if (!(frac > 0)) continue;
        Piece P{e, {}, ts, frac};
        for (int j = 0; j < nc; ++j)
          if (sv[j] != 0) P.sides.push_back({cuts_of[e][j].cut, sv[j]});
        pieces.push_back(P);
        ++rep.pieces;
        rep.min_fraction = std::min(rep.min_fraction, frac);
      }
    }
    elem_piece_ptr.push_back(static_cast<int>(pieces.size()));
  }
  const int np = static_cast<int>(pieces.size());

  // Piece connectivity across shared faces.
  std::vector<std::vector<int>> adj(np);
  for (size_t p = 0; p < pairs.size(); ++p) {
    if (separated[p]) continue;
    const auto& fp = pairs[p];
    const bool simple = cuts_of[fp.e].empty() && cuts_of[fp.f].empty();
    const int tri[3] = {node(fp.e, kTetFace[fp.ke][0]), node(fp.e, kTetFace[fp.ke][1]),
                        node(fp.e, kTetFace[fp.ke][2])};
    for (int P = elem_piece_ptr[fp.e]; P < elem_piece_ptr[fp.e + 1]; ++P)
      for (int Q = elem_piece_ptr[fp.f]; Q < elem_piece_ptr[fp.f + 1]; ++Q) {
        bool connected = simple;
        if (!simple) {
          std::vector<std::pair<std::array<double, 3>, int>> cons;
          bool clash = false;
          for (const auto* S : {&pieces[P].sides, &pieces[Q].sides})
            for (const auto& [c, s] : *S) {
              for (const auto& [c2, s2] : pieces[P].sides)
                if (c2 == c && s2 != s) clash = true;
              for (const auto& [c2, s2] : pieces[Q].sides)
                if (c2 == c && s2 != s) clash = true;
              std::array<double, 3> f3;
              for (int i = 0; i < 3; ++i) f3[i] = phi[static_cast<size_t>(c) * nn + tri[i]];
              cons.push_back({f3, s});
            }
          // any positive overlap: a sliver 1e-12 h thin still connects to its neighbours
          connected = !clash && overlap_area(cons) > 0.0;
        }
        if (connected) {
          adj[P].push_back(Q);
          adj[Q].push_back(P);
        }
      }
  }

  {
    UnionFind all(np);
    for (int P = 0; P < np; ++P)
      for (int Q : adj[P]) all.join(P, Q);
    rep.bodies = 0;
    for (int P = 0; P < np; ++P) rep.bodies += all.find(P) == P;
  }

  // Regions of each node's support; only nodes touching split elements or
  // separated faces can have more than one.
  std::vector<char> candidate(nn, 0);
  for (int e = 0; e < nt; ++e)
    if (!cuts_of[e].empty())
      for (int a = 0; a < npe; ++a) candidate[node(e, a)] = 1;
  for (size_t p = 0; p < pairs.size(); ++p)
    if (separated[p])
      for (int a = 0; a < npe; ++a) candidate[node(pairs[p].e, a)] = 1;
  L.piece_enr.assign(static_cast<size_t>(np) * npe, -1);
  std::vector<int> enr_node;
  for (int i = 0; i < nn; ++i) {
    if (!candidate[i]) continue;
    std::vector<int> sp;  // pieces of the support
    for (int k = base.node_elem_ptr[i]; k < base.node_elem_ptr[i + 1]; ++k)
      for (int P = elem_piece_ptr[base.node_elem[k]]; P < elem_piece_ptr[base.node_elem[k] + 1]; ++P) sp.push_back(P);
    std::map<int, int> local;
    for (size_t k = 0; k < sp.size(); ++k) local[sp[k]] = static_cast<int>(k);
    UnionFind uf(static_cast<int>(sp.size()));
    for (size_t k = 0; k < sp.size(); ++k)
      for (int Q : adj[sp[k]])
        if (auto it = local.find(Q); it != local.end()) uf.join(static_cast<int>(k), it->second);
    std::map<int, double> volume;  // root -> volume
    std::map<int, int> first;      // root -> smallest piece id (deterministic ties)
    for (size_t k = 0; k < sp.size(); ++k) {
      const int r = uf.find(static_cast<int>(k));
      volume[r] += pieces[sp[k]].fraction * base.elem_volume[pieces[sp[k]].elem];
      if (!first.count(r)) first[r] = sp[k];
    }
    if (volume.size() < 2) continue;
    int home = -1;
    for (const auto& [r, v] : volume)
      if (home < 0 || v > volume[home] || (v == volume[home] && first[r] < first[home])) home = r;
    std::map<int, int> enr;  // root -> enriched DOF node
    for (const auto& [r, v] : volume)
      if (r != home) {
        enr[r] = nn + static_cast<int>(enr_node.size());
        enr_node.push_back(i);
      }
    for (size_t k = 0; k < sp.size(); ++k) {
      const int r = uf.find(static_cast<int>(k));
      if (r == home) continue;
      const Piece& P = pieces[sp[k]];
      for (int a = 0; a < npe; ++a)
        if (node(P.elem, a) == i) L.piece_enr[static_cast<size_t>(sp[k]) * npe + a] = enr[r];
    }
  }

  // Output arrays.
  L.n_enriched = static_cast<int>(enr_node.size());
  L.enr_node = enr_node;
  L.elem_piece_ptr = elem_piece_ptr;
  L.elem_split.assign(nt, 0);
  L.piece_subtet_ptr.assign(1, 0);
  static const double kRef[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (const Piece& P : pieces) {
    if (P.subtets.empty()) {
      L.subtet_rst.insert(L.subtet_rst.end(), kRef, kRef + 12);
      L.subtet_face.insert(L.subtet_face.end(), {0, 1, 2, 3});
    } else {
      L.elem_split[P.elem] = 1;
      const SubTets& S = subs[P.elem];
      for (int t : P.subtets) {
        L.subtet_rst.insert(L.subtet_rst.end(), S.rst.begin() + 12 * t, S.rst.begin() + 12 * (t + 1));
        L.subtet_face.insert(L.subtet_face.end(), S.face.begin() + 4 * t, S.face.begin() + 4 * (t + 1));
      }
    }
    L.piece_subtet_ptr.push_back(static_cast<int>(L.subtet_face.size() / 4));
    L.piece_fraction.push_back(P.fraction);
  }
  rep.enriched_nodes = L.n_enriched;
  if (report) *report = rep;
  return L;
}

}  // namespace incise
