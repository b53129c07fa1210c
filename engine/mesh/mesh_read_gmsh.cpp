// Gmsh .msh reader, format 2.2 and 4.1, ASCII and binary (little-endian,
// 8-byte size_t: what gmsh and meshio write). Element types 4 (tet4) and 11
// (tet10) are kept; all other types (points, lines, triangles) are skipped.
//
// Gmsh tet10 mid-edge nodes (Gmsh manual, "Node ordering"): 4:(0,1) 5:(1,2)
// 6:(2,0) 7:(3,0) 8:(3,2) 9:(3,1). Ours (VTK): 8:(1,3) 9:(2,3), so Gmsh
// nodes 8 and 9 swap; the others match (edge direction does not matter).
// Node tags may be sparse; they are mapped to 0-based rows in file order.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "engine/util/error.h"
#include "engine/mesh/mesh_text.h"

namespace incise::meshio {
namespace {

constexpr int kFromGmshTet10[10] = {0, 1, 2, 3, 4, 5, 6, 7, 9, 8};  // ours[k] = gmsh[kFromGmshTet10[k]]

int tet_nodes(long long type) { return type == 4 ? 4 : type == 11 ? 10 : 0; }

// Nodes of Gmsh element types 1-19 (a binary file's elements of other types
// must be skipped by size); 0 for types not in the table.
int gmsh_nodes(long long type) {
  static const int n[20] = {0, 2, 3, 4, 4, 8, 6, 5, 3, 6, 9, 10, 27, 18, 14, 1, 8, 20, 15, 13};
  return type >= 1 && type <= 19 ? n[type] : 0;
}

// A cursor over binary data inside the file's text, bounds-checked.
struct Bin {
  TextFile& f;
  size_t pos;
  template <class T>
  T get(const char* what) {
    const std::string& s = f.text();
    if (pos > s.size() || s.size() - pos < sizeof(T))
      f.fail(std::string("binary data ends inside ") + what + " (truncated at byte " + std::to_string(s.size()) + ")");
    T v;
    std::memcpy(&v, s.data() + pos, sizeof(T));
    pos += sizeof(T);
    return v;
  }
  // A count that must fit in what is left of the file at `bytes_each` each.
  uint64_t count(uint64_t n, uint64_t bytes_each, const char* what) {
    const uint64_t left = f.text().size() - std::min(pos, f.text().size());
    if (bytes_each > 0 && n > left / bytes_each)
      f.fail(std::string(what) + " is " + std::to_string(n) + ", more than the " + std::to_string(left) + " bytes left can hold");
    return n;
  }
};

struct Reader {
  TextFile f;
  RawMesh raw;
  std::vector<std::string_view> tok;
  int major = 0;  // 2 or 4
  bool binary = false;

  explicit Reader(const std::string& path) : f(path) {}

