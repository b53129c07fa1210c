// VTK readers: legacy ASCII .vtk (UNSTRUCTURED_GRID, both the classic CELLS
// layout and the 5.1 OFFSETS/CONNECTIVITY layout) and XML .vtu with ASCII
// DataArrays. Cell types 10 (tet4) and 24 (tet10) are kept, others skipped.
// VTK's quadratic tetra ordering is ours, so no permutation is needed.
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <string>
#include <type_traits>
#include <vector>

#include "engine/util/error.h"
#include "engine/mesh/mesh_text.h"

namespace incise::meshio {
namespace {

int tet_nodes(long long type) { return type == 10 ? 4 : type == 24 ? 10 : 0; }
const char* kKinds = "VTK cell types 10 (tet4) and 24 (tet10)";

// Cells as read: offsets into connectivity, type and the line for messages.
struct Cells {
  std::vector<long long> conn, start, types;  // start: (ncell + 1)
  std::vector<int> line;                      // (ncell) line of the cell (or its type)
};

// Adds the tetrahedral cells to raw; f is only used for its path in messages.
void add_cells(RawMesh& raw, const Cells& c, TextFile& f) {
  const size_t ncell = c.types.size();
  if (c.start.size() != ncell + 1 || c.line.size() != ncell)
    f.fail("CELLS has " + std::to_string(c.start.size() - 1) + " cells but CELL_TYPES has " +
           std::to_string(ncell));
  for (size_t e = 0; e < ncell; ++e)  // (checked by the readers; here so that no reader can skip it)
    if (c.start[e] < 0 || c.start[e] > c.start[e + 1] || c.start[e + 1] > static_cast<long long>(c.conn.size()))
      f.fail("cell " + std::to_string(e) + "'s offsets fall outside the connectivity");
  for (size_t e = 0; e < ncell; ++e) {
    const int n = tet_nodes(c.types[e]);
    if (!n) continue;
    const long long len = c.start[e + 1] - c.start[e];
    if (len != n)
      f.fail_at(c.line[e], "cell " + std::to_string(e) + " has type " + std::to_string(c.types[e]) +
                               " but " + std::to_string(len) + " nodes; type 10 needs 4, type 24 needs 10");
    if (raw.npe == 0) raw.npe = n;
    if (raw.npe != n)
      f.fail_at(c.line[e], "cell " + std::to_string(e) + " has " + std::to_string(n) +
                               " nodes but earlier tetrahedra have " + std::to_string(raw.npe) +
                               "; mixed tet4/tet10 meshes are not supported");
    raw.tags.insert(raw.tags.end(), c.conn.begin() + c.start[e], c.conn.begin() + c.start[e + 1]);
    raw.line.push_back(c.line[e]);
    raw.id.push_back(static_cast<long long>(e));
  }
}

// ---------------------------------------------------------------- legacy .vtk

struct Tokens {
  TextFile& f;
  std::vector<std::string_view> tok;
  size_t i = 0;
  bool next(std::string_view& t) {
    while (i >= tok.size()) {
      std::string_view l;
      if (!f.next(l)) return false;
      split(l, tok);
      i = 0;
    }
    t = tok[i++];
    return true;
  }
  std::string_view need(const char* what) {
    std::string_view t;
    if (!next(t)) f.fail(std::string("unexpected end of file, expected ") + what);
    return t;
  }
  long long need_long(const char* what) { return get_long(f, need(what), what); }
  void drop_line() { i = tok.size(); }
};

Mesh read_legacy(const std::string& path) {
  TextFile f(path);
  std::string_view line;
  if (!f.next(line) || line.substr(0, 14) != "# vtk DataFile")
    f.fail("not a legacy VTK file (first line must start with '# vtk DataFile')");
  if (!f.next(line)) f.fail("unexpected end of file after the header");  // title
  if (!f.next(line)) f.fail("unexpected end of file, expected ASCII or BINARY");
  const std::string fmt = upper(trim(line));
  if (fmt == "BINARY") f.fail("binary legacy .vtk not supported, save as ASCII");
  if (fmt != "ASCII") f.fail("expected ASCII or BINARY, got " + quote(line));

  Tokens t{f, {}, 0};
  if (upper(t.need("DATASET")) != "DATASET") f.fail("expected DATASET UNSTRUCTURED_GRID");
  std::string_view kind = t.need("UNSTRUCTURED_GRID");
  if (upper(kind) != "UNSTRUCTURED_GRID")
    f.fail("dataset " + quote(kind) + " is not supported; allowed: UNSTRUCTURED_GRID");

  RawMesh raw;
  Cells cells;
  bool have_points = false, have_cells = false, have_types = false;
  std::string_view kw;
  while (t.next(kw)) {
    const std::string key = upper(kw);
    if (key == "POINTS") {
      long long n = t.need_long("the number of points");
      t.need("the point data type");
      for (long long p = 0; p < n; ++p) {
        double x[3];
        for (int c = 0; c < 3; ++c) x[c] = get_coord(f, t.need("a point coordinate"), "a point coordinate");
        raw.add_node(f, p, x);
      }
      have_points = true;
    } else if (key == "CELLS") {
      if (have_cells) f.fail("a second CELLS section; a legacy .vtk file has one");
      long long a = t.need_long("the number of cells");
      long long b = t.need_long("the size of the cell list");
      if (a < 0 || b < 0) f.fail("CELLS sizes must not be negative");
      std::string_view next = a > 0 ? t.need("cell data") : std::string_view();
      if (a == 0) {
        cells.start.assign(1, 0);
      } else if (upper(next) == "OFFSETS") {  // VTK 5.1: a = ncell + 1 offsets, b connectivity entries
        t.need("the offsets data type");
        for (long long i = 0; i < a; ++i) {
          cells.start.push_back(t.need_long("a cell offset"));
          if (i > 0) cells.line.push_back(f.line());
        }
        if (upper(t.need("CONNECTIVITY")) != "CONNECTIVITY") f.fail("expected CONNECTIVITY after OFFSETS");
        t.need("the connectivity data type");
        for (long long i = 0; i < b; ++i) cells.conn.push_back(t.need_long("a node index"));
        if (cells.start.empty() || cells.start[0] != 0) f.fail("OFFSETS must start with 0");
        for (size_t i = 1; i < cells.start.size(); ++i)
          if (cells.start[i] < cells.start[i - 1] || cells.start[i] > b)
            f.fail("OFFSETS must increase and stay within the " + std::to_string(b) + " CONNECTIVITY entries");
      } else {  // classic: a cells, b integers "npts id id ..." in all
        cells.start.push_back(0);
        long long used = 0;
        for (long long c = 0; c < a; ++c) {
          long long n = get_long(f, c == 0 ? next : t.need("the node count of a cell"), "the node count of a cell");
          if (n < 0 || n > b - used - 1) f.fail("cell " + std::to_string(c) + " overruns the CELLS size " + std::to_string(b));
          cells.line.push_back(f.line());
          for (long long k = 0; k < n; ++k) cells.conn.push_back(t.need_long("a node index"));
          cells.start.push_back(static_cast<long long>(cells.conn.size()));
          used += 1 + n;
        }
      }
      have_cells = true;
    } else if (key == "CELL_TYPES") {
      if (have_types) f.fail("a second CELL_TYPES section; a legacy .vtk file has one");
      long long n = t.need_long("the number of cell types");
      for (long long c = 0; c < n; ++c) cells.types.push_back(t.need_long("a cell type"));
      have_types = true;
    } else if (key == "METADATA") {  // ends at a blank line
      t.drop_line();
      while (f.next(line) && !trim(line).empty()) {
      }
    } else if (key == "POINT_DATA" || key == "CELL_DATA" || key == "FIELD") {
      break;  // fields are not part of the mesh
    } else {
      f.fail("unexpected keyword " + quote(kw) + "; expected POINTS, CELLS or CELL_TYPES");
    }
  }
  if (!have_points || !have_cells || !have_types)
    throw Error(path + ": missing " + std::string(!have_points ? "POINTS" : !have_cells ? "CELLS" : "CELL_TYPES") +
                " section");
  add_cells(raw, cells, f);
  return finish(raw, path, kKinds);
}

// ---------------------------------------------------------------- XML .vtu

struct Xml {
  const std::string& s;
  const std::string& path;
  int line_of(size_t pos) const {
    int n = 1;
    for (size_t i = 0; i < pos && i < s.size(); ++i) n += s[i] == '\n';
    return n;
  }
  [[noreturn]] void fail(size_t pos, const std::string& msg) const {
    throw Error(path + ":" + std::to_string(line_of(pos)) + ": " + msg);
  }
};

// Value of attribute `name` in a start tag "<Tag a="1" b='2'>"; "" if absent.
std::string attr(std::string_view tag, std::string_view name) {
  size_t i = tag.find_first_of(" \t\r\n");
  while (i != std::string_view::npos && i < tag.size()) {
    while (i < tag.size() && std::string_view(" \t\r\n").find(tag[i]) != std::string_view::npos) ++i;
    size_t eq = tag.find('=', i);
    if (eq == std::string_view::npos) break;
    std::string_view key = trim(tag.substr(i, eq - i));
    size_t q = tag.find_first_of("\"'", eq);
    if (q == std::string_view::npos) break;
    size_t qe = tag.find(tag[q], q + 1);
    if (qe == std::string_view::npos) break;
    if (key == name) return std::string(tag.substr(q + 1, qe - q - 1));
    i = qe + 1;
  }
  return {};
}

struct DataArray {
  std::string name;
  size_t tag_pos = 0, begin = 0, end = 0;  // start tag, content [begin, end)
  int ncomp = 1;
};

// All DataArrays in [from, to) of the text.
std::vector<DataArray> arrays_in(const Xml& x, size_t from, size_t to) {
  std::vector<DataArray> out;
  size_t p = from;
  while ((p = x.s.find("<DataArray", p)) != std::string::npos && p < to) {
    size_t gt = x.s.find('>', p);
    if (gt == std::string::npos) x.fail(p, "unterminated <DataArray> tag");
    std::string_view tag(x.s.data() + p, gt - p);
    DataArray a;
    a.name = attr(tag, "Name");
    a.tag_pos = p;
    std::string format = attr(tag, "format");
    if (format != "ascii")
      x.fail(p, "DataArray '" + a.name + "' has " +
                    (format.empty() ? std::string("no format attribute") : "format=\"" + format + "\"") +
                    "; only format=\"ascii\" is supported (save the .vtu with ASCII data mode)");
    std::string nc = attr(tag, "NumberOfComponents");
    if (!nc.empty()) a.ncomp = std::atoi(nc.c_str());
    a.begin = gt + 1;
    if (tag.back() == '/') {
      a.end = a.begin;
    } else {
      size_t close = x.s.find("</DataArray>", a.begin);
      if (close == std::string::npos) x.fail(p, "DataArray '" + a.name + "' is not closed");
      a.end = close;
    }
    out.push_back(a);
    p = a.end;
  }
  return out;
}

// Section [begin, end) of the first <name ...> ... </name>.
bool section(const Xml& x, const char* name, size_t& begin, size_t& end) {
  std::string open = std::string("<") + name, close = std::string("</") + name + ">";
  size_t p = 0;
  while ((p = x.s.find(open, p)) != std::string::npos) {
    char c = p + open.size() < x.s.size() ? x.s[p + open.size()] : '\0';
    if (c == '>' || c == ' ' || c == '\t' || c == '\n' || c == '\r') break;
    ++p;
  }
  if (p == std::string::npos) return false;
  begin = p;
  end = x.s.find(close, p);
  if (end == std::string::npos) x.fail(p, std::string("<") + name + "> is not closed");
  return true;
}

// Numbers of an ASCII DataArray; line numbers are computed only on error.
template <class T>
std::vector<T> numbers(const Xml& x, const DataArray& a) {
  std::vector<T> out;
  size_t i = a.begin;
  while (i < a.end) {
    while (i < a.end && std::isspace(static_cast<unsigned char>(x.s[i]))) ++i;
    size_t b = i;
    while (i < a.end && !std::isspace(static_cast<unsigned char>(x.s[i]))) ++i;
    if (i == b) break;
    std::string_view tok(x.s.data() + b, i - b);
    if constexpr (std::is_same_v<T, double>) {
      double v;
      if (!parse_double(tok, v)) x.fail(b, "DataArray '" + a.name + "': expected a number, got " + quote(tok));
      out.push_back(v);
    } else {
      long long v;
      if (!parse_long(tok, v)) x.fail(b, "DataArray '" + a.name + "': expected an integer, got " + quote(tok));
      out.push_back(v);
    }
  }
  return out;
}

Mesh read_xml(const std::string& path) {
  TextFile f(path);
  const Xml x{f.text(), path};
  size_t b = 0, e = 0;
  if (!section(x, "VTKFile", b, e)) throw Error(path + ": not a VTK XML file (no <VTKFile>)");
  std::string type = attr(std::string_view(x.s).substr(b, x.s.find('>', b) - b), "type");
  if (type != "UnstructuredGrid")
    x.fail(b, "VTKFile type \"" + type + "\" is not supported; allowed: UnstructuredGrid (.vtu)");
  size_t pb, pe;
  if (!section(x, "Piece", pb, pe)) x.fail(b, "no <Piece> in the UnstructuredGrid");
  if (x.s.find("<Piece", pe) != std::string::npos) x.fail(pe, "more than one <Piece>; only single-piece .vtu files are supported");

  RawMesh raw;
  size_t sb, se;
  if (!section(x, "Points", sb, se)) x.fail(pb, "no <Points> in the <Piece>");
  auto parr = arrays_in(x, sb, se);
  if (parr.empty()) x.fail(sb, "<Points> has no DataArray");
  if (parr[0].ncomp != 3) x.fail(parr[0].tag_pos, "Points DataArray must have NumberOfComponents=\"3\"");
  auto pts = numbers<double>(x, parr[0]);
  if (pts.size() % 3) x.fail(parr[0].tag_pos, "Points DataArray has " + std::to_string(pts.size()) + " values, not a multiple of 3");
  for (size_t i = 0; i < pts.size(); ++i)
    if (!std::isfinite(pts[i])) x.fail(parr[0].tag_pos, "point " + std::to_string(i / 3) + " has a non-finite coordinate");
  raw.X = pts;
  for (size_t i = 0; i < pts.size() / 3; ++i) raw.index.emplace(static_cast<long long>(i), static_cast<int>(i));

  if (!section(x, "Cells", sb, se)) x.fail(pb, "no <Cells> in the <Piece>");
  const DataArray *conn = nullptr, *offs = nullptr, *types = nullptr;
  auto carr = arrays_in(x, sb, se);
  for (const auto& a : carr) {
    if (a.name == "connectivity") conn = &a;
    if (a.name == "offsets") offs = &a;
    if (a.name == "types") types = &a;
  }
  if (!conn || !offs || !types) x.fail(sb, "<Cells> needs DataArrays named connectivity, offsets and types");
  Cells c;
  c.conn = numbers<long long>(x, *conn);
  auto off = numbers<long long>(x, *offs);
  c.types = numbers<long long>(x, *types);
  c.start.push_back(0);
  for (size_t i = 0; i < off.size(); ++i) {
    if (off[i] < c.start.back() || off[i] > static_cast<long long>(c.conn.size()))
      x.fail(offs->tag_pos, "offsets must increase and end at the connectivity size " + std::to_string(c.conn.size()));
    c.start.push_back(off[i]);
  }
  const int cells_line = x.line_of(conn->tag_pos);
  c.line.assign(c.types.size(), cells_line);
  add_cells(raw, c, f);
  // Element errors from finish() point at the line of the connectivity array.
  return finish(raw, path, kKinds);
}

}  // namespace

Mesh read_vtk_legacy(const std::string& path) { return read_legacy(path); }
Mesh read_vtu(const std::string& path) { return read_xml(path); }

}  // namespace incise::meshio
