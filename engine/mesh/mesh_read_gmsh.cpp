// Gmsh .msh reader, ASCII format 2.2 and 4.1. Element types 4 (tet4) and 11
// (tet10) are kept; all other types (points, lines, triangles) are skipped.
//
// Gmsh tet10 mid-edge nodes (Gmsh manual, "Node ordering"): 4:(0,1) 5:(1,2)
// 6:(2,0) 7:(3,0) 8:(3,2) 9:(3,1). Ours (VTK): 8:(1,3) 9:(2,3), so Gmsh
// nodes 8 and 9 swap; the others match (edge direction does not matter).
// Node tags may be sparse; they are mapped to 0-based rows in file order.
#include <algorithm>
#include <string>
#include <vector>

#include "engine/util/error.h"
#include "engine/mesh/mesh_text.h"

namespace incise::meshio {
namespace {

constexpr int kFromGmshTet10[10] = {0, 1, 2, 3, 4, 5, 6, 7, 9, 8};  // ours[k] = gmsh[kFromGmshTet10[k]]

int tet_nodes(long long type) { return type == 4 ? 4 : type == 11 ? 10 : 0; }

struct Reader {
  TextFile f;
  RawMesh raw;
  std::vector<std::string_view> tok;
  int major = 0;  // 2 or 4

  explicit Reader(const std::string& path) : f(path) {}

  // Next non-blank line split into tok; `what` says what was expected.
  void need_line(const char* what) {
    std::string_view line;
    do {
      if (!f.next(line)) f.fail(std::string("unexpected end of file, expected ") + what);
    } while (trim(line).empty());
    split(line, tok);
  }
  void need_tokens(size_t n, const char* what) {
    if (tok.size() < n)
      f.fail(std::string("expected ") + what + " (" + std::to_string(n) + " values), got " +
             std::to_string(tok.size()));
  }
  void expect_end(const std::string& end) {
    need_line(end.c_str());
    if (tok.size() != 1 || tok[0] != end) f.fail("expected " + end + ", got " + quote(tok.empty() ? "" : tok[0]));
  }
  void skip_to(const std::string& end) {
    std::string_view line;
    while (f.next(line))
      if (trim(line) == end) return;
    f.fail("unexpected end of file, missing " + end);
  }

  void mesh_format() {
    need_line("'version file-type data-size'");
    need_tokens(3, "'version file-type data-size'");
    if (tok[1] != "0") f.fail("binary .msh not supported, save as ASCII");
    if (tok[0].substr(0, 2) == "2.")
      major = 2;
    else if (tok[0] == "4.1")
      major = 4;
    else
      f.fail("Gmsh format version " + std::string(tok[0]) + " is not supported; allowed: 2.2 or 4.1 (ASCII)");
    expect_end("$EndMeshFormat");
  }

  void node(long long tag, size_t first) {
    double x[3];
    for (int c = 0; c < 3; ++c) x[c] = get_coord(f, tok[first + c], "a node coordinate");
    raw.add_node(f, tag, x);
  }

  void tet(long long id, long long type, const std::vector<std::string_view>& nodes_tok, size_t first) {
    const int n = tet_nodes(type);
    long long g[10], ours[10];
    for (int a = 0; a < n; ++a) g[a] = get_long(f, nodes_tok[first + a], "a node tag");
    for (int a = 0; a < n; ++a) ours[a] = n == 10 ? g[kFromGmshTet10[a]] : g[a];
    raw.add_tet(f, id, ours, n);
  }

  void nodes2() {
    need_line("the number of nodes");
    long long n = get_long(f, tok[0], "the number of nodes");
    for (long long i = 0; i < n; ++i) {
      need_line("'tag x y z'");
      need_tokens(4, "'tag x y z'");
      node(get_long(f, tok[0], "a node tag"), 1);
    }
  }