  // Next non-blank line split into tok; `what` says what was expected.
  void need_line(const char* what) {
    std::string_view line;
    do {
      if (!f.next(line)) f.fail(std::string("unexpected end of file, expected ") + what);
    } while (trim(line).empty());
    split(line, tok);
  }
  // An entity block's header: exactly 4 values (a data line here means the
  // previous block's count is wrong).
  void need_block_header(const char* what, long long b) {
    if (tok.size() != 4)
      f.fail(std::string("expected entity block ") + std::to_string(b + 1) + "'s header " + what + " (4 values), got " +
             std::to_string(tok.size()) + (b > 0 ? "; does the previous block's count match its data?" : ""));
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
  // A section's count from its header line (hline): not negative.
  long long count(std::string_view tok_, const char* what) {
    const long long n = get_long(f, tok_, what);
    if (n < 0) f.fail(std::string(what) + " must not be negative, got " + std::to_string(n));
    return n;
  }
  // The next line of a counted section; a section end ("$End...") before the
  // count is reached names the header and what the data holds.
  void need_item(const char* what, const std::string& header, int hline, long long n, long long i, const char* items) {
    need_line(what);
    if (!tok.empty() && !tok[0].empty() && tok[0][0] == '$')
      f.fail(header + " on line " + std::to_string(hline) + " says " + std::to_string(n) + " " + items +
             ", but the data ends after " + std::to_string(i) + " (at " + quote(tok[0]) + ")");
  }
  // The end line of a counted section; more data before it contradicts the header.
  void expect_end_of(const std::string& end, const std::string& header, int hline, long long n, const char* items) {
    need_line(end.c_str());
    if (tok.size() != 1 || tok[0] != end)
      f.fail(header + " on line " + std::to_string(hline) + " says " + std::to_string(n) + " " + items +
             ", but the data holds more (expected " + end + ", got " + quote(tok.empty() ? "" : tok[0]) + ")");
  }
  // A tag of a Gmsh 4.1 section, within the header's [min, max].
  void in_range(long long tag, long long lo, long long hi, const std::string& header, int hline, const char* what) {
    if (tag < lo || tag > hi)
      f.fail(std::string(what) + " " + std::to_string(tag) + " is outside [" + std::to_string(lo) + ", " + std::to_string(hi) +
             "], the range " + header + " on line " + std::to_string(hline) + " gives");
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
    if (tok[1] != "0" && tok[1] != "1") f.fail("file-type must be 0 (ASCII) or 1 (binary), got " + quote(tok[1]));
    binary = tok[1] == "1";
    if (binary && tok[2] != "8") f.fail("binary data-size " + quote(tok[2]) + " is not supported; allowed: 8 (64-bit size_t)");
    if (tok[0].substr(0, 2) == "2.")
      major = 2;
    else if (tok[0] == "4.1")
      major = 4;
    else
      f.fail("Gmsh format version " + std::string(tok[0]) + " is not supported; allowed: 2.2 or 4.1");
    if (binary) {  // the integer 1, to tell the byte order
      Bin b{f, f.pos()};
      if (b.get<int32_t>("the byte-order mark") != 1) f.fail("big-endian binary .msh is not supported");
      f.seek(b.pos);
    }
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
    const long long n = count(tok[0], "the number of nodes");
    const int hline = f.line();
    for (long long i = 0; i < n; ++i) {
      need_item("'tag x y z'", "$Nodes", hline, n, i, "nodes");
      need_tokens(4, "'tag x y z'");
      node(get_long(f, tok[0], "a node tag"), 1);
    }
    expect_end_of("$EndNodes", "$Nodes", hline, n, "nodes");
  }

  void elements2() {
    need_line("the number of elements");
    const long long n = count(tok[0], "the number of elements");
    const int hline = f.line();
    for (long long i = 0; i < n; ++i) {
      need_item("'tag type ntags tags... nodes...'", "$Elements", hline, n, i, "elements");
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
    expect_end_of("$EndElements", "$Elements", hline, n, "elements");
  }

  void nodes4() {
    need_line("'numEntityBlocks numNodes minNodeTag maxNodeTag'");
    need_tokens(4, "'numEntityBlocks numNodes minNodeTag maxNodeTag'");
    const int hline = f.line();
    const long long nblocks = count(tok[0], "numEntityBlocks"), total = count(tok[1], "numNodes");
    const long long lo = get_long(f, tok[2], "minNodeTag"), hi = get_long(f, tok[3], "maxNodeTag");
    const std::string H = "$Nodes";
    long long seen = 0;
    std::vector<long long> tags;
    for (long long b = 0; b < nblocks; ++b) {
      need_item("'entityDim entityTag parametric numNodesInBlock'", H + " (numEntityBlocks)", hline, nblocks, b, "entity blocks");
      need_block_header("'entityDim entityTag parametric numNodesInBlock'", b);
      const long long n = count(tok[3], "numNodesInBlock");
      const int bline = f.line();
      if (n > total - seen)
        f.fail("this block's " + std::to_string(n) + " nodes bring the count past numNodes = " + std::to_string(total) +
               " on line " + std::to_string(hline));
      seen += n;
      tags.clear();
      while (static_cast<long long>(tags.size()) < n) {  // one tag a line, but be lenient
        need_item("a node tag", "the entity block", bline, n, static_cast<long long>(tags.size()), "node tags");
        for (auto t : tok) {
          tags.push_back(get_long(f, t, "a node tag"));
          in_range(tags.back(), lo, hi, H, hline, "node tag");
        }
      }
      if (static_cast<long long>(tags.size()) != n) f.fail("more node tags than numNodesInBlock = " + std::to_string(n));
      for (long long i = 0; i < n; ++i) {
        need_item("'x y z'", "the entity block", bline, n, i, "node coordinates");
        need_tokens(3, "'x y z'");  // parametric coordinates may follow
        node(tags[i], 0);
      }
    }
    if (seen != total)
      f.fail(H + " on line " + std::to_string(hline) + " says numNodes = " + std::to_string(total) + ", but its " +
             std::to_string(nblocks) + " entity blocks hold " + std::to_string(seen));
    expect_end_of("$EndNodes", H + " (numEntityBlocks)", hline, nblocks, "entity blocks");
  }

  void elements4() {
    need_line("'numEntityBlocks numElements minElementTag maxElementTag'");
    need_tokens(4, "'numEntityBlocks numElements minElementTag maxElementTag'");
    const int hline = f.line();
    const long long nblocks = count(tok[0], "numEntityBlocks"), total = count(tok[1], "numElements");
    const long long lo = get_long(f, tok[2], "minElementTag"), hi = get_long(f, tok[3], "maxElementTag");
    const std::string H = "$Elements";
    long long seen = 0;
    for (long long b = 0; b < nblocks; ++b) {
      need_item("'entityDim entityTag elementType numElementsInBlock'", H + " (numEntityBlocks)", hline, nblocks, b, "entity blocks");
      need_block_header("'entityDim entityTag elementType numElementsInBlock'", b);
      long long type = get_long(f, tok[2], "an element type");
      const long long n = count(tok[3], "numElementsInBlock");
      const int bline = f.line();
      if (n > total - seen)
        f.fail("this block's " + std::to_string(n) + " elements bring the count past numElements = " +
               std::to_string(total) + " on line " + std::to_string(hline));
      seen += n;
      for (long long i = 0; i < n; ++i) {
        need_item("'elementTag nodeTag...'", "the entity block", bline, n, i, "elements");
        const long long id = get_long(f, tok[0], "an element tag");
        in_range(id, lo, hi, H, hline, "element tag");
        if (!tet_nodes(type)) continue;
        if (tok.size() != 1 + static_cast<size_t>(tet_nodes(type)))
          f.fail("element " + std::to_string(id) + " of type " + std::to_string(type) + " needs " +
                 std::to_string(tet_nodes(type)) + " node tags, got " + std::to_string(tok.size() - 1));
        tet(id, type, tok, 1);
      }
    }
    if (seen != total)
      f.fail(H + " on line " + std::to_string(hline) + " says numElements = " + std::to_string(total) + ", but its " +
             std::to_string(nblocks) + " entity blocks hold " + std::to_string(seen));
    expect_end_of("$EndElements", H + " (numEntityBlocks)", hline, nblocks, "entity blocks");
  }

  // Binary coordinates skip get_coord, so the finiteness check is here.
  void node_bin(long long tag, const double* x) {
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(x[c]))
        f.fail("binary node " + std::to_string(tag) + " has a non-finite coordinate (" + std::to_string(x[c]) +
               "); coordinates must be finite");
    raw.add_node(f, tag, x);
  }
  void tet_bin(long long id, long long type, const long long* g) {
    const int n = tet_nodes(type);
    long long ours[10];
    for (int a = 0; a < n; ++a) ours[a] = n == 10 ? g[kFromGmshTet10[a]] : g[a];
    raw.add_tet(f, id, ours, n);
  }

  void nodes2_bin() {
    need_line("the number of nodes");
    Bin b{f, f.pos()};
    const uint64_t n = b.count(static_cast<uint64_t>(get_long(f, tok[0], "the number of nodes")), 28, "the number of nodes");
    for (uint64_t i = 0; i < n; ++i) {
      const long long tag = b.get<int32_t>("a node tag");
      double x[3];
      for (double& c : x) c = b.get<double>("a node coordinate");
      node_bin(tag, x);
    }
    f.seek(b.pos);
  }

  void elements2_bin() {
    need_line("the number of elements");
    Bin b{f, f.pos()};
    const uint64_t total = b.count(static_cast<uint64_t>(get_long(f, tok[0], "the number of elements")), 8, "the number of elements");
    uint64_t done = 0;
    while (done < total) {
      const long long type = b.get<int32_t>("an element type");
      const uint64_t n = b.count(static_cast<uint32_t>(b.get<int32_t>("the elements following")), 4, "the elements following");
      const int32_t ntags = b.get<int32_t>("the number of tags");
      const int nn = gmsh_nodes(type);
      if (nn == 0) f.fail("binary element type " + std::to_string(type) + " is not one this reader can skip (types 1-19)");
      if (ntags < 0 || ntags > 100) f.fail("implausible number of element tags " + std::to_string(ntags));
      if (n == 0 || n > total - done) f.fail("an element block of " + std::to_string(n) + " runs past the " + std::to_string(total) + " elements");
      for (uint64_t i = 0; i < n; ++i) {
        const long long id = b.get<int32_t>("an element tag");
        for (int t = 0; t < ntags; ++t) b.get<int32_t>("an element tag");
        long long g[27];
        for (int a = 0; a < nn; ++a) g[a] = b.get<int32_t>("an element's node tag");
        if (tet_nodes(type)) tet_bin(id, type, g);
      }
      done += n;
    }
    f.seek(b.pos);
  }

  void nodes4_bin() {
    Bin b{f, f.pos()};
    const uint64_t nblocks = b.count(b.get<uint64_t>("numEntityBlocks"), 20, "numEntityBlocks");
    const uint64_t total = b.get<uint64_t>("numNodes"), lo = b.get<uint64_t>("minNodeTag"), hi = b.get<uint64_t>("maxNodeTag");
    uint64_t seen = 0;
    std::vector<long long> tags;
    for (uint64_t k = 0; k < nblocks; ++k) {
      b.get<int32_t>("entityDim"), b.get<int32_t>("entityTag");
      if (b.get<int32_t>("parametric") != 0) f.fail("binary nodes with parametric coordinates are not supported");
      const uint64_t n = b.count(b.get<uint64_t>("numNodesInBlock"), 32, "numNodesInBlock");
      if (n > total - seen)
        f.fail("binary $Nodes: entity block " + std::to_string(k) + "'s " + std::to_string(n) +
               " nodes bring the count past numNodes = " + std::to_string(total));
      seen += n;
      tags.resize(n);
      for (auto& t : tags) {
        const uint64_t v = b.get<uint64_t>("a node tag");
        if (v < lo || v > hi)
          f.fail("binary $Nodes: node tag " + std::to_string(v) + " is outside [" + std::to_string(lo) + ", " +
                 std::to_string(hi) + "], the range the header gives");
        t = static_cast<long long>(v);
      }
      for (uint64_t i = 0; i < n; ++i) {
        double x[3];
        for (double& c : x) c = b.get<double>("a node coordinate");
        node_bin(tags[i], x);
      }
    }
    if (seen != total)
      f.fail("binary $Nodes: the header says numNodes = " + std::to_string(total) + ", but its " + std::to_string(nblocks) +
             " entity blocks hold " + std::to_string(seen));
    f.seek(b.pos);
  }

  void elements4_bin() {
    Bin b{f, f.pos()};
    const uint64_t nblocks = b.count(b.get<uint64_t>("numEntityBlocks"), 20, "numEntityBlocks");
    const uint64_t total = b.get<uint64_t>("numElements"), lo = b.get<uint64_t>("minElementTag"),
                   hi = b.get<uint64_t>("maxElementTag");
    uint64_t seen = 0;
    for (uint64_t k = 0; k < nblocks; ++k) {
      b.get<int32_t>("entityDim"), b.get<int32_t>("entityTag");
      const long long type = b.get<int32_t>("elementType");
      const int nn = gmsh_nodes(type);
      if (nn == 0) f.fail("binary element type " + std::to_string(type) + " is not one this reader can skip (types 1-19)");
      const uint64_t n = b.count(b.get<uint64_t>("numElementsInBlock"), 8 * (1 + static_cast<uint64_t>(nn)), "numElementsInBlock");
      if (n > total - seen)
        f.fail("binary $Elements: entity block " + std::to_string(k) + "'s " + std::to_string(n) +
               " elements bring the count past numElements = " + std::to_string(total));
      seen += n;
      for (uint64_t i = 0; i < n; ++i) {
        const uint64_t tag = b.get<uint64_t>("an element tag");
        if (tag < lo || tag > hi)
          f.fail("binary $Elements: element tag " + std::to_string(tag) + " is outside [" + std::to_string(lo) + ", " +
                 std::to_string(hi) + "], the range the header gives");
        const long long id = static_cast<long long>(tag);
        long long g[27];
        for (int a = 0; a < nn; ++a) g[a] = static_cast<long long>(b.get<uint64_t>("an element's node tag"));
        if (tet_nodes(type)) tet_bin(id, type, g);
      }
    }
    if (seen != total)
      f.fail("binary $Elements: the header says numElements = " + std::to_string(total) + ", but its " +
             std::to_string(nblocks) + " entity blocks hold " + std::to_string(seen));
    f.seek(b.pos);
  }

  // A binary section this reader does not use ($Entities, ...): its end
  // line found in the text after it.
  void skip_binary_to(const std::string& end) {
    const size_t at = f.text().find("\n" + end, f.pos());
    if (at == std::string::npos) f.fail("unexpected end of file, missing " + end);
    f.seek(at + 1);
    expect_end(end);
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
      if (name == "Nodes") {  // (the ASCII readers check their section's end)
        if (binary) major == 2 ? nodes2_bin() : nodes4_bin(), expect_end("$EndNodes");
        else major == 2 ? nodes2() : nodes4();
      } else if (name == "Elements") {
        if (binary) major == 2 ? elements2_bin() : elements4_bin(), expect_end("$EndElements");
        else major == 2 ? elements2() : elements4();
      } else if (name == "NOD" || name == "ELM") {
        f.fail("Gmsh format 1 is not supported; allowed: 2.2 or 4.1");
      } else if (binary) {
        skip_binary_to("$End" + name);
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
