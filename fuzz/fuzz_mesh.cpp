// Fuzzes the mesh readers through incise::read_mesh (engine/mesh/mesh_io.h):
// Gmsh .msh 2.2/4.1, legacy .vtk, XML .vtu, TetGen .node/.ele, Abaqus .inp.
// The readers take a path, so each input is written to a file in a private
// folder (fuzz/fuzz_tmp.h: /dev/shm/incise-fuzz-mesh.PID) and read back.
//
// Input: one format byte, then the file's text. 'g' .msh, 'k' .vtk, 'u' .vtu,
// 't' TetGen, 'a' .inp; any other byte picks by its value mod 5. For TetGen
// the text is the .node file, then a line "#--ele--", then the .ele file.
// Only incise::Error may escape (the readers' documented failure); a mesh
// that is returned must be consistent (ids in range, finite coordinates), and
// then goes through check_mesh (engine/mesh/mesh_tools.h).
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "engine/mesh/mesh_io.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/util/error.h"
#include "fuzz/fuzz_tmp.h"

namespace {

[[noreturn]] void bad_mesh(const char* what) {
  std::fprintf(stderr, "fuzz_mesh: read_mesh returned an inconsistent mesh: %s\n", what);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz_tmp::init("incise-fuzz-mesh.", {"in.msh", "in.vtk", "in.vtu", "in.node", "in.ele", "in.inp"});
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* const kExt[5] = {".msh", ".vtk", ".vtu", ".node", ".inp"};
  int fmt = data[0] % 5;
  switch (data[0]) {
    case 'g': fmt = 0; break;
    case 'k': fmt = 1; break;
    case 'u': fmt = 2; break;
    case 't': fmt = 3; break;
    case 'a': fmt = 4; break;
  }
  const char* text = reinterpret_cast<const char*>(data + 1);
  const std::string path = fuzz_tmp::g_dir + "/in" + kExt[fmt];
  if (fmt == 3) {
    const std::string all(text, size - 1), sep = "#--ele--\n";
    const size_t at = all.find(sep);
    const size_t node_n = at == std::string::npos ? all.size() : at;
    const size_t ele_at = at == std::string::npos ? all.size() : at + sep.size();
    fuzz_tmp::put("in.node", all.data(), node_n);
    fuzz_tmp::put("in.ele", all.data() + ele_at, all.size() - ele_at);
  } else {
    fuzz_tmp::put(std::string("in") + kExt[fmt], text, size - 1);
  }
  try {
    const incise::Mesh m = incise::read_mesh(path);
    if (m.order != 1 && m.order != 2) bad_mesh("order");
    if (m.X.size() % 3 != 0 || m.tet.empty() || m.tet.size() % m.npe() != 0) bad_mesh("array sizes");
    for (int v : m.tet)
      if (v < 0 || v >= m.nnode()) bad_mesh("node id out of range");
    for (double x : m.X)
      if (!std::isfinite(x)) bad_mesh("non-finite coordinate");
    if (!m.elem_line.empty() && m.elem_line.size() != static_cast<size_t>(m.ntet())) bad_mesh("elem_line size");
    incise::check_mesh(m);  // geometry (volumes, tet10 det J): what every consumer runs next
  } catch (const incise::Error&) {
    // the documented failure: "FILE:LINE: what was wrong"
  }
  return 0;
}
