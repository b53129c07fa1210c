#include "cutting/xfem_layout.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numeric>
#include <string>

#include "cutting/subdivide.h"
#include "engine/model/front_enrichment.h"
#include "engine/util/error.h"

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

// The mesh, the cuts, and the cuts' level sets at the mesh's corner nodes.
struct LevelSets {
  const Mesh& mesh;
  const std::vector<const CutSurface*>& cuts;
  int npe, nt, nn, ncut;
  std::vector<double> phi;       // (ncut, nn) level set at the corner nodes, 0 at the others
  std::vector<signed char> sgn;  // (ncut, nn) its exact sign
  int node(int e, int a) const { return mesh.tet[static_cast<size_t>(e) * npe + a]; }
  double at(int c, int i) const { return phi[static_cast<size_t>(c) * nn + i]; }
};

// The level sets (signed distance, [preprint] eq. (72)) at the corner nodes,
// with exact signs: phi == 0 iff the node is on the surface.
LevelSets corner_level_sets(const Mesh& mesh, const std::vector<const CutSurface*>& cuts) {
  LevelSets ls{mesh, cuts, mesh.npe(), mesh.ntet(), mesh.nnode(), static_cast<int>(cuts.size()), {}, {}};
  std::vector<char> is_corner(ls.nn, 0);
  for (int e = 0; e < ls.nt; ++e)
    for (int k = 0; k < 4; ++k) is_corner[ls.node(e, k)] = 1;
  ls.phi.assign(static_cast<size_t>(ls.ncut) * ls.nn, 0.0);
  ls.sgn.assign(static_cast<size_t>(ls.ncut) * ls.nn, 0);
  for (int c = 0; c < ls.ncut; ++c)
    for (int i = 0; i < ls.nn; ++i)
      if (is_corner[i]) {
        const auto v = cuts[c]->value(&mesh.X[3 * i]);
        ls.phi[static_cast<size_t>(c) * ls.nn + i] = v.phi;
        ls.sgn[static_cast<size_t>(c) * ls.nn + i] = static_cast<signed char>(v.sign);
      }
  return ls;
}

// Longest corner-to-corner edge of element e.
double element_size(const LevelSets& ls, int e) {
  const std::vector<double>& X = ls.mesh.X;
  double h = 0;
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) {
      double d2 = 0;
      for (int d = 0; d < 3; ++d) d2 += std::pow(X[3 * ls.node(e, a) + d] - X[3 * ls.node(e, b) + d], 2);
      h = std::max(h, std::sqrt(d2));
    }
  return h;
}

// A cut of an element: the cut, and for a cut that ends on an earlier one
// inside the element (a T junction) the side of that one it splits.
struct ElemCut {
  int cut;
  int only = -1;      // index into the element's list of the cut it ends on
  int only_side = 0;  // side of that cut it splits
};

// A zero of a cut's level set on a corner or an edge of an element.
struct Crossing {
  double y[3];
  double l[4];  // barycentric position in the element
  bool covered;
};

// Whether cut c has corners of element e strictly on both sides ([preprint]
// eq. (73), with exact signs).
bool crosses(const LevelSets& ls, int e, int c) {
  int npos = 0, nneg = 0;
  for (int k = 0; k < 4; ++k) {
    const int s = ls.sgn[static_cast<size_t>(c) * ls.nn + ls.node(e, k)];
    npos += s > 0;
    nneg += s < 0;
  }
  return npos > 0 && nneg > 0;
}

