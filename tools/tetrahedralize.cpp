#include "tools/tetrahedralize.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "engine/mesh/mesh_io.h"
#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "tools/spawn.h"

namespace incise {

namespace {
namespace fs = std::filesystem;

std::string lower_ext(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

// OBJ (v and f lines; "f a/b/c ..." and negative indices; polygons fanned)
// as OFF, which TetGen reads.
void obj_to_off(const std::string& obj, const std::string& off) {
  std::istringstream in(read_input_file(obj, kMaxTableBytes, "surface file"));
  std::vector<double> v;
  std::vector<std::vector<long>> faces;
  std::string line;
  for (int lineno = 1; std::getline(in, line); ++lineno) {
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "v") {
      double x, y, z;
      if (!(ls >> x >> y >> z) || !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
        throw Error(obj + ":" + std::to_string(lineno) + ": a vertex needs three finite coordinates");
      v.insert(v.end(), {x, y, z});
    } else if (key == "f") {
      std::vector<long> f;
      std::string tok;
      while (ls >> tok) {
        long i = 0;
        try {
          i = std::stol(tok.substr(0, tok.find('/')));
        } catch (const std::exception&) {
          throw Error(obj + ":" + std::to_string(lineno) + ": bad face index '" + tok + "'");
        }
        const long nv = static_cast<long>(v.size() / 3);
        i = i < 0 ? nv + i : i - 1;
        if (i < 0 || i >= nv) throw Error(obj + ":" + std::to_string(lineno) + ": face index '" + tok + "' names no vertex defined before it");
        f.push_back(i);
      }
      if (f.size() < 3) throw Error(obj + ":" + std::to_string(lineno) + ": a face needs at least 3 vertices");
      faces.push_back(f);
    }
  }
  std::ofstream os(off);
  os.precision(17);
  os << "OFF\n" << v.size() / 3 << ' ' << faces.size() << " 0\n";
  for (size_t i = 0; i < v.size(); i += 3) os << v[i] << ' ' << v[i + 1] << ' ' << v[i + 2] << '\n';
  for (const auto& f : faces) {
    os << f.size();
    for (long i : f) os << ' ' << i;
    os << '\n';
  }
  if (!os) throw Error(off + ": cannot write");
}

std::string tail_of(const std::string& path, int lines) {
  std::ifstream in(path);
  std::vector<std::string> all;
  for (std::string l; std::getline(in, l);) all.push_back(l);
  std::string out;
  for (size_t i = all.size() > static_cast<size_t>(lines) ? all.size() - lines : 0; i < all.size(); ++i) out += "\n  " + all[i];
  return out;
}

}  // namespace

Mesh tetrahedralize(const std::string& surface, double size, double quality) {
  if (!(size > 0.0) || !std::isfinite(size)) throw Error("mesh tetrahedralize: --size must be a finite length > 0");
  if (!(quality >= 1.1) || !std::isfinite(quality)) throw Error("mesh tetrahedralize: --quality must be >= 1.1 (TetGen's bound)");
  const std::string ext = lower_ext(surface);
  if (ext != ".stl" && ext != ".ply" && ext != ".off" && ext != ".obj")
    throw Error(surface + ": a surface to tetrahedralize must be .stl, .ply, .off or .obj");
  std::string tmpl = (fs::temp_directory_path() / "incise_tet_XXXXXX").string();
  if (!mkdtemp(tmpl.data())) throw Error("mesh tetrahedralize: cannot make a temporary folder in " + fs::temp_directory_path().string());
  const fs::path tmp = tmpl;
  struct Cleanup {
    fs::path p;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(p, ec);
    }
  } cleanup{tmp};
  // TetGen 1.5 reads ASCII STL only; a binary one (80-byte header, a
  // triangle count, 50 bytes a triangle) made it abort, and the error then
  // blamed the surface's shape.
  if (ext == ".stl") {
    check_input_file(surface, kMaxMeshBytes, "surface");
    std::ifstream is(surface, std::ios::binary);
    char head[84] = {0};
    is.read(head, sizeof head);
    std::uint32_t ntri = 0;
    std::memcpy(&ntri, head + 80, 4);
    const std::uintmax_t bytes = fs::file_size(surface);
    if (is.gcount() == 84 && bytes == 84 + 50 * static_cast<std::uintmax_t>(ntri))
      throw Error(surface + ": a binary STL (" + std::to_string(ntri) +
                  " triangles); TetGen reads ASCII STL only: convert it to ASCII STL or OBJ (e.g. meshio convert "
                  "--ascii in.stl out.stl)");
  }
  const fs::path in = tmp / (std::string("surface") + (ext == ".obj" ? ".off" : ext));
  if (ext == ".obj") obj_to_off(surface, in.string());
  else fs::copy_file(surface, in);
  // A regular tetrahedron of edge `size`: volume size^3 / (6 sqrt 2).
  char switches[96];
  std::snprintf(switches, sizeof switches, "-pq%ga%g", quality, size * size * size / (6.0 * std::sqrt(2.0)));
  const std::string log = (tmp / "tetgen.log").string();
  int rc = 0;
  try {
    rc = spawn_and_wait({"tetgen", switches, in.string()}, log);
  } catch (const Error&) {
    throw Error(surface + ": cannot run TetGen (apt-get install tetgen)");
  }
  const fs::path ele = tmp / "surface.1.ele";
  if (rc != 0)
    throw Error(surface + ": TetGen failed (exit " + std::to_string(rc) +
                "); the surface must be closed, manifold and not self-intersecting. TetGen said:" + tail_of(log, 6));
  std::ifstream e(ele);
  long n = 0;
  if (!(e >> n)) n = 0;
  if (n <= 0)
    throw Error(surface + ": TetGen made no tetrahedra: the surface is not closed (or not manifold). TetGen said:" + tail_of(log, 6));
  Mesh m = read_mesh(ele.string());
  m.source = surface;
  return m;
}

}  // namespace incise
