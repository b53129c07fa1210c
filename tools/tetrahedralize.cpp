#include "tools/tetrahedralize.h"

#include <algorithm>
#include <array>
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
#include "engine/mesh/mesh_tools.h"
#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "tools/option_checks.h"
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

// The region attribute TetGen's -A gives each tetrahedron of `ele` (the
// last value of its line; one per closed region of the surface), in order.
std::vector<double> region_of_tets(const std::string& ele, int ntet) {
  std::ifstream in(ele);
  std::vector<double> region;
  region.reserve(static_cast<size_t>(ntet));
  std::string line;
  bool header = true;
  while (std::getline(in, line) && static_cast<int>(region.size()) < ntet) {
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream ls(line);
    std::vector<double> v;
    for (double x; ls >> x;) v.push_back(x);
    if (v.empty()) continue;
    if (header) {
      header = false;
      continue;
    }
    region.push_back(v.size() >= 6 ? v.back() : 0.0);
  }
  if (static_cast<int>(region.size()) != ntet) region.assign(static_cast<size_t>(ntet), 0.0);
  return region;
}

// Drops the tetrahedra of regions that no face on the outside bounds (the
// inside of an inner closed shell: a cavity) and the nodes only they used.
// Returns the volume dropped and the number of such regions.
std::pair<double, int> drop_enclosed_regions(Mesh& m, const std::vector<double>& region) {
  struct Face {
    std::array<int, 3> v;
    int tet;
  };
  std::vector<Face> faces;
  faces.reserve(4 * static_cast<size_t>(m.ntet()));
  for (int e = 0; e < m.ntet(); ++e)
    for (const auto& f : kTetFace) {
      std::array<int, 3> v = {m.tet[4 * e + f[0]], m.tet[4 * e + f[1]], m.tet[4 * e + f[2]]};
      std::sort(v.begin(), v.end());
      faces.push_back({v, e});
    }
  std::sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) { return a.v < b.v; });
  std::vector<double> outside;  // regions with a face on the outside
  for (size_t i = 0; i < faces.size();) {
    size_t j = i + 1;
    while (j < faces.size() && faces[j].v == faces[i].v) ++j;
    if (j - i == 1) outside.push_back(region[static_cast<size_t>(faces[i].tet)]);
    i = j;
  }
  std::sort(outside.begin(), outside.end());
  outside.erase(std::unique(outside.begin(), outside.end()), outside.end());
  std::vector<double> all(region);
  std::sort(all.begin(), all.end());
  all.erase(std::unique(all.begin(), all.end()), all.end());
  const int enclosed = static_cast<int>(all.size() - outside.size());
  if (enclosed == 0) return {0.0, 0};
  const auto keep = [&](int e) { return std::binary_search(outside.begin(), outside.end(), region[static_cast<size_t>(e)]); };
  Mesh kept;
  kept.order = 1;
  kept.source = m.source;
  std::vector<int> id(static_cast<size_t>(m.nnode()), -1);
  for (int e = 0; e < m.ntet(); ++e) {
    if (!keep(e)) continue;
    for (int k = 0; k < 4; ++k) {
      int& n = id[static_cast<size_t>(m.tet[4 * e + k])];
      if (n < 0) {
        n = kept.nnode();
        kept.X.insert(kept.X.end(), m.X.begin() + 3 * m.tet[4 * e + k], m.X.begin() + 3 * m.tet[4 * e + k] + 3);
      }
      kept.tet.push_back(n);
    }
    if (!m.elem_file_id.empty()) kept.elem_file_id.push_back(m.elem_file_id[static_cast<size_t>(e)]);
    if (!m.elem_line.empty()) kept.elem_line.push_back(m.elem_line[static_cast<size_t>(e)]);
  }
  const double dropped = mesh_quality(m).total_volume - mesh_quality(kept).total_volume;
  m = std::move(kept);
  return {dropped, enclosed};
}

}  // namespace

Mesh tetrahedralize(const std::string& surface, double size, double quality, bool fill_cavities, std::string* note) {
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
  const fs::path ele = tmp / "surface.1.ele";
  // -p: the surface's constrained tetrahedralization; -A: a region
  // attribute per closed region; -Q: quiet.
  const auto run_tetgen = [&](const std::string& switches) {
    const std::string log = (tmp / "tetgen.log").string();
    int rc = 0;
    try {
      rc = spawn_and_wait({"tetgen", switches, in.string()}, log);
    } catch (const Error&) {
      throw Error(surface + ": cannot run TetGen (apt-get install tetgen)");
    }
    if (rc != 0)
      throw Error(surface + ": TetGen failed (exit " + std::to_string(rc) +
                  "); the surface must be closed, manifold and not self-intersecting. TetGen said:" + tail_of(log, 6));
    std::ifstream e(ele);
    long n = 0;
    if (!(e >> n)) n = 0;
    if (n <= 0)
      throw Error(surface + ": TetGen made no tetrahedra: the surface is not closed (or not manifold). TetGen said:" +
                  tail_of(log, 6));
    Mesh m = read_mesh(ele.string());
    m.source = surface;
    return m;
  };
  // First the surface's own tetrahedra (no refinement, seconds even for a
  // large surface): the volume it encloses, so that a --size that would ask
  // TetGen for billions of tetrahedra is refused before it runs out of
  // memory. TetGen's quality mesh has 2.4-3.5 tetrahedra per volume bound
  // (a sphere at 10 and 20 edges across); 3 is the estimate.
  const double bound = size * size * size / (6.0 * std::sqrt(2.0));  // a regular tetrahedron of edge `size`
  const double volume = mesh_quality(run_tetgen("-pQA")).total_volume;
  const double estimate = 3.0 * volume / bound;
  if (estimate > static_cast<double>(kMaxBeamTets)) {
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  ": --size %g asks for about %.2g tetrahedra (the surface encloses %.3g cubic units); at most %lld: "
                  "use --size %.3g or larger",
                  size, estimate, volume, kMaxBeamTets, size * std::cbrt(estimate / static_cast<double>(kMaxBeamTets)));
    throw Error(surface + buf);
  }
  char switches[96];
  std::snprintf(switches, sizeof switches, "-pQAq%ga%g", quality, bound);
  Mesh m = run_tetgen(switches);
  // TetGen keeps the surface's triangles and grades the inside from them: a
  // surface finer than --size gives many more tetrahedra than it asks for
  // (a 1280-triangle kidney at --size 0.02: 5,521 against about 370), and
  // nothing said why.
  if (note && m.ntet() > 4.0 * estimate && m.ntet() > 1000) {
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "made %d tetrahedra, %.0fx the about %.2g that --size %g asks for: TetGen keeps the surface's "
                  "triangles and grades the inside from them, so a surface finer than --size sets the size; remesh "
                  "the surface coarser for fewer\n",
                  m.ntet(), m.ntet() / std::max(estimate, 1.0), estimate, size);
    *note += buf;
  }
  if (!fill_cavities) {
    const auto [dropped, regions] = drop_enclosed_regions(m, region_of_tets(ele.string(), m.ntet()));
    if (regions > 0 && note) {
      char buf[320];
      std::snprintf(buf, sizeof buf,
                    "left %d enclosed region(s) empty (%.3g cubic units, %.2g%% of the volume): the inside of an inner "
                    "closed shell is a cavity; --fill-cavities fills it with tissue\n",
                    regions, dropped, 100.0 * dropped / volume);
      *note += buf;
    }
  }
  return m;
}

}  // namespace incise