// Appends to xs the corners of element e on cut c and the zeros of its
// level set on the edges (linear along them), each marked covered when it
// lies on the surface's extent (within tol). Returns whether all are covered.
bool find_crossings(const LevelSets& ls, int e, int c, double tol, std::vector<Crossing>& xs) {
  const std::vector<double>& X = ls.mesh.X;
  bool all = true;
  for (int a = 0; a < 4; ++a) {
    const int ia = ls.node(e, a);
    const double fa = ls.at(c, ia);
    if (fa == 0.0) {
      Crossing x{{X[3 * ia], X[3 * ia + 1], X[3 * ia + 2]}, {0, 0, 0, 0}, false};
      x.l[a] = 1.0;
      x.covered = ls.cuts[c]->covers(x.y, tol);
      all = all && x.covered;
      xs.push_back(x);
    }
    for (int b = a + 1; b < 4; ++b) {
      const int ib = ls.node(e, b);
      const double fb = ls.at(c, ib);
      if (!((fa > 0 && fb < 0) || (fa < 0 && fb > 0))) continue;
      const double t = fa / (fa - fb);
      Crossing x{{0, 0, 0}, {0, 0, 0, 0}, false};
      for (int d = 0; d < 3; ++d) x.y[d] = X[3 * ia + d] + t * (X[3 * ib + d] - X[3 * ia + d]);
      x.l[a] = 1.0 - t;
      x.l[b] = t;
      // On the surface, or (a curved or kinked surface, whose nearest-facet
      // zero strays from its facets) the edge passes through a facet: a
      // cylinder's arc or a plane bent by 1 degree cut nothing before.
      x.covered = ls.cuts[c]->covers(x.y, tol) || ls.cuts[c]->crosses_segment(&X[3 * ia], &X[3 * ib], tol);
      all = all && x.covered;
      xs.push_back(x);
    }
  }
  return all;
}

// Whether a partial cut with crossings xs ends on full cut cj inside element
// e, on `side` of it: its covered crossings strictly on that side, its
// uncovered ones not (scale: cj's largest corner |phi|, for the tolerance).
bool ends_on_side(const LevelSets& ls, int e, int cj, int side, double scale, const std::vector<Crossing>& xs) {
  bool ok = true, any = false;
  for (const Crossing& x : xs) {
    double f = 0;
    for (int k = 0; k < 4; ++k) f += x.l[k] * ls.at(cj, ls.node(e, k));
    const double sf = side * f;
    if (x.covered) {
      any = any || sf > 1e-12 * scale;
      ok = ok && sf >= -1e-12 * scale;
    } else {
      ok = ok && sf <= 1e-12 * scale;
    }
  }
  return ok && any;
}

// Adds to element e's cuts `ec` each partial cut that ends on one of its full
// cuts (a T junction); the others leave e a cut front element.
void place_partial_cuts(const LevelSets& ls, int e, const std::vector<std::pair<int, std::vector<Crossing>>>& partial,
                        std::vector<ElemCut>& ec, CutReport& rep, std::vector<std::pair<int, int>>& fronts) {
  for (const auto& [c, xs] : partial) {
    bool placed = false;
    const int nfull = static_cast<int>(ec.size());
    for (int j = 0; j < nfull && !placed; ++j) {
      if (ec[j].only >= 0) continue;
      const int cj = ec[j].cut;
      double scale = 0;
      for (int k = 0; k < 4; ++k) scale = std::max(scale, std::abs(ls.at(cj, ls.node(e, k))));
      for (int side : {1, -1})
        if (ends_on_side(ls, e, cj, side, scale, xs)) {
          ec.push_back({c, j, side});
          placed = true;
          break;
        }
    }
    // The front passes through e where the surface covers some of its
    // crossings (not all: then it would be cut); with none covered e only
    // straddles the plane of a bounded surface, away from it.
    if (!placed && std::any_of(xs.begin(), xs.end(), [](const Crossing& x) { return x.covered; })) {
      ++rep.front_elements;
      fronts.push_back({e, c});
    }
  }
}

// Classification: per element, the cuts that split it (fully crossed), then
// cuts that end on one of those inside the element (a T junction), which
// split only the side of that cut where they are on the surface.
// fronts: (element, cut) for each cut whose front passes through the element.
std::vector<std::vector<ElemCut>> classify_elements(const LevelSets& ls, CutReport& rep,
                                                    std::vector<std::pair<int, int>>& fronts) {
  std::vector<std::vector<ElemCut>> cuts_of(ls.nt);
  for (int e = 0; e < ls.nt; ++e) {
    const double tol = 1e-9 * element_size(ls, e);
    std::vector<std::pair<int, std::vector<Crossing>>> partial;
    for (int c = 0; c < ls.ncut; ++c) {
      if (!crosses(ls, e, c)) continue;
      std::vector<Crossing> xs;
      if (find_crossings(ls, e, c, tol, xs)) cuts_of[e].push_back({c});
      else partial.push_back({c, xs});
    }
    place_partial_cuts(ls, e, partial, cuts_of[e], rep, fronts);
  }
  return cuts_of;
}

