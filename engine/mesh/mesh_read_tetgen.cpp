// TetGen .node + .ele reader (give either file; the other has the same stem).
// Indices are 0- or 1-based as the first point of the .node file says; they
// are mapped through a tag table, so any consistent numbering works.
// Point attributes, boundary markers and region attributes are skipped.
//
// Second-order (-o2) ordering. TetGen 1.5/1.6 writes the six extra nodes of
// a tet (corners p0..p3) in the order of its internal edge table
// (tetgenmesh::highorder(): edge i is version edge2ver[i] = {0,1,2,3,8,5},
// org/dest from orgpivot/destpivot), which gives the edges
//   file 4:(2,3) 5:(0,3) 6:(0,1) 7:(1,2) 8:(1,3) 9:(0,2),
// so ours 4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3) 8:(1,3) 9:(2,3) take
//   file 6, 7, 9, 5, 8, 4.
// TetGen places extra nodes exactly at edge midpoints, which the reader uses
// as a check: when each extra node is nearest to a different edge midpoint
// (always so for TetGen output) that match is used, so files from TetGen
// versions with another edge numbering are read correctly too; otherwise
// (strongly curved edges) the table above is used and check_mesh() judges.
#include <cmath>
#include <string>
#include <vector>

#include "engine/util/error.h"
#include "engine/mesh/mesh_text.h"

