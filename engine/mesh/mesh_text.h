#pragma once
// Internal to the mesh readers/writers (not a public interface): line access
// with line numbers, number parsing that reports FILE:LINE, collection of
// nodes and elements by file tag (atomic writes: engine/util/file_io.h).
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "engine/mesh/mesh.h"

namespace incise::meshio {

// A whole text file in memory, handed out line by line.
class TextFile {
 public:
  explicit TextFile(std::string path);
  // Text already in memory (`path` names it in messages).
  static TextFile from_text(std::string path, std::string text);
  const std::string& path() const { return path_; }
  const std::string& text() const { return text_; }
  // Next line without its end of line ("\n" or "\r\n"); false at end of file.
  bool next(std::string_view& line);
  // Byte position of the next line, and a jump past binary data read from
  // text() (Gmsh binary sections); the line count stays that of the text.
  size_t pos() const { return pos_; }
  void seek(size_t pos) { pos_ = pos; }
  int line() const { return line_; }  // 1-based number of the line last returned
  [[noreturn]] void fail(const std::string& msg) const { fail_at(line_, msg); }
  [[noreturn]] void fail_at(int line, const std::string& msg) const;

 private:
  TextFile() = default;
  std::string path_, text_;
  size_t pos_ = 0;
  int line_ = 0;
};

std::string_view trim(std::string_view s);
// Splits at blanks (and at commas when comma is true); empty fields dropped.
void split(std::string_view s, std::vector<std::string_view>& out, bool comma = false);
std::string upper(std::string_view s);
std::string quote(std::string_view s);  // 'text', shortened for messages

bool parse_long(std::string_view s, long long& v);
bool parse_double(std::string_view s, double& v);
// Throwing variants: "FILE:LINE: expected WHAT, got 'tok'".
long long get_long(const TextFile& f, std::string_view tok, const char* what);
double get_double(const TextFile& f, std::string_view tok, const char* what);
// Like get_double, and rejects NaN/Inf.
double get_coord(const TextFile& f, std::string_view tok, const char* what);

// Nodes and elements as the file names them, resolved once everything is read.
struct RawMesh {
  std::vector<double> X;                     // (nnode, 3)
  std::unordered_map<long long, int> index;  // file node tag -> row of X
  int npe = 0;                               // 4 or 10; 0 until an element is seen
  std::vector<long long> tags;               // (ntet, npe) node tags, our ordering
  std::vector<int> line;                     // (ntet) line each element starts on
  std::vector<long long> id;                 // (ntet) element id in the file

  void add_node(const TextFile& f, long long tag, const double x[3]);
  // node_tags already in the ordering of engine/mesh/mesh.h.
  void add_tet(const TextFile& f, long long elem_id, const long long* node_tags, int n);
};

// Resolves node tags (error names file, line and element), drops nodes no
// tetrahedron uses (a solver would see them as singular rows), and throws if
// the file holds no tetrahedra. `kinds` names what was looked for.
Mesh finish(const RawMesh& raw, const std::string& path, const std::string& kinds);

// Appends printf-formatted text (one number or a short piece) to out.
void appendf(std::string& out, const char* fmt, ...) __attribute__((format(printf, 2, 3)));

Mesh read_gmsh(const std::string& path);
Mesh read_vtk_legacy(const std::string& path);
Mesh read_vtu(const std::string& path);
Mesh read_tetgen(const std::string& path);  // .node or .ele
Mesh read_abaqus(const std::string& path);

}  // namespace incise::meshio