struct FacePair {
  int e, ke, f, kf;  // face ke of element e is face kf of element f
};

// The mesh's interior faces, found once (Model::tet_face_pair).
std::vector<FacePair> face_pairs(const Model& base) {
  std::vector<FacePair> pairs(base.tet_face_pair.size() / 4);
  for (size_t p = 0; p < pairs.size(); ++p)
    pairs[p] = {base.tet_face_pair[4 * p], base.tet_face_pair[4 * p + 1], base.tet_face_pair[4 * p + 2],
                base.tet_face_pair[4 * p + 3]};
  return pairs;
}

// Corner nodes of face k of element e.
std::array<int, 3> face_corners(const LevelSets& ls, int e, int k) {
  return {ls.node(e, kTetFace[k][0]), ls.node(e, kTetFace[k][1]), ls.node(e, kTetFace[k][2])};
}

// Whether the face with corners tri lies exactly on cut c, within its extent.
bool face_on_cut(const LevelSets& ls, const std::array<int, 3>& tri, int c, double tol) {
  bool in_plane = true;
  for (int i : tri) in_plane = in_plane && ls.sgn[static_cast<size_t>(c) * ls.nn + i] == 0;
  if (!in_plane) return false;
  double cen[3] = {0, 0, 0};
  bool covered = true;
  for (int i : tri) {
    covered = covered && ls.cuts[c]->covers(&ls.mesh.X[3 * i], tol);
    for (int d = 0; d < 3; ++d) cen[d] += ls.mesh.X[3 * i + d] / 3.0;
  }
  return covered && ls.cuts[c]->covers(cen, tol);
}

// Interior faces lying exactly on a covered surface: they separate their two
// elements (marked in L.elem_face_cut). Returns (npairs) 1 where separated.
std::vector<char> separate_faces(const LevelSets& ls, const std::vector<FacePair>& pairs, CutLayout& L,
                                 CutReport& rep) {
  L.elem_face_cut.assign(4 * static_cast<size_t>(ls.nt), 0);
  std::vector<char> separated(pairs.size(), 0);
  for (size_t p = 0; p < pairs.size(); ++p) {
    const auto& fp = pairs[p];
    const std::array<int, 3> tri = face_corners(ls, fp.e, fp.ke);
    const double tol = 1e-9 * element_size(ls, fp.e);
    for (int c = 0; c < ls.ncut && !separated[p]; ++c)
      if (face_on_cut(ls, tri, c, tol)) separated[p] = 1;
    if (separated[p]) {
      L.elem_face_cut[4 * fp.e + fp.ke] = L.elem_face_cut[4 * fp.f + fp.kf] = 1;
      ++rep.separated_faces;
    }
  }
  return separated;
}

struct PieceSet {
  std::vector<Piece> pieces;
  std::vector<int> elem_piece_ptr{0};  // (nelem + 1) into pieces
  std::vector<SubTets> subs;           // (nelem) sub-tetrahedra of each split element
};

// Splits element e by its cuts ec into sub-tetrahedra (sub-element
// integration, [preprint] eq. (52) and sec. 5.2) and groups them into pieces
// by their side of each cut; pieces of zero volume are dropped.
void split_element(const LevelSets& ls, int e, const std::vector<ElemCut>& ec, PieceSet& ps, CutReport& rep) {
  const int nc = static_cast<int>(ec.size());
  std::vector<double> ph(4 * static_cast<size_t>(nc));
  std::vector<int> only(2 * static_cast<size_t>(nc));
  for (int j = 0; j < nc; ++j) {
    for (int k = 0; k < 4; ++k) ph[4 * j + k] = ls.at(ec[j].cut, ls.node(e, k));
    only[2 * j] = ec[j].only;
    only[2 * j + 1] = ec[j].only_side;
  }
  SubTets& sub = ps.subs[e];
  sub = subdivide_tet(ph, nc, only);
  std::map<std::vector<signed char>, std::vector<int>> groups;
  for (int t = 0; t < sub.size(); ++t)
    groups[std::vector<signed char>(sub.side.begin() + t * nc, sub.side.begin() + (t + 1) * nc)].push_back(t);
  ++rep.cut_elements;
  for (const auto& [sv, ts] : groups) {
    double frac = 0;
    for (int t : ts) frac += 6.0 * sub.volume[t];
    if (!(frac > 0)) continue;
    Piece P{e, {}, ts, frac};
    for (int j = 0; j < nc; ++j)
      if (sv[j] != 0) P.sides.push_back({ec[j].cut, sv[j]});
    ps.pieces.push_back(P);
    ++rep.pieces;
    rep.min_fraction = std::min(rep.min_fraction, frac);
  }
}

