// Shared plumbing of the mesh readers and writers (see engine/mesh/mesh_text.h).
#include "engine/mesh/mesh_text.h"

#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "engine/util/error.h"
#include "engine/util/file_io.h"

namespace incise::meshio {

TextFile::TextFile(std::string path) : path_(std::move(path)) {
  text_ = read_input_file(path_, kMaxMeshBytes, "mesh file");
}

TextFile TextFile::from_text(std::string path, std::string text) {
  TextFile f;
  f.path_ = std::move(path);
  f.text_ = std::move(text);
  return f;
}

bool TextFile::next(std::string_view& line) {
  if (pos_ >= text_.size()) return false;
  size_t end = text_.find('\n', pos_);
  if (end == std::string::npos) end = text_.size();
  line = std::string_view(text_).substr(pos_, end - pos_);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  pos_ = end + 1;
  ++line_;
  return true;
}

void TextFile::fail_at(int line, const std::string& msg) const {
  throw Error(path_ + ":" + std::to_string(line) + ": " + msg);
}

std::string_view trim(std::string_view s) {
  const char* ws = " \t\r\n\f\v";
  size_t b = s.find_first_not_of(ws);
  if (b == std::string_view::npos) return {};
  size_t e = s.find_last_not_of(ws);
  return s.substr(b, e - b + 1);
}

void split(std::string_view s, std::vector<std::string_view>& out, bool comma) {
  out.clear();
  size_t i = 0, n = s.size();
  auto sep = [&](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || (comma && c == ',');
  };
  while (i < n) {
    while (i < n && sep(s[i])) ++i;
    size_t b = i;
    while (i < n && !sep(s[i])) ++i;
    if (i > b) out.push_back(s.substr(b, i - b));
  }
}

std::string upper(std::string_view s) {
  std::string r(s);
  for (char& c : r) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return r;
}

std::string quote(std::string_view s) {
  if (s.size() > 40) return "'" + std::string(s.substr(0, 40)) + "...'";
  return "'" + std::string(s) + "'";
}

// Both reject out-of-range values (from_chars reports them) and "+-1".
bool parse_long(std::string_view s, long long& v) {
  if (!s.empty() && s[0] == '+') {
    s.remove_prefix(1);
    if (!s.empty() && s[0] == '-') return false;
  }
  auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_double(std::string_view s, double& v) {
  if (!s.empty() && s[0] == '+') {
    s.remove_prefix(1);
    if (!s.empty() && s[0] == '-') return false;
  }
  auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

long long get_long(const TextFile& f, std::string_view tok, const char* what) {
  long long v = 0;
  if (!parse_long(tok, v)) f.fail(std::string("expected ") + what + " (an integer), got " + quote(tok));
  return v;
}

double get_double(const TextFile& f, std::string_view tok, const char* what) {
  double v = 0;
  if (!parse_double(tok, v)) f.fail(std::string("expected ") + what + " (a number), got " + quote(tok));
  return v;
}

double get_coord(const TextFile& f, std::string_view tok, const char* what) {
  double v = get_double(f, tok, what);
  if (!std::isfinite(v)) f.fail(std::string(what) + " is " + quote(tok) + "; coordinates must be finite");
  return v;
}

void RawMesh::add_node(const TextFile& f, long long tag, const double x[3]) {
  int row = static_cast<int>(X.size() / 3);
  if (!index.emplace(tag, row).second) f.fail("node " + std::to_string(tag) + " is defined twice");
  X.insert(X.end(), x, x + 3);
}

void RawMesh::add_tet(const TextFile& f, long long elem_id, const long long* node_tags, int n) {
  if (npe == 0) npe = n;
  if (n != npe)
    f.fail("element " + std::to_string(elem_id) + " has " + std::to_string(n) +
           " nodes but earlier tetrahedra have " + std::to_string(npe) +
           "; mixed tet4/tet10 meshes are not supported");
  tags.insert(tags.end(), node_tags, node_tags + n);
  line.push_back(f.line());
  id.push_back(elem_id);
}

Mesh finish(const RawMesh& raw, const std::string& path, const std::string& kinds) {
  if (raw.id.empty()) throw Error(path + ": no tetrahedra found (looked for " + kinds + ")");
  const int npe = raw.npe, nraw = static_cast<int>(raw.X.size() / 3);
  std::vector<int> tet(raw.tags.size());
  std::vector<char> used(nraw, 0);
  for (size_t e = 0; e < raw.id.size(); ++e) {
    for (int a = 0; a < npe; ++a) {
      long long t = raw.tags[e * npe + a];
      auto it = raw.index.find(t);
      if (it == raw.index.end())
        throw Error(path + ":" + std::to_string(raw.line[e]) + ": element " + std::to_string(raw.id[e]) +
                    " references node " + std::to_string(t) + ", which is not among the " +
                    std::to_string(nraw) + " nodes defined");
      tet[e * npe + a] = it->second;
      used[it->second] = 1;
    }
  }
  // Renumber densely in file order; identity when every node is used.
  std::vector<int> newid(nraw, -1);
  Mesh m;
  m.order = npe == 10 ? 2 : 1;
  m.source = path;
  m.X.reserve(raw.X.size());
  for (int i = 0; i < nraw; ++i) {
    if (!used[i]) continue;
    newid[i] = static_cast<int>(m.X.size() / 3);
    m.X.insert(m.X.end(), raw.X.begin() + 3 * i, raw.X.begin() + 3 * i + 3);
  }
  for (int& v : tet) v = newid[v];
  m.tet = std::move(tet);
  m.elem_file_id = raw.id;
  m.elem_line = raw.line;
  return m;
}

void appendf(std::string& out, const char* fmt, ...) {
  char buf[256];
  va_list ap;
  va_start(ap, fmt);
  int n = std::vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  if (n < 0) return;
  if (static_cast<size_t>(n) < sizeof buf) {
    out.append(buf, n);
    return;
  }
  std::string big(n + 1, '\0');
  va_start(ap, fmt);
  std::vsnprintf(big.data(), big.size(), fmt, ap);
  va_end(ap);
  out.append(big.data(), n);
}

}  // namespace incise::meshio
