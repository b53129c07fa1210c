// read_mesh dispatch, mesh and .vtu writers, ParaView .pvd series.
// All writers build the text in memory and write it atomically (temp file +
// rename). Points are printed with %.17g so a write/read round trip is exact.
#include "engine/mesh/mesh_io.h"

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "engine/util/error.h"
#include "engine/mesh/mesh_text.h"
#include "engine/util/file_io.h"

namespace incise {
namespace {

namespace fs = std::filesystem;
using meshio::appendf;

constexpr const char* kReadable =
    ".msh (Gmsh 2.2/4.1 ASCII), .vtk (legacy ASCII), .vtu (XML ASCII), .node/.ele (TetGen), .inp (Abaqus/CalculiX)";
constexpr const char* kWritable = ".vtu, .vtk, .msh (Gmsh 4.1 ASCII)";
constexpr int kToGmshTet10[10] = {0, 1, 2, 3, 4, 5, 6, 7, 9, 8};  // gmsh[k] = ours[kToGmshTet10[k]]

std::string extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// Sizes and ids consistent; coordinates finite. Messages name `path`.
void check_shapes(const Mesh& m, const std::string& path) {
  if (m.order != 1 && m.order != 2) throw Error(path + ": mesh order must be 1 or 2, got " + std::to_string(m.order));
  if (m.X.size() % 3) throw Error(path + ": mesh X size " + std::to_string(m.X.size()) + " is not a multiple of 3");
  if (m.tet.size() % m.npe())
    throw Error(path + ": mesh tet size " + std::to_string(m.tet.size()) + " is not a multiple of " + std::to_string(m.npe()));
  for (size_t i = 0; i < m.tet.size(); ++i)
    if (m.tet[i] < 0 || m.tet[i] >= m.nnode())
      throw Error(path + ": element " + std::to_string(i / m.npe()) + " references node " + std::to_string(m.tet[i]) +
                  ", but only " + std::to_string(m.nnode()) + " nodes are defined");
  // Each reader checks as it parses; this catches a path that forgets (the fuzzer found one).
  for (size_t i = 0; i < m.X.size(); ++i)
    if (!std::isfinite(m.X[i]))
      throw Error(path + ": node " + std::to_string(i / 3) + " has a non-finite coordinate; coordinates must be finite");
}

void points_text(std::string& out, const std::vector<double>& X, const char* sep_line) {
  for (size_t i = 0; i + 2 < X.size(); i += 3) appendf(out, "%.17g %.17g %.17g%s", X[i], X[i + 1], X[i + 2], sep_line);
}

std::string xml_escape(const std::string& s) {
  std::string r;
  for (char c : s) {
    switch (c) {
      case '&': r += "&amp;"; break;
      case '<': r += "&lt;"; break;
      case '>': r += "&gt;"; break;
      case '"': r += "&quot;"; break;
      default: r += c;
    }
  }
  return r;
}

VtuGrid grid_of(const Mesh& m) {
  VtuGrid g;
  g.points = m.X;
  g.connectivity = m.tet;
  const int npe = m.npe();
  for (int e = 0; e < m.ntet(); ++e) {
    g.offsets.push_back((e + 1) * npe);
    g.types.push_back(npe == 10 ? 24 : 10);
  }
  return g;
}

void write_vtk_legacy(const Mesh& m, const std::string& path) {
  std::string s;
  const int npe = m.npe(), ntet = m.ntet();
  s += "# vtk DataFile Version 3.0\nincise mesh\nASCII\nDATASET UNSTRUCTURED_GRID\n";
  appendf(s, "POINTS %d double\n", m.nnode());
  points_text(s, m.X, "\n");
  appendf(s, "CELLS %d %d\n", ntet, ntet * (npe + 1));
  for (int e = 0; e < ntet; ++e) {
    appendf(s, "%d", npe);
    for (int a = 0; a < npe; ++a) appendf(s, " %d", m.tet[e * npe + a]);
    s += '\n';
  }
  appendf(s, "CELL_TYPES %d\n", ntet);
  for (int e = 0; e < ntet; ++e) s += npe == 10 ? "24\n" : "10\n";
  write_file_atomic(path, s);
}

// Gmsh 4.1 with one volume entity holding all nodes and elements, tags 1-based.
void write_msh41(const Mesh& m, const std::string& path) {
  std::string s;
  const int npe = m.npe(), ntet = m.ntet(), n = m.nnode();
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  for (int c = 0; c < 3 && n > 0; ++c) {
    lo[c] = hi[c] = m.X[c];
    for (int i = 1; i < n; ++i) lo[c] = std::min(lo[c], m.X[3 * i + c]), hi[c] = std::max(hi[c], m.X[3 * i + c]);
  }
  s += "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";
  s += "$Entities\n0 0 0 1\n";
  appendf(s, "1 %.17g %.17g %.17g %.17g %.17g %.17g 0 0\n", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
  s += "$EndEntities\n";
  appendf(s, "$Nodes\n1 %d 1 %d\n3 1 0 %d\n", n, n, n);
  for (int i = 1; i <= n; ++i) appendf(s, "%d\n", i);
  points_text(s, m.X, "\n");
  s += "$EndNodes\n";
  appendf(s, "$Elements\n1 %d 1 %d\n3 1 %d %d\n", ntet, ntet, npe == 10 ? 11 : 4, ntet);
  for (int e = 0; e < ntet; ++e) {
    appendf(s, "%d", e + 1);
    for (int a = 0; a < npe; ++a) appendf(s, " %d", 1 + m.tet[e * npe + (npe == 10 ? kToGmshTet10[a] : a)]);
    s += '\n';
  }
  s += "$EndElements\n";
  write_file_atomic(path, s);
}

void check_field(const VtuField& f, size_t n, const char* where, const std::string& path) {
  if (f.ncomp < 1 || f.values.size() != n * static_cast<size_t>(f.ncomp))
    throw Error(path + ": " + where + " field '" + f.name + "' has " + std::to_string(f.values.size()) + " values, expected " +
                std::to_string(n) + " x " + std::to_string(f.ncomp));
}

void fields_text(std::string& s, const std::vector<VtuField>& fields, const char* tag) {
  if (fields.empty()) return;
  appendf(s, "      <%s>\n", tag);
  for (const auto& f : fields) {
    s += "        <DataArray type=\"Float64\" Name=\"" + xml_escape(f.name) + "\"";
    appendf(s, " NumberOfComponents=\"%d\" format=\"ascii\">\n", f.ncomp);
    for (size_t i = 0; i < f.values.size(); ++i)
      appendf(s, "%.9g%c", f.values[i], (i + 1) % f.ncomp == 0 ? '\n' : ' ');
    s += "        </DataArray>\n";
  }
  appendf(s, "      </%s>\n", tag);
}

}  // namespace

Mesh read_mesh(const std::string& path) {
  const std::string ext = extension(path);
  Mesh m;
  if (ext == ".msh") m = meshio::read_gmsh(path);
  else if (ext == ".vtk") m = meshio::read_vtk_legacy(path);
  else if (ext == ".vtu") m = meshio::read_vtu(path);
  else if (ext == ".node" || ext == ".ele") m = meshio::read_tetgen(path);
  else if (ext == ".inp") m = meshio::read_abaqus(path);
  else throw Error(path + ": unknown mesh file extension '" + ext + "'; allowed: " + kReadable);
  check_shapes(m, path);
  return m;
}

void write_mesh(const Mesh& mesh, const std::string& path) {
  const std::string ext = extension(path);
  if (ext != ".vtu" && ext != ".vtk" && ext != ".msh")
    throw Error(path + ": cannot write meshes with extension '" + ext + "'; allowed: " + kWritable);
  check_shapes(mesh, path);
  if (ext == ".vtu") write_vtu(grid_of(mesh), path);
  if (ext == ".vtk") write_vtk_legacy(mesh, path);
  if (ext == ".msh") write_msh41(mesh, path);
}

namespace {

// The appended blocks of the binary .vtu: each array one zlib block with its
// UInt64 header [1, size, size, compressed size] (0 blocks when empty).
struct Appended {
  std::string blob;
  size_t add(const void* data, size_t n, const std::string& path) {
    const size_t at = blob.size();
    auto u64 = [&](uint64_t v) { blob.append(reinterpret_cast<const char*>(&v), 8); };
    if (n == 0) {
      u64(0), u64(32768), u64(0);
      return at;
    }
    uLongf cn = compressBound(static_cast<uLong>(n));
    std::string c(cn, '\0');
    if (compress2(reinterpret_cast<Bytef*>(c.data()), &cn, static_cast<const Bytef*>(data), static_cast<uLong>(n), Z_BEST_SPEED) != Z_OK)
      throw Error(path + ": zlib could not compress a DataArray of " + std::to_string(n) + " bytes");
    u64(1), u64(n), u64(n), u64(cn);
    blob.append(c.data(), cn);
    return at;
  }
};

void write_vtu_binary(const VtuGrid& g, const std::string& path) {
  const size_t npoint = g.points.size() / 3, ncell = g.types.size();
  Appended app;
  std::string s;
  s += "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
       "header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\">\n";
  appendf(s, "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\">\n", npoint, ncell);
  auto arr = [&](const char* type, const std::string& name, int ncomp, const void* data, size_t bytes) {
    const size_t off = app.add(data, bytes, path);
    s += std::string("        <DataArray type=\"") + type + "\"" + (name.empty() ? "" : " Name=\"" + xml_escape(name) + "\"");
    appendf(s, " NumberOfComponents=\"%d\" format=\"appended\" offset=\"%zu\"/>\n", ncomp, off);
  };
  for (const auto* fields : {&g.point_data, &g.cell_data}) {
    if (fields->empty()) continue;
    const char* tag = fields == &g.point_data ? "PointData" : "CellData";
    appendf(s, "      <%s>\n", tag);
    for (const auto& f : *fields) arr("Float64", f.name, f.ncomp, f.values.data(), f.values.size() * sizeof(double));
    appendf(s, "      </%s>\n", tag);
  }
  s += "      <Points>\n";
  arr("Float64", "Points", 3, g.points.data(), g.points.size() * sizeof(double));
  s += "      </Points>\n      <Cells>\n";
  arr("Int32", "connectivity", 1, g.connectivity.data(), g.connectivity.size() * sizeof(int));
  arr("Int32", "offsets", 1, g.offsets.data(), g.offsets.size() * sizeof(int));
  std::vector<unsigned char> types(g.types.begin(), g.types.end());
  arr("UInt8", "types", 1, types.data(), types.size());
  s += "      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   _";
  s += app.blob;
  s += "\n  </AppendedData>\n</VTKFile>\n";
  write_file_atomic(path, s);
}

}  // namespace

void write_vtu(const VtuGrid& g, const std::string& path, VtuEncoding encoding) {
  const size_t npoint = g.points.size() / 3, ncell = g.types.size();
  if (g.points.size() % 3) throw Error(path + ": points size " + std::to_string(g.points.size()) + " is not a multiple of 3");
  if (g.offsets.size() != ncell)
    throw Error(path + ": " + std::to_string(g.offsets.size()) + " offsets for " + std::to_string(ncell) + " cell types");
  int prev = 0;
  for (size_t c = 0; c < ncell; ++c) {
    const int len = g.offsets[c] - prev;
    if (len <= 0 || g.offsets[c] > static_cast<int>(g.connectivity.size()))
      throw Error(path + ": cell " + std::to_string(c) + " has offset " + std::to_string(g.offsets[c]) +
                  "; offsets must increase and end at the connectivity size " + std::to_string(g.connectivity.size()));
    if ((g.types[c] == 10 && len != 4) || (g.types[c] == 24 && len != 10))
      throw Error(path + ": cell " + std::to_string(c) + " of VTK type " + std::to_string(g.types[c]) + " has " +
                  std::to_string(len) + " nodes");
    prev = g.offsets[c];
  }
  if (static_cast<size_t>(prev) != g.connectivity.size())
    throw Error(path + ": last offset " + std::to_string(prev) + " != connectivity size " + std::to_string(g.connectivity.size()));
  for (size_t i = 0; i < g.connectivity.size(); ++i)
    if (g.connectivity[i] < 0 || static_cast<size_t>(g.connectivity[i]) >= npoint)
      throw Error(path + ": connectivity entry " + std::to_string(i) + " is " + std::to_string(g.connectivity[i]) +
                  ", but only " + std::to_string(npoint) + " points are defined");
  for (const auto& f : g.point_data) check_field(f, npoint, "point", path);
  for (const auto& f : g.cell_data) check_field(f, ncell, "cell", path);
  if (encoding == VtuEncoding::Binary) {
    write_vtu_binary(g, path);
    return;
  }

  std::string s;
  s.reserve(64 * (npoint + g.connectivity.size()));
  s += "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n";
  appendf(s, "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\">\n", npoint, ncell);
  fields_text(s, g.point_data, "PointData");
  fields_text(s, g.cell_data, "CellData");
  s += "      <Points>\n        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  points_text(s, g.points, "\n");
  s += "        </DataArray>\n      </Points>\n      <Cells>\n";
  s += "        <DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
  prev = 0;
  for (size_t c = 0; c < ncell; ++c) {
    for (int i = prev; i < g.offsets[c]; ++i) appendf(s, i + 1 < g.offsets[c] ? "%d " : "%d\n", g.connectivity[i]);
    prev = g.offsets[c];
  }
  s += "        </DataArray>\n        <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
  for (size_t c = 0; c < ncell; ++c) appendf(s, "%d\n", g.offsets[c]);
  s += "        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (size_t c = 0; c < ncell; ++c) appendf(s, "%d\n", g.types[c]);
  s += "        </DataArray>\n      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  write_file_atomic(path, s);
}

PvdSeries::PvdSeries(std::string pvd_path, VtuEncoding encoding) : pvd_path_(std::move(pvd_path)), encoding_(encoding) {
  fs::path dir = fs::path(pvd_path_).parent_path();
  std::error_code ec;
  if (!dir.empty()) fs::create_directories(dir, ec);
  if (ec) throw Error(pvd_path_ + ": cannot create folder " + dir.string() + ": " + ec.message());
}

void PvdSeries::add(double time, const VtuGrid& grid) {
  if (!std::isfinite(time)) throw Error(pvd_path_ + ": time of step " + std::to_string(files_.size()) + " is not finite");
  const fs::path pvd(pvd_path_);
  std::string name = pvd.stem().string();
  appendf(name, "_%06zu.vtu", files_.size());
  write_vtu(grid, (pvd.parent_path() / name).string(), encoding_);
  files_.push_back(name);
  times_.push_back(time);

  std::string s = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n";
  for (size_t i = 0; i < files_.size(); ++i) {
    appendf(s, "    <DataSet timestep=\"%.17g\" group=\"\" part=\"0\" file=\"", times_[i]);
    s += xml_escape(files_[i]) + "\"/>\n";
  }
  s += "  </Collection>\n</VTKFile>\n";
  write_file_atomic(pvd_path_, s);
}

}  // namespace incise