// An element the front of cut c passes through, under front enrichment: one
// piece, integrated over the sub-tetrahedra of its cut plane (phi = 0) and
// front plane (psi = 0), inside each of which F is smooth. The element is
// not opened by pieces (its branch DOFs open it): of their faces on those
// planes, the ones on the cut behind the front keep the cut tag (4, the
// display draws them), the others are tagged inside (5).
void split_front_element(const LevelSets& ls, int e, int c, const CutLayout& L, PieceSet& ps) {
  std::vector<double> ph(8);
  int npos = 0, nneg = 0;
  double scale = 0;
  for (int k = 0; k < 4; ++k) {
    ph[k] = ls.at(c, ls.node(e, k));
    ph[4 + k] = L.front_psi[ls.node(e, k)];
    npos += ph[4 + k] > 0;
    nneg += ph[4 + k] < 0;
    scale = std::max(scale, std::abs(ph[k]));
  }
  const std::vector<double> level = ph;  // phi, psi at the corners
  const int nc = npos > 0 && nneg > 0 ? 2 : 1;
  ph.resize(4 * static_cast<size_t>(nc));
  SubTets& sub = ps.subs[e];
  sub = subdivide_tet(ph, nc);
  auto at = [&](int which, const double* r) {  // phi (0) or psi (1) at local point r
    const double* f = &level[4 * static_cast<size_t>(which)];
    return (1 - r[0] - r[1] - r[2]) * f[0] + r[0] * f[1] + r[1] * f[2] + r[2] * f[3];
  };
  for (int t = 0; t < sub.size(); ++t)
    for (int k = 0; k < 4; ++k) {
      signed char& tag = sub.face[4 * static_cast<size_t>(t) + k];
      if (tag != 4) continue;
      bool on_cut = true;
      double cen[3] = {0, 0, 0};
      for (int j = 0; j < 4; ++j) {
        if (j == k) continue;
        const double* v = &sub.rst[12 * static_cast<size_t>(t) + 3 * j];
        on_cut = on_cut && std::abs(at(0, v)) <= 1e-9 * scale;
        for (int d = 0; d < 3; ++d) cen[d] += v[d] / 3;
      }
      tag = on_cut && at(1, cen) < 0 ? 4 : 5;
    }
  Piece P{e, {}, {}, 0.0};
  for (int t = 0; t < sub.size(); ++t) {
    P.subtets.push_back(t);
    P.fraction += 6.0 * sub.volume[t];
  }
  ps.pieces.push_back(P);
}

// The pieces of every element: an uncut element is one whole piece; tip:
// (nelem) the cut whose front passes through the element under front
// enrichment, else -1 (empty: none).
PieceSet make_pieces(const LevelSets& ls, const std::vector<std::vector<ElemCut>>& cuts_of, const std::vector<int>& tip,
                     const CutLayout& L, CutReport& rep) {
  PieceSet ps;
  ps.subs.resize(ls.nt);
  for (int e = 0; e < ls.nt; ++e) {
    if (!tip.empty() && tip[e] >= 0) split_front_element(ls, e, tip[e], L, ps);
    else if (cuts_of[e].empty()) ps.pieces.push_back({e, {}, {}, 1.0});
    else split_element(ls, e, cuts_of[e], ps, rep);
    ps.elem_piece_ptr.push_back(static_cast<int>(ps.pieces.size()));
  }
  return ps;
}

