// VTK readers: legacy .vtk, ASCII or binary (big-endian) (UNSTRUCTURED_GRID,
// both the classic CELLS layout and the 5.1 OFFSETS/CONNECTIVITY layout) and XML .vtu with ascii,
// binary (base64 inline) or appended (raw or base64) DataArrays, plain or
// zlib-compressed (engine/mesh/vtk_binary.h). Cell types 10 (tet4) and 24 (tet10) are kept, others skipped.
// VTK's quadratic tetra ordering is ours, so no permutation is needed.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "engine/util/error.h"
#include "engine/mesh/mesh_text.h"
#include "engine/mesh/vtk_binary.h"

namespace incise::meshio {
namespace {

// 3 n values must be countable (a smaller absurd count is refused when the
// data runs out, naming how many values the header announced).
void check_point_count(const TextFile& f, long long n) {
  constexpr long long kMaxPoints = std::numeric_limits<long long>::max() / 3;
  if (n > kMaxPoints)
    f.fail("the number of points must be at most " + std::to_string(kMaxPoints) + ", got " + std::to_string(n));
}

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
  // The value after `i` of the `n` a header (line hline) announced: a keyword
  // or the end of the file before them names the header and what was there.
  std::string_view item(const char* what, const std::string& header, int hline, long long n, long long i_) {
    std::string_view t;
    double v;
    if (!next(t) || (!parse_double(t, v) && std::isalpha(static_cast<unsigned char>(t[0]))))
      f.fail(header + " on line " + std::to_string(hline) + " announces " + std::to_string(n) + " values, but the data ends after " +
             std::to_string(i_) + " (expected " + what + ", got " + (t.empty() ? std::string("the end of the file") : quote(t)) + ")");
    return t;
  }
};

// Binary legacy .vtk: the keyword lines are text, each array's values
// follow as big-endian binary (the legacy format's byte order), then '\n'.
struct BigEndian {
  TextFile& f;
  size_t pos;
  size_t size_of(std::string_view type) {
    const std::string t = upper(type);
    if (t == "FLOAT" || t == "INT" || t == "UNSIGNED_INT" || t == "VTKTYPEINT32") return 4;
    if (t == "DOUBLE" || t == "LONG" || t == "UNSIGNED_LONG" || t == "VTKTYPEINT64") return 8;
    f.fail("binary data type " + quote(type) + " is not supported; allowed: float, double, int, long, vtktypeint32/64");
  }
  void check(uint64_t n, size_t each, const char* what) {
    const uint64_t left = f.text().size() - std::min(pos, f.text().size());
    if (n > left / each) f.fail(std::string(what) + ": " + std::to_string(n) + " values of " + std::to_string(each) + " bytes, more than the " + std::to_string(left) + " bytes left");
  }
  uint64_t raw(size_t each) {
    uint64_t v = 0;
    for (size_t k = 0; k < each; ++k) v = (v << 8) | static_cast<unsigned char>(f.text()[pos + k]);
    pos += each;
    return v;
  }
  double real(size_t each) {
    const uint64_t b = raw(each);
    if (each == 4) {
      float x;
      const uint32_t w = static_cast<uint32_t>(b);
      std::memcpy(&x, &w, 4);
      return x;
    }
    double x;
    std::memcpy(&x, &b, 8);
    return x;
  }
  long long integer(size_t each) {
    const uint64_t b = raw(each);
    return each == 4 ? static_cast<long long>(static_cast<int32_t>(b)) : static_cast<long long>(b);
  }
  void done() { f.seek(pos); }
};

Mesh read_legacy_binary(TextFile& f, const std::string& path) {
  std::string_view line;
  std::vector<std::string_view> tok;
  auto keyword_line = [&](bool& more) {
    while ((more = f.next(line)))
      if (!trim(line).empty()) break;
    split(line, tok);
  };
  bool more = true;
  keyword_line(more);
  if (!more || tok.size() < 2 || upper(tok[0]) != "DATASET" || upper(tok[1]) != "UNSTRUCTURED_GRID")
    f.fail("expected DATASET UNSTRUCTURED_GRID");
  RawMesh raw;
  Cells cells;
  bool have_points = false, have_cells = false, have_types = false;
  for (keyword_line(more); more; keyword_line(more)) {
    const std::string key = upper(tok[0]);
    BigEndian b{f, f.pos()};
    if (key == "POINTS") {
      if (tok.size() < 3) f.fail("expected POINTS n type");
      const long long n = get_long(f, tok[1], "the number of points");
      const size_t each = b.size_of(tok[2]);
      if (n < 0) f.fail("the number of points must not be negative");
      check_point_count(f, n);
      b.check(3 * static_cast<uint64_t>(n), each, "POINTS");
      for (long long p = 0; p < n; ++p) {
        double x[3];
        for (double& c : x) c = b.real(each);
        for (double c : x)
          if (!std::isfinite(c)) f.fail("point " + std::to_string(p) + " has a non-finite coordinate");
        raw.add_node(f, p, x);
      }
      b.done();
      have_points = true;
    } else if (key == "CELLS") {
      if (tok.size() < 3) f.fail("expected CELLS n size");
      const long long a = get_long(f, tok[1], "the number of cells"), sz = get_long(f, tok[2], "the size of the cell list");
      if (a < 0 || sz < 0) f.fail("CELLS sizes must not be negative");
      const int cells_line = f.line();
      // VTK 5.1: OFFSETS type \n a values, CONNECTIVITY type \n sz values.
      const size_t save = f.pos();
      std::string_view probe;
      bool offsets = false;
      if (f.next(probe) && upper(trim(probe)).rfind("OFFSETS", 0) == 0) offsets = true;
      else f.seek(save);
      if (offsets) {
        std::vector<std::string_view> ot;
        split(probe, ot);
        BigEndian o{f, f.pos()};
        const size_t each = o.size_of(ot.size() > 1 ? ot[1] : "");
        o.check(static_cast<uint64_t>(a), each, "OFFSETS");
        for (long long i = 0; i < a; ++i) cells.start.push_back(o.integer(each));
        o.done();
        keyword_line(more);
        if (!more || upper(tok[0]) != "CONNECTIVITY") f.fail("expected CONNECTIVITY after OFFSETS");
        BigEndian c{f, f.pos()};
        const size_t ce = c.size_of(tok.size() > 1 ? tok[1] : "");
        c.check(static_cast<uint64_t>(sz), ce, "CONNECTIVITY");
        for (long long i = 0; i < sz; ++i) cells.conn.push_back(c.integer(ce));
        c.done();
        if (cells.start.empty() || cells.start[0] != 0) f.fail("OFFSETS must start with 0");
        for (size_t i = 1; i < cells.start.size(); ++i) {
          if (cells.start[i] < cells.start[i - 1] || cells.start[i] > sz)
            f.fail("OFFSETS must increase and stay within the " + std::to_string(sz) + " CONNECTIVITY entries");
          cells.line.push_back(cells_line);
        }
        if (a == 0) cells.start.assign(1, 0);
        if (cells.start.back() != sz)
          f.fail("CELLS says " + std::to_string(sz) + " CONNECTIVITY entries, but the last offset is " +
                 std::to_string(cells.start.back()));
      } else {
        b.check(static_cast<uint64_t>(sz), 4, "CELLS");
        cells.start.push_back(0);
        long long used = 0;
        for (long long c = 0; c < a; ++c) {
          if (used >= sz) f.fail("cell " + std::to_string(c) + " overruns the CELLS size " + std::to_string(sz));
          const long long n = b.integer(4);
          ++used;
          if (n < 0 || n > sz - used) f.fail("cell " + std::to_string(c) + " overruns the CELLS size " + std::to_string(sz));
          for (long long k = 0; k < n; ++k) cells.conn.push_back(b.integer(4));
          used += n;
          cells.start.push_back(static_cast<long long>(cells.conn.size()));
          cells.line.push_back(cells_line);
        }
        if (used != sz)
          f.fail("CELLS says the cell list holds " + std::to_string(sz) + " integers, but its " + std::to_string(a) +
                 " cells hold " + std::to_string(used));
        b.done();
      }
      have_cells = true;
    } else if (key == "CELL_TYPES") {
      if (tok.size() < 2) f.fail("expected CELL_TYPES n");
      const long long n = get_long(f, tok[1], "the number of cell types");
      if (n < 0) f.fail("the number of cell types must not be negative");
      b.check(static_cast<uint64_t>(n), 4, "CELL_TYPES");
      for (long long i = 0; i < n; ++i) cells.types.push_back(b.integer(4));
      b.done();
      have_types = true;
    } else if (key == "POINT_DATA" || key == "CELL_DATA" || key == "FIELD") {
      break;  // fields are not part of the mesh
    } else if (key == "METADATA") {
      while (f.next(line) && !trim(line).empty()) {
      }
    } else {
      f.fail("unexpected keyword " + quote(tok[0]) + "; expected POINTS, CELLS or CELL_TYPES");
    }
  }
  if (!have_points || !have_cells || !have_types)
    throw Error(path + ": missing " + std::string(!have_points ? "POINTS" : !have_cells ? "CELLS" : "CELL_TYPES") + " section");
  add_cells(raw, cells, f);
  return finish(raw, path, kKinds);
}

Mesh read_legacy(const std::string& path) {
  TextFile f(path);
  std::string_view line;
  if (!f.next(line) || line.substr(0, 14) != "# vtk DataFile")
    f.fail("not a legacy VTK file (first line must start with '# vtk DataFile')");
  if (!f.next(line)) f.fail("unexpected end of file after the header");  // title
  if (!f.next(line)) f.fail("unexpected end of file, expected ASCII or BINARY");
  const std::string fmt = upper(trim(line));
  if (fmt == "BINARY") return read_legacy_binary(f, path);
  if (fmt != "ASCII") f.fail("expected ASCII or BINARY, got " + quote(line));

  Tokens t{f, {}, 0};
  if (upper(t.need("DATASET")) != "DATASET") f.fail("expected DATASET UNSTRUCTURED_GRID");
  std::string_view kind = t.need("UNSTRUCTURED_GRID");
  if (upper(kind) != "UNSTRUCTURED_GRID")
    f.fail("dataset " + quote(kind) + " is not supported; allowed: UNSTRUCTURED_GRID");

  RawMesh raw;
  Cells cells;
  bool have_points = false, have_cells = false, have_types = false;
  std::string last;  // the last counted section, for values past its count
  std::string_view kw;
  while (t.next(kw)) {
    const std::string key = upper(kw);
    if (key == "POINTS") {
      const int hline = f.line();
      const long long n = t.need_long("the number of points");
      if (n < 0) f.fail("the number of points must not be negative");
      check_point_count(f, n);
      t.need("the point data type");
      for (long long p = 0; p < n; ++p) {
        double x[3];
        for (int c = 0; c < 3; ++c)
          x[c] = get_coord(f, t.item("a point coordinate", "POINTS " + std::to_string(n), hline, 3 * n, 3 * p + c),
                           "a point coordinate");
        raw.add_node(f, p, x);
      }
      have_points = true;
      last = "POINTS " + std::to_string(n) + " on line " + std::to_string(hline);
    } else if (key == "CELLS") {
      if (have_cells) f.fail("a second CELLS section; a legacy .vtk file has one");
      const int hline = f.line();
      long long a = t.need_long("the number of cells");
      long long b = t.need_long("the size of the cell list");
      if (a < 0 || b < 0) f.fail("CELLS sizes must not be negative");
      std::string_view next = a > 0 ? t.need("cell data") : std::string_view();
      if (a == 0) {
        cells.start.assign(1, 0);
      } else if (upper(next) == "OFFSETS") {  // VTK 5.1: a = ncell + 1 offsets, b connectivity entries
        t.need("the offsets data type");
        for (long long i = 0; i < a; ++i) {
          cells.start.push_back(get_long(f, t.item("a cell offset", "CELLS (OFFSETS)", hline, a, i), "a cell offset"));
          if (i > 0) cells.line.push_back(f.line());
        }
        if (upper(t.need("CONNECTIVITY")) != "CONNECTIVITY")
          f.fail("CELLS on line " + std::to_string(hline) + " says " + std::to_string(a) +
                 " OFFSETS, but more follow (expected CONNECTIVITY)");
        t.need("the connectivity data type");
        for (long long i = 0; i < b; ++i)
          cells.conn.push_back(get_long(f, t.item("a node index", "CELLS (CONNECTIVITY)", hline, b, i), "a node index"));
        if (cells.start.empty() || cells.start[0] != 0) f.fail("OFFSETS must start with 0");
        for (size_t i = 1; i < cells.start.size(); ++i)
          if (cells.start[i] < cells.start[i - 1] || cells.start[i] > b)
            f.fail("OFFSETS must increase and stay within the " + std::to_string(b) + " CONNECTIVITY entries");
        if (cells.start.back() != b)
          f.fail("CELLS on line " + std::to_string(hline) + " says " + std::to_string(b) +
                 " CONNECTIVITY entries, but the last offset is " + std::to_string(cells.start.back()));
      } else {  // classic: a cells, b integers "npts id id ..." in all
        cells.start.push_back(0);
        long long used = 0;
        const std::string H = "CELLS " + std::to_string(a) + " " + std::to_string(b) + " (its cells)";
        for (long long c = 0; c < a; ++c) {
          long long n = get_long(f, c == 0 ? next : t.item("the node count of a cell", H, hline, a, c), "the node count of a cell");
          if (n < 0 || n > b - used - 1) f.fail("cell " + std::to_string(c) + " overruns the CELLS size " + std::to_string(b));
          cells.line.push_back(f.line());
          for (long long k = 0; k < n; ++k)
            cells.conn.push_back(get_long(f, t.item("a node index", "cell " + std::to_string(c) + "'s node count", f.line(), n, k), "a node index"));
          cells.start.push_back(static_cast<long long>(cells.conn.size()));
          used += 1 + n;
        }
        if (used != b)
          f.fail("CELLS on line " + std::to_string(hline) + " says the cell list holds " + std::to_string(b) +
                 " integers, but its " + std::to_string(a) + " cells hold " + std::to_string(used));
      }
      have_cells = true;
      last = "CELLS on line " + std::to_string(hline);
    } else if (key == "CELL_TYPES") {
      if (have_types) f.fail("a second CELL_TYPES section; a legacy .vtk file has one");
      const int hline = f.line();
      const long long n = t.need_long("the number of cell types");
      if (n < 0) f.fail("the number of cell types must not be negative");
      for (long long c = 0; c < n; ++c)
        cells.types.push_back(get_long(f, t.item("a cell type", "CELL_TYPES " + std::to_string(n), hline, n, c), "a cell type"));
      have_types = true;
      last = "CELL_TYPES " + std::to_string(n) + " on line " + std::to_string(hline);
    } else if (key == "METADATA") {  // ends at a blank line
      t.drop_line();
      while (f.next(line) && !trim(line).empty()) {
      }
    } else if (key == "POINT_DATA" || key == "CELL_DATA" || key == "FIELD") {
      break;  // fields are not part of the mesh
    } else {
      double v;
      if (!last.empty() && parse_double(kw, v))
        f.fail(last + " announces fewer values than follow (" + quote(kw) + " is one too many)");
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
  std::string name, format, type;
  size_t tag_pos = 0, begin = 0, end = 0;  // start tag, content [begin, end)
  int ncomp = 1;
  long long offset = -1;                   // format="appended": into the appended data
};

// How the file's binary DataArrays are laid out (the VTKFile tag and
// <AppendedData>).
struct Binary {
  VtkBlockFormat fmt;
  bool header_given = false;  // header_type present; else UInt32, or both tried where the block must fill its text
  bool appended_base64 = false;
  std::string_view appended;  // after the '_' to </AppendedData>
  std::vector<long long> offsets;  // of every appended array, sorted (a base64 array ends at the next)
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
    a.format = attr(tag, "format");
    a.type = attr(tag, "type");
    if (a.format != "ascii" && a.format != "binary" && a.format != "appended")
      x.fail(p, "DataArray '" + a.name + "' has " +
                    (a.format.empty() ? std::string("no format attribute") : "format=\"" + a.format + "\"") +
                    "; allowed: ascii, binary, appended");
    if (a.format == "appended") {
      long long off = -1;
      if (!parse_long(attr(tag, "offset"), off) || off < 0) x.fail(p, "DataArray '" + a.name + "' is appended but has no offset >= 0");
      a.offset = off;
    }
    std::string nc = attr(tag, "NumberOfComponents");
    if (!nc.empty()) {  // (atoi wrapped on overflow)
      long long v = 0;
      if (!parse_long(nc, v) || v < 1 || v > 1000)
        x.fail(p, "DataArray '" + a.name + "' has NumberOfComponents=\"" + nc.substr(0, 40) + "\"; allowed: 1 to 1000");
      a.ncomp = static_cast<int>(v);
    }
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

// The bytes of a binary or appended DataArray.
std::string block_bytes(const Xml& x, const DataArray& a, const Binary& bin) {
  const std::string ctx = x.path + ":" + std::to_string(x.line_of(a.tag_pos)) + ": DataArray '" + a.name + "'";
  auto with = [&](bool u64) {
    VtkBlockFormat f = bin.fmt;
    f.uint64_header = u64;
    if (a.format == "binary") return decode_inline_block(std::string_view(x.s).substr(a.begin, a.end - a.begin), f, ctx);
    if (bin.appended.data() == nullptr) throw Error(ctx + ": format=\"appended\" but the file has no <AppendedData>");
    if (!bin.appended_base64) {
      if (static_cast<size_t>(a.offset) > bin.appended.size())
        throw Error(ctx + ": offset " + std::to_string(a.offset) + " is beyond the appended data (" + std::to_string(bin.appended.size()) + " bytes)");
      size_t pos = static_cast<size_t>(a.offset);
      return read_vtk_block(bin.appended, pos, f, ctx);
    }
    // base64: this array's text runs to the next array's offset.
    size_t end = bin.appended.size();
    for (long long o : bin.offsets)
      if (o > a.offset) {
        end = std::min(end, static_cast<size_t>(o));
        break;
      }
    if (static_cast<size_t>(a.offset) > end) throw Error(ctx + ": offset " + std::to_string(a.offset) + " is beyond the appended data");
    return decode_inline_block(bin.appended.substr(static_cast<size_t>(a.offset), end - static_cast<size_t>(a.offset)), f, ctx);
  };
  // Without header_type the spec's UInt32; both sizes are tried only where a
  // wrong guess cannot pass (the block must fill its base64 text exactly:
  // meshio writes UInt64 headers in version 0.1 files).
  const bool filled = a.format == "binary" || bin.appended_base64;
  if (bin.header_given || !filled) return with(bin.fmt.uint64_header);
  try {
    return with(false);
  } catch (const Error&) {
    return with(true);  // its error names what does not fit
  }
}

// Numbers of a DataArray; line numbers are computed only on error.
template <class T>
std::vector<T> numbers(const Xml& x, const DataArray& a, const Binary& bin) {
  if (a.format != "ascii") {
    const std::string ctx = x.path + ":" + std::to_string(x.line_of(a.tag_pos)) + ": DataArray '" + a.name + "'";
    const std::string bytes = block_bytes(x, a, bin);
    if constexpr (std::is_same_v<T, double>) return vtk_values_as_double(bytes, a.type, ctx);
    else return vtk_values_as_int(bytes, a.type, ctx);
  }
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
  // The XML ends where raw appended data (any bytes) begins: tags are looked
  // up in the text before it only.
  const size_t app = f.text().find("<AppendedData");
  const std::string head_copy = app == std::string::npos ? std::string() : f.text().substr(0, app);
  const Xml x{app == std::string::npos ? f.text() : head_copy, path};
  size_t b = 0;
  if (x.s.find("<VTKFile") == std::string::npos) throw Error(path + ": not a VTK XML file (no <VTKFile>)");
  b = x.s.find("<VTKFile");
  const std::string_view vtk_tag = std::string_view(x.s).substr(b, x.s.find('>', b) - b);
  std::string type = attr(vtk_tag, "type");
  Binary bin;
  if (attr(vtk_tag, "byte_order") == "BigEndian") x.fail(b, "byte_order=\"BigEndian\" is not supported; allowed: LittleEndian");
  const std::string header_type = attr(vtk_tag, "header_type");
  if (!header_type.empty() && header_type != "UInt32" && header_type != "UInt64")
    x.fail(b, "header_type=\"" + header_type + "\" is not supported; allowed: UInt32, UInt64");
  bin.header_given = !header_type.empty();
  bin.fmt.uint64_header = header_type == "UInt64";
  const std::string compressor = attr(vtk_tag, "compressor");
  if (!compressor.empty() && compressor != "vtkZLibDataCompressor")
    x.fail(b, "compressor=\"" + compressor + "\" is not supported; allowed: vtkZLibDataCompressor (or none)");
  bin.fmt.zlib = !compressor.empty();
  if (app != std::string::npos) {
    const std::string& all = f.text();
    const size_t gt = all.find('>', app);
    const size_t us = gt == std::string::npos ? gt : all.find('_', gt);
    const size_t close = all.rfind("</AppendedData>");
    if (us == std::string::npos || close == std::string::npos || close < us)
      throw Error(path + ": <AppendedData> has no '_' marker or is not closed");
    const std::string enc = attr(std::string_view(all).substr(app, gt - app), "encoding");
    if (enc != "raw" && enc != "base64")
      throw Error(path + ": <AppendedData encoding=\"" + enc + "\"> is not supported; allowed: raw, base64");
    bin.appended_base64 = enc == "base64";
    bin.appended = std::string_view(all).substr(us + 1, close - us - 1);
    if (bin.appended_base64) {  // the text up to the closing tag, without the blanks before it
      while (!bin.appended.empty() && std::isspace(static_cast<unsigned char>(bin.appended.back()))) bin.appended.remove_suffix(1);
    }
  }
  if (type != "UnstructuredGrid")
    x.fail(b, "VTKFile type \"" + type + "\" is not supported; allowed: UnstructuredGrid (.vtu)");
  for (const auto& a : arrays_in(x, 0, x.s.size()))
    if (a.offset >= 0) bin.offsets.push_back(a.offset);
  std::sort(bin.offsets.begin(), bin.offsets.end());
  size_t pb, pe;
  if (!section(x, "Piece", pb, pe)) x.fail(b, "no <Piece> in the UnstructuredGrid");
  if (x.s.find("<Piece", pe) != std::string::npos) x.fail(pe, "more than one <Piece>; only single-piece .vtu files are supported");
  // The Piece's counts, checked against the arrays below.
  const std::string_view piece_tag = std::string_view(x.s).substr(pb, x.s.find('>', pb) - pb);
  auto piece_count = [&](const char* name) {
    long long n = -1;
    if (!parse_long(attr(piece_tag, name), n) || n < 0)
      x.fail(pb, std::string("<Piece> needs ") + name + "=\"n\" (n >= 0), got " + quote(attr(piece_tag, name)));
    return n;
  };
  const long long npoint = piece_count("NumberOfPoints"), ncell = piece_count("NumberOfCells");

  RawMesh raw;
  size_t sb, se;
  if (!section(x, "Points", sb, se)) x.fail(pb, "no <Points> in the <Piece>");
  auto parr = arrays_in(x, sb, se);
  if (parr.empty()) x.fail(sb, "<Points> has no DataArray");
  if (parr[0].ncomp != 3) x.fail(parr[0].tag_pos, "Points DataArray must have NumberOfComponents=\"3\"");
  auto pts = numbers<double>(x, parr[0], bin);
  if (pts.size() % 3) x.fail(parr[0].tag_pos, "Points DataArray has " + std::to_string(pts.size()) + " values, not a multiple of 3");
  if (static_cast<long long>(pts.size() / 3) != npoint)
    x.fail(parr[0].tag_pos, "<Piece NumberOfPoints=\"" + std::to_string(npoint) + "\"> but the Points DataArray holds " +
                                std::to_string(pts.size() / 3) + " points");
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
  c.conn = numbers<long long>(x, *conn, bin);
  auto off = numbers<long long>(x, *offs, bin);
  c.types = numbers<long long>(x, *types, bin);
  for (const auto& [arr, n] : {std::pair<const DataArray*, size_t>{offs, off.size()}, {types, c.types.size()}})
    if (static_cast<long long>(n) != ncell)
      x.fail(arr->tag_pos, "<Piece NumberOfCells=\"" + std::to_string(ncell) + "\"> but the " + arr->name +
                               " DataArray holds " + std::to_string(n) + " values");
  if (!off.empty() && off.back() != static_cast<long long>(c.conn.size()))
    x.fail(offs->tag_pos, "the last offset is " + std::to_string(off.back()) + ", but the connectivity DataArray holds " +
                              std::to_string(c.conn.size()) + " values");
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
