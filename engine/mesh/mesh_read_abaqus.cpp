// Abaqus / CalculiX .inp reader: *NODE and *ELEMENT with TYPE=C3D4 (tet4) or
// C3D10* (C3D10, C3D10M, C3D10H, ...: tet10). Keywords and parameters are
// case-insensitive, "**" starts a comment line, element data may continue
// over several lines (C3D10 often takes two). Other element types and all
// other keywords (sets, materials, steps) are skipped.
// C3D10 node order equals ours: 5:(1,2) 6:(2,3) 7:(3,1) 8:(1,4) 9:(2,4)
// 10:(3,4) in Abaqus' 1-based numbering.
#include <string>
#include <vector>

#include "engine/util/error.h"
#include "engine/mesh/mesh_text.h"

namespace incise::meshio {
namespace {

// Value of PARAM=value on a keyword line, upper-cased; "" if absent.
std::string param(const std::vector<std::string_view>& fields, const char* name) {
  for (size_t i = 1; i < fields.size(); ++i) {
    std::string_view f = trim(fields[i]);
    size_t eq = f.find('=');
    if (eq != std::string_view::npos && upper(trim(f.substr(0, eq))) == name) return upper(trim(f.substr(eq + 1)));
  }
  return {};
}

void split_commas(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  size_t b = 0;
  while (b <= line.size()) {
    size_t e = line.find(',', b);
    if (e == std::string_view::npos) e = line.size();
    out.push_back(line.substr(b, e - b));
    b = e + 1;
  }
}

}  // namespace

Mesh read_abaqus(const std::string& path) {
  TextFile f(path);
  RawMesh raw;
  enum class Block { Skip, Node, Element } block = Block::Skip;
  int npe = 0;
  std::vector<long long> pending;  // id and node tags of an element not yet complete
  int pending_line = 0;
  std::vector<std::string_view> fields, tok;

  auto close_element = [&]() {
    if (!pending.empty())
      f.fail_at(pending_line, "element " + std::to_string(pending[0]) + " lists " + std::to_string(pending.size() - 1) +
                                  " nodes, but its type needs " + std::to_string(npe));
  };

  std::string_view line;
  while (f.next(line)) {
    line = trim(line);
    if (line.empty() || line.substr(0, 2) == "**") continue;
    if (line[0] == '*') {
      close_element();
      split_commas(line, fields);
      const std::string key = upper(trim(fields[0]));
      block = Block::Skip;
      if (key == "*NODE") {
        block = Block::Node;
      } else if (key == "*ELEMENT") {
        const std::string type = param(fields, "TYPE");
        if (type.empty()) f.fail("*ELEMENT without TYPE=");
        npe = type.rfind("C3D10", 0) == 0 ? 10 : (type == "C3D4" || type == "C3D4H") ? 4 : 0;
        if (npe) block = Block::Element;
      } else if (key == "*INCLUDE") {
        f.fail("*INCLUDE is not supported; paste the included file into " + path);
      }
      continue;
    }
    if (block == Block::Node) {
      split(line, tok, true);
      if (tok.size() < 4) f.fail("expected 'node, x, y, z', got " + quote(line));
      long long tag = get_long(f, tok[0], "a node number");
      double x[3];
      for (int c = 0; c < 3; ++c) x[c] = get_coord(f, tok[1 + c], "a node coordinate");
      raw.add_node(f, tag, x);
    } else if (block == Block::Element) {
      split(line, tok, true);
      if (pending.empty()) pending_line = f.line();
      for (auto t : tok) pending.push_back(get_long(f, t, pending.empty() ? "an element number" : "a node number"));
      if (pending.size() > static_cast<size_t>(1 + npe))
        f.fail("element " + std::to_string(pending[0]) + " lists more than the " + std::to_string(npe) +
               " nodes its type has");
      if (pending.size() == static_cast<size_t>(1 + npe)) {
        raw.add_tet(f, pending[0], pending.data() + 1, npe);
        raw.line.back() = pending_line;
        pending.clear();
      }
    }
  }
  close_element();
  return finish(raw, path, "*ELEMENT TYPE=C3D4 or C3D10");
}

}  // namespace incise::meshio