// Whether pieces P and Q of the two elements sharing the face with corners
// tri overlap on it with positive area (a sliver 1e-12 h thin still connects
// to its neighbours); never when they lie on opposite sides of a cut.
bool pieces_touch(const LevelSets& ls, const Piece& P, const Piece& Q, const std::array<int, 3>& tri) {
  std::vector<std::pair<std::array<double, 3>, int>> cons;
  bool clash = false;
  for (const auto* S : {&P.sides, &Q.sides})
    for (const auto& [c, s] : *S) {
      for (const auto& [c2, s2] : P.sides)
        if (c2 == c && s2 != s) clash = true;
      for (const auto& [c2, s2] : Q.sides)
        if (c2 == c && s2 != s) clash = true;
      std::array<double, 3> f3;
      for (int i = 0; i < 3; ++i) f3[i] = ls.at(c, tri[i]);
      cons.push_back({f3, s});
    }
  return !clash && overlap_area(cons) > 0.0;
}

// Piece connectivity across shared faces that are not separated: (npiece)
// lists of neighbouring pieces.
std::vector<std::vector<int>> connect_pieces(const LevelSets& ls, const std::vector<FacePair>& pairs,
                                             const std::vector<char>& separated,
                                             const std::vector<std::vector<ElemCut>>& cuts_of, const PieceSet& ps) {
  std::vector<std::vector<int>> adj(ps.pieces.size());
  for (size_t p = 0; p < pairs.size(); ++p) {
    if (separated[p]) continue;
    const auto& fp = pairs[p];
    const bool simple = cuts_of[fp.e].empty() && cuts_of[fp.f].empty();
    const std::array<int, 3> tri = face_corners(ls, fp.e, fp.ke);
    for (int P = ps.elem_piece_ptr[fp.e]; P < ps.elem_piece_ptr[fp.e + 1]; ++P)
      for (int Q = ps.elem_piece_ptr[fp.f]; Q < ps.elem_piece_ptr[fp.f + 1]; ++Q)
        if (simple || pieces_touch(ls, ps.pieces[P], ps.pieces[Q], tri)) {
          adj[P].push_back(Q);
          adj[Q].push_back(P);
        }
  }
  return adj;
}

// Connected components of the piece graph: the separate bodies of tissue,
// numbered in the order of their first piece. (npiece) body of each piece.
std::vector<int> label_bodies(const std::vector<std::vector<int>>& adj, int& bodies) {
  const int np = static_cast<int>(adj.size());
  UnionFind all(np);
  for (int P = 0; P < np; ++P)
    for (int Q : adj[P]) all.join(P, Q);
  std::vector<int> root_body(np, -1), body(np);
  bodies = 0;
  for (int P = 0; P < np; ++P) {
    int& b = root_body[all.find(P)];
    if (b < 0) b = bodies++;
    body[P] = b;
  }
  return body;
}

// Nodes that can have more than one region: the nodes of split elements and
// of elements with a separated face. (nn) flags.
std::vector<char> region_candidates(const LevelSets& ls, const std::vector<std::vector<ElemCut>>& cuts_of,
                                    const std::vector<FacePair>& pairs, const std::vector<char>& separated) {
  std::vector<char> candidate(ls.nn, 0);
  for (int e = 0; e < ls.nt; ++e)
    if (!cuts_of[e].empty())
      for (int a = 0; a < ls.npe; ++a) candidate[ls.node(e, a)] = 1;
  for (size_t p = 0; p < pairs.size(); ++p)
    if (separated[p])
      for (int a = 0; a < ls.npe; ++a) candidate[ls.node(pairs[p].e, a)] = 1;
  return candidate;
}

// The regions of node i's support (connected components of its pieces). The
// largest keeps the standard DOF; each other region gets an enriched DOF
// node, numbered after the mesh nodes ([preprint] eq. (74)) and written to
// L.piece_enr for the region's pieces.
void enrich_node(const Model& base, const LevelSets& ls, int i, const PieceSet& ps,
                 const std::vector<std::vector<int>>& adj, CutLayout& L, std::vector<int>& enr_node) {
  std::vector<int> sp;  // pieces of the support
  for (int k = base.node_elem_ptr[i]; k < base.node_elem_ptr[i + 1]; ++k)
    for (int P = ps.elem_piece_ptr[base.node_elem[k]]; P < ps.elem_piece_ptr[base.node_elem[k] + 1]; ++P) sp.push_back(P);
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
    volume[r] += ps.pieces[sp[k]].fraction * base.elem_volume[ps.pieces[sp[k]].elem];
    if (!first.count(r)) first[r] = sp[k];
  }
  if (volume.size() < 2) return;
  int home = -1;
  for (const auto& [r, v] : volume)
    if (home < 0 || v > volume[home] || (v == volume[home] && first[r] < first[home])) home = r;
  std::map<int, int> enr;  // root -> enriched DOF node
  for (const auto& [r, v] : volume)
    if (r != home) {
      enr[r] = ls.nn + static_cast<int>(enr_node.size());
      enr_node.push_back(i);
    }
  for (size_t k = 0; k < sp.size(); ++k) {
    const int r = uf.find(static_cast<int>(k));
    if (r == home) continue;
    const Piece& P = ps.pieces[sp[k]];
    for (int a = 0; a < ls.npe; ++a)
      if (ls.node(P.elem, a) == i) L.piece_enr[static_cast<size_t>(sp[k]) * ls.npe + a] = enr[r];
  }
}