  void elements2() {
    need_line("the number of elements");
    long long n = get_long(f, tok[0], "the number of elements");
    for (long long i = 0; i < n; ++i) {
      need_line("'tag type ntags tags... nodes...'");
      need_tokens(3, "'tag type ntags ...'");
      long long id = get_long(f, tok[0], "an element tag");
      long long type = get_long(f, tok[1], "an element type");
      if (!tet_nodes(type)) continue;
      long long ntags = get_long(f, tok[2], "the number of element tags");
      if (ntags < 0 || ntags > 100) f.fail("implausible number of element tags " + std::to_string(ntags));
      size_t first = 3 + static_cast<size_t>(ntags);
      if (tok.size() != first + tet_nodes(type))
        f.fail("element " + std::to_string(id) + " of type " + std::to_string(type) + " needs " +
               std::to_string(tet_nodes(type)) + " node tags, got " + std::to_string(tok.size() - std::min(tok.size(), first)));
      tet(id, type, tok, first);
    }
  }

  void nodes4() {
    need_line("'numEntityBlocks numNodes minNodeTag maxNodeTag'");
    need_tokens(4, "'numEntityBlocks numNodes minNodeTag maxNodeTag'");
    long long nblocks = get_long(f, tok[0], "the number of entity blocks");
    std::vector<long long> tags;
    for (long long b = 0; b < nblocks; ++b) {
      need_line("'entityDim entityTag parametric numNodesInBlock'");
      need_tokens(4, "'entityDim entityTag parametric numNodesInBlock'");
      long long n = get_long(f, tok[3], "numNodesInBlock");
      tags.clear();
      while (static_cast<long long>(tags.size()) < n) {  // one tag a line, but be lenient
        need_line("a node tag");
        for (auto t : tok) tags.push_back(get_long(f, t, "a node tag"));
      }
      if (static_cast<long long>(tags.size()) != n) f.fail("more node tags than numNodesInBlock = " + std::to_string(n));
      for (long long i = 0; i < n; ++i) {
        need_line("'x y z'");
        need_tokens(3, "'x y z'");  // parametric coordinates may follow
        node(tags[i], 0);
      }
    }
  }

  void elements4() {
    need_line("'numEntityBlocks numElements minElementTag maxElementTag'");
    need_tokens(4, "'numEntityBlocks numElements minElementTag maxElementTag'");
    long long nblocks = get_long(f, tok[0], "the number of entity blocks");
    for (long long b = 0; b < nblocks; ++b) {
      need_line("'entityDim entityTag elementType numElementsInBlock'");
      need_tokens(4, "'entityDim entityTag elementType numElementsInBlock'");
      long long type = get_long(f, tok[2], "an element type");
      long long n = get_long(f, tok[3], "numElementsInBlock");
      for (long long i = 0; i < n; ++i) {
        need_line("'elementTag nodeTag...'");
        if (!tet_nodes(type)) continue;
        long long id = get_long(f, tok[0], "an element tag");
        if (tok.size() != 1 + static_cast<size_t>(tet_nodes(type)))
          f.fail("element " + std::to_string(id) + " of type " + std::to_string(type) + " needs " +
                 std::to_string(tet_nodes(type)) + " node tags, got " + std::to_string(tok.size() - 1));
        tet(id, type, tok, 1);
      }
    }
  }

  Mesh read() {
    std::string_view line;
    while (f.next(line)) {
      line = trim(line);
      if (line.empty()) continue;
      if (line[0] != '$') f.fail("expected a section such as $Nodes, got " + quote(line));
      const std::string name(line.substr(1));
      if (name == "MeshFormat") {
        mesh_format();
        continue;
      }
      if ((name == "Nodes" || name == "Elements") && major == 0)
        f.fail("$" + name + " before $MeshFormat; is this a Gmsh .msh file?");
      if (name == "Nodes") {
        major == 2 ? nodes2() : nodes4();
        expect_end("$EndNodes");
      } else if (name == "Elements") {
        major == 2 ? elements2() : elements4();
        expect_end("$EndElements");
      } else if (name == "NOD" || name == "ELM") {
        f.fail("Gmsh format 1 is not supported; allowed: 2.2 or 4.1 (ASCII)");
      } else {
        skip_to("$End" + name);  // $Entities, $PhysicalNames, $NodeData, ...
      }
    }
    if (major == 0) throw Error(f.path() + ": not a Gmsh .msh file (no $MeshFormat section)");
    return finish(raw, f.path(), "Gmsh element types 4 (tet4) and 11 (tet10)");
  }
};

}  // namespace

Mesh read_gmsh(const std::string& path) { return Reader(path).read(); }

}  // namespace incise::meshio
