// Fuzzes the mesh readers through incise::read_mesh (engine/mesh/mesh_io.h):
// Gmsh .msh 2.2/4.1, legacy .vtk, XML .vtu, TetGen .node/.ele, Abaqus .inp.
// The readers take a path, so each input is written to a file in a private
// folder under /dev/shm (else $TMPDIR or /tmp), incise-fuzz-mesh.PID, and read
// back; the folder is removed at exit (or by the next run, after a crash).
//
// Input: one format byte, then the file's text. 'g' .msh, 'k' .vtk, 'u' .vtu,
// 't' TetGen, 'a' .inp; any other byte picks by its value mod 5. For TetGen
// the text is the .node file, then a line "#--ele--", then the .ele file.
// Only incise::Error may escape (the readers' documented failure); a mesh
// that is returned must be consistent (ids in range, finite coordinates), and
// then goes through check_mesh (engine/mesh/mesh_tools.h).
#include <dirent.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

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

namespace {

std::string g_dir;

void put_file(const std::string& path, const char* data, size_t n) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || std::fwrite(data, 1, n, f) != n || std::fclose(f) != 0) {
    std::perror(path.c_str());
    std::abort();  // the harness's fault, not the reader's
  }
}

void remove_files(const std::string& dir) {
  for (const char* ext : {".msh", ".vtk", ".vtu", ".node", ".ele", ".inp"}) std::remove((dir + "/in" + ext).c_str());
  rmdir(dir.c_str());
}

[[noreturn]] void bad_mesh(const char* what) {
  std::fprintf(stderr, "fuzz_mesh: read_mesh returned an inconsistent mesh: %s\n", what);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* tmp = std::getenv("TMPDIR");
  const std::string base = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : tmp ? tmp : "/tmp";
  const std::string prefix = "incise-fuzz-mesh.";
  // Folders of earlier runs that crashed (no atexit then) and whose process is gone.
  if (DIR* d = opendir(base.c_str())) {
    while (const dirent* e = readdir(d)) {
      const std::string name = e->d_name;
      if (name.rfind(prefix, 0) != 0) continue;
      const long pid = std::strtol(name.c_str() + prefix.size(), nullptr, 10);
      if (pid > 0 && kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) remove_files(base + "/" + name);
    }
    closedir(d);
  }
  g_dir = base + "/" + prefix + std::to_string(getpid());
  if (mkdir(g_dir.c_str(), 0700) != 0 && errno != EEXIST) {
    std::perror(("fuzz_mesh: mkdir " + g_dir).c_str());
    std::abort();
  }
  std::atexit([] { remove_files(g_dir); });
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
  const std::string path = g_dir + "/in" + kExt[fmt];
  if (fmt == 3) {
    const std::string all(text, size - 1), sep = "#--ele--\n";
    const size_t at = all.find(sep);
    const size_t node_n = at == std::string::npos ? all.size() : at;
    const size_t ele_at = at == std::string::npos ? all.size() : at + sep.size();
    put_file(g_dir + "/in.node", all.data(), node_n);
    put_file(g_dir + "/in.ele", all.data() + ele_at, all.size() - ele_at);
  } else {
    put_file(path, text, size - 1);
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