// The pieces' sub-tetrahedra, faces and fractions into the layout's flat arrays.
void write_pieces(const PieceSet& ps, int nt, CutLayout& L) {
  L.elem_split.assign(nt, 0);
  L.piece_subtet_ptr.assign(1, 0);
  static const double kRef[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (const Piece& P : ps.pieces) {
    if (P.subtets.empty()) {
      L.subtet_rst.insert(L.subtet_rst.end(), kRef, kRef + 12);
      L.subtet_face.insert(L.subtet_face.end(), {0, 1, 2, 3});
    } else {
      L.elem_split[P.elem] = 1;
      const SubTets& S = ps.subs[P.elem];
      for (int t : P.subtets) {
        L.subtet_rst.insert(L.subtet_rst.end(), S.rst.begin() + 12 * t, S.rst.begin() + 12 * (t + 1));
        L.subtet_face.insert(L.subtet_face.end(), S.face.begin() + 4 * t, S.face.begin() + 4 * (t + 1));
      }
    }
    L.piece_subtet_ptr.push_back(static_cast<int>(L.subtet_face.size() / 4));
    L.piece_fraction.push_back(P.fraction);
  }
}

// Front enrichment: the elements fronts pass through (tip, (nelem): the
// cut, -1 none) and the two level sets at the corners of every element that
// holds one of their nodes (L.front_phi, front_psi). One front per element
// and per node's support; a front element that another cut splits is not
// handled yet (an error says so).
std::vector<int> front_elements(const Model& base, const LevelSets& ls, const std::vector<std::pair<int, int>>& fronts,
                                const std::vector<std::vector<ElemCut>>& cuts_of, CutLayout& L) {
  std::vector<int> tip(ls.nt, -1);
  std::vector<int> node_cut(ls.nn, -1);
  L.node_branch.assign(ls.nn, -1);
  L.front_phi.assign(ls.nn, 0.0);
  L.front_psi.assign(ls.nn, 0.0);
  for (const auto& [e, c] : fronts) {
    if (tip[e] >= 0 || !cuts_of[e].empty())
      throw Error("front enrichment: element " + std::to_string(e) +
                  " holds a cut front and another cut; only one cut per front element is handled");
    tip[e] = c;
  }
  // The nodes of the front elements and of every element sharing a corner
  // with one get branch DOFs (a ring one element wide). Enriching the front
  // elements' nodes alone left the sqrt(r) field to a support about h wide
  // and the slit study 1.0-1.2x the conforming mesh's error with the front
  // inside elements; with the ring 0.16-0.48x (docs/benchmarks.md, "Issue
  // 21: branch elements integrated with 27 points").
  std::vector<int> enr_cut = tip;  // (nelem): the cut whose branch functions enrich the element's nodes, -1 none
  for (int e = 0; e < ls.nt; ++e)
    for (int a = 0; tip[e] >= 0 && a < 4; ++a) {
      const int i = ls.node(e, a);
      for (int k = base.node_elem_ptr[i]; k < base.node_elem_ptr[i + 1]; ++k) {
        int& f = enr_cut[base.node_elem[k]];
        if (f >= 0 && f != tip[e])
          throw Error("front enrichment: element " + std::to_string(base.node_elem[k]) +
                      " lies next to the fronts of two cuts");
        f = tip[e];
      }
    }
  for (int e = 0; e < ls.nt; ++e)
    for (int a = 0; enr_cut[e] >= 0 && a < ls.npe; ++a) {
      const int c = enr_cut[e];
      const int i = ls.node(e, a);
      L.node_branch[i] = 1;
      for (int k = base.node_elem_ptr[i]; k < base.node_elem_ptr[i + 1]; ++k)
        for (int b = 0; b < 4; ++b) {
          const int j = ls.node(base.node_elem[k], b);
          if (node_cut[j] == c) continue;
          if (node_cut[j] >= 0)
            throw Error("front enrichment: node " + std::to_string(j) + " lies near the fronts of two cuts");
          node_cut[j] = c;
          L.front_phi[j] = ls.at(c, j);
          L.front_psi[j] = ls.cuts[c]->front_distance(&ls.mesh.X[3 * j]);
        }
    }
  return tip;
}

// Each node front_elements marked (node_branch 1) gets kBranchFunctions branch DOF nodes, after the enriched ones.
void add_branch_nodes(const LevelSets& ls, CutLayout& L, std::vector<int>& enr_node) {
  for (int i = 0; i < ls.nn; ++i)
    if (L.node_branch[i] == 1) {
      L.node_branch[i] = ls.nn + static_cast<int>(enr_node.size());
      enr_node.insert(enr_node.end(), kBranchFunctions, i);
    }
}

}  // namespace