namespace incise::meshio {
namespace {

constexpr int kFromTetgenTet10[10] = {0, 1, 2, 3, 6, 7, 9, 5, 8, 4};  // ours[k] = file[kFromTetgenTet10[k]]

// Next data line (comments after '#' removed) split into tok; false at end.
bool data_line(TextFile& f, std::vector<std::string_view>& tok) {
  std::string_view line;
  while (f.next(line)) {
    size_t hash = line.find('#');
    if (hash != std::string_view::npos) line = line.substr(0, hash);
    split(line, tok);
    if (!tok.empty()) return true;
  }
  return false;
}

double dist2_to_mid(const RawMesh& raw, int m, int a, int b) {
  double d = 0;
  for (int c = 0; c < 3; ++c) {
    double v = raw.X[3 * m + c] - 0.5 * (raw.X[3 * a + c] + raw.X[3 * b + c]);
    d += v * v;
  }
  return d;
}

// Puts the six extra node tags of a tet10 into our order (see top of file).
void order_extras(const RawMesh& raw, const long long* file, long long* ours) {
  for (int k = 0; k < 10; ++k) ours[k] = file[kFromTetgenTet10[k]];
  int row[10];
  for (int k = 0; k < 10; ++k) {
    auto it = raw.index.find(file[k]);
    if (it == raw.index.end()) return;  // finish() reports the missing node with its line
    row[k] = it->second;
  }
  // Nearest edge midpoint of each extra node; must be a permutation.
  int edge_of[6], taken[6] = {0, 0, 0, 0, 0, 0};
  for (int j = 0; j < 6; ++j) {
    double best = INFINITY;
    edge_of[j] = -1;
    for (int e = 0; e < 6; ++e) {
      double d = dist2_to_mid(raw, row[4 + j], row[kTet10Edge[e][0]], row[kTet10Edge[e][1]]);
      if (d < best) best = d, edge_of[j] = e;
    }
    if (edge_of[j] < 0 || taken[edge_of[j]]++) return;  // ambiguous: keep the table
  }
  for (int j = 0; j < 6; ++j) ours[4 + edge_of[j]] = file[4 + j];
}

}  // namespace

Mesh read_tetgen(const std::string& path) {
  std::string stem = path;
  size_t dot = stem.rfind('.');
  if (dot != std::string::npos) stem.resize(dot);
  RawMesh raw;
  std::vector<std::string_view> tok;

  TextFile node(stem + ".node");
  if (!data_line(node, tok)) node.fail("empty .node file");
  // Header "n dim [nattr [nmarker]]": each point line holds exactly
  // index, x, y, z, nattr attributes and nmarker (0 or 1) markers.
  const int node_hline = node.line();
  const long long n = get_long(node, tok[0], "the number of points");
  const long long dim = tok.size() > 1 ? get_long(node, tok[1], "the dimension") : 3;
  const long long nattr = tok.size() > 2 ? get_long(node, tok[2], "the number of point attributes") : 0;
  const long long nmark = tok.size() > 3 ? get_long(node, tok[3], "the number of boundary markers") : 0;
  if (dim != 3) node.fail("dimension must be 3, got " + std::to_string(dim));
  if (n <= 0) node.fail("the .node file lists no points (points inside a .poly are not supported)");
  if (nattr < 0 || nattr > 1000) node.fail("the number of point attributes must be in [0, 1000], got " + std::to_string(nattr));
  if (nmark != 0 && nmark != 1) node.fail("the number of boundary markers must be 0 or 1, got " + std::to_string(nmark));
  const size_t node_cols = static_cast<size_t>(4 + nattr + nmark);
  for (long long i = 0; i < n; ++i) {
    if (!data_line(node, tok))
      node.fail("unexpected end of file: " + std::to_string(i) + " of " + std::to_string(n) + " points read");
    if (tok.size() != node_cols)
      node.fail("expected " + std::to_string(node_cols) + " values (index x y z, " + std::to_string(nattr) +
                " attributes, " + std::to_string(nmark) + " markers, as the header on line " +
                std::to_string(node_hline) + " says), got " + std::to_string(tok.size()));
    long long tag = get_long(node, tok[0], "a point index");
    if (i == 0 && tag != 0 && tag != 1) node.fail("the first point index must be 0 or 1, got " + std::to_string(tag));
    double x[3];
    for (int c = 0; c < 3; ++c) x[c] = get_coord(node, tok[1 + c], "a point coordinate");
    raw.add_node(node, tag, x);
  }
  if (data_line(node, tok))
    node.fail("the header on line " + std::to_string(node_hline) + " says " + std::to_string(n) +
              " points, but more data follows");

  TextFile ele(stem + ".ele");
  if (!data_line(ele, tok)) ele.fail("empty .ele file");
  // Header "ntet [npe [nregion]]": each line holds index, npe nodes and
  // nregion (0 or 1) region attributes.
  const int ele_hline = ele.line();
  const long long ntet = get_long(ele, tok[0], "the number of tetrahedra");
  const long long npe = tok.size() > 1 ? get_long(ele, tok[1], "nodes per tetrahedron") : 4;
  const long long nreg = tok.size() > 2 ? get_long(ele, tok[2], "the number of region attributes") : 0;
  if (ntet < 0) ele.fail("the number of tetrahedra must not be negative, got " + std::to_string(ntet));
  if (npe != 4 && npe != 10) ele.fail("nodes per tetrahedron must be 4 or 10, got " + std::to_string(npe));
  if (nreg != 0 && nreg != 1) ele.fail("the number of region attributes must be 0 or 1, got " + std::to_string(nreg));
  for (long long e = 0; e < ntet; ++e) {
    if (!data_line(ele, tok))
      ele.fail("unexpected end of file: " + std::to_string(e) + " of " + std::to_string(ntet) + " tetrahedra read");
    if (static_cast<long long>(tok.size()) != 1 + npe + nreg)
      ele.fail("expected " + std::to_string(1 + npe + nreg) + " values (index, " + std::to_string(npe) + " node indices, " +
               std::to_string(nreg) + " region attributes, as the header on line " + std::to_string(ele_hline) +
               " says), got " + std::to_string(tok.size()));
    long long id = get_long(ele, tok[0], "a tetrahedron index");
    long long file[10], ours[10];
    for (int a = 0; a < npe; ++a) file[a] = get_long(ele, tok[1 + a], "a node index");
    if (npe == 10)
      order_extras(raw, file, ours);
    else
      for (int a = 0; a < 4; ++a) ours[a] = file[a];
    raw.add_tet(ele, id, ours, static_cast<int>(npe));
  }
  if (data_line(ele, tok))
    ele.fail("the header on line " + std::to_string(ele_hline) + " says " + std::to_string(ntet) +
             " tetrahedra, but more data follows");
  return finish(raw, ele.path(), "tetrahedra in the .ele file");
}

}  // namespace incise::meshio