CutLayout compute_cut_layout(const Model& base, const std::vector<const CutSurface*>& cuts, CutReport* report,
                             const std::vector<char>& branch_front) {
  CutReport rep;
  CutLayout L;
  const LevelSets ls = corner_level_sets(base.mesh, cuts);
  std::vector<std::pair<int, int>> fronts;
  const std::vector<std::vector<ElemCut>> cuts_of = classify_elements(ls, rep, fronts);
  const std::vector<FacePair> pairs = face_pairs(base);
  const std::vector<char> separated = separate_faces(ls, pairs, L, rep);
  // The fronts of the surfaces flagged in branch_front, surface by surface:
  // one that front_elements refuses beside the earlier ones (two fronts a
  // few elements apart, a front element another cut splits) keeps its
  // front on faces.
  std::vector<std::pair<int, int>> enriched_fronts;
  for (int c = 0; c < static_cast<int>(cuts.size()); ++c) {
    if (static_cast<size_t>(c) >= branch_front.size() || !branch_front[c]) continue;
    std::vector<std::pair<int, int>> trial = enriched_fronts;
    for (const auto& f : fronts)
      if (f.second == c) trial.push_back(f);
    if (trial.size() == enriched_fronts.size()) continue;  // no front inside the body
    try {
      front_elements(base, ls, trial, cuts_of, L);
      enriched_fronts = std::move(trial);
    } catch (const Error&) {
      rep.fronts_on_faces.push_back(c);
    }
  }
  // L as for the accepted set (a refused trial may have written part of it).
  std::vector<int> tip;
  L.node_branch.clear();
  L.front_phi.clear();
  L.front_psi.clear();
  if (!enriched_fronts.empty()) tip = front_elements(base, ls, enriched_fronts, cuts_of, L);
  const PieceSet ps = make_pieces(ls, cuts_of, tip, L, rep);
  const std::vector<std::vector<int>> adj = connect_pieces(ls, pairs, separated, cuts_of, ps);
  L.piece_body = label_bodies(adj, rep.bodies);
  L.bodies = rep.bodies;
  // Regions of each node's support; only candidates can have more than one.
  const std::vector<char> candidate = region_candidates(ls, cuts_of, pairs, separated);
  L.piece_enr.assign(ps.pieces.size() * ls.npe, -1);
  std::vector<int> enr_node;
  for (int i = 0; i < ls.nn; ++i)
    if (candidate[i]) enrich_node(base, ls, i, ps, adj, L, enr_node);
  if (!tip.empty()) add_branch_nodes(ls, L, enr_node);
  L.n_enriched = static_cast<int>(enr_node.size());
  L.enr_node = std::move(enr_node);
  L.elem_piece_ptr = ps.elem_piece_ptr;
  write_pieces(ps, ls.nt, L);
  rep.enriched_nodes = L.n_enriched;
  if (report) *report = rep;
  return L;
}

}  // namespace incise
