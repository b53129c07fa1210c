#pragma once
// Reading and writing tetrahedral meshes and result files.
//
// Readers (chosen by extension): Gmsh .msh (2.2 and 4.1 ASCII), VTK legacy
// .vtk and XML .vtu (ASCII), TetGen .node/.ele (give either file), Abaqus /
// CalculiX .inp. tet4 and tet10 where the format has them; other element
// types are skipped (surface triangles, lines) unless a file has no tets.
// Errors: incise::Error "FILE:LINE: what was wrong, what is allowed".
#include <string>
#include <vector>

#include "engine/mesh/mesh.h"

namespace incise {

Mesh read_mesh(const std::string& path);
// Writes a mesh (no fields) by extension: .vtu, .vtk, .msh (Gmsh 4.1 ASCII).
// Written to a temporary file and renamed, so no half-written file remains.
void write_mesh(const Mesh& mesh, const std::string& path);

// Generic unstructured grid with fields, for ParaView output. Cells are tet4
// (VTK type 10) or tet10 (VTK type 24) in the ordering of engine/mesh/mesh.h.
struct VtuField {
  std::string name;
  int ncomp = 1;
  std::vector<double> values;  // (n, ncomp)
};
struct VtuGrid {
  std::vector<double> points;     // (npoint, 3)
  std::vector<int> connectivity;  // concatenated cell node ids
  std::vector<int> offsets;       // (ncell) end offset of each cell in connectivity
  std::vector<int> types;         // (ncell) VTK cell type: 10 or 24
  std::vector<VtuField> point_data;
  std::vector<VtuField> cell_data;
};
// Binary: every DataArray appended raw after <AppendedData>, zlib-compressed
// (vtkZLibDataCompressor, UInt64 headers, fastest level: a frame is written
// while the next one waits), what ParaView writes; Ascii: readable text.
enum class VtuEncoding { Binary, Ascii };
void write_vtu(const VtuGrid& grid, const std::string& path,
               VtuEncoding encoding = VtuEncoding::Binary);  // atomic (temp + rename)

// A ParaView .pvd collection: add() writes one .vtu per step into the
// folder of the .pvd and rewrites the .pvd so it is valid after every step.
class PvdSeries {
 public:
  explicit PvdSeries(std::string pvd_path, VtuEncoding encoding = VtuEncoding::Binary);
  void add(double time, const VtuGrid& grid);
  const std::vector<std::string>& files() const { return files_; }

 private:
  std::string pvd_path_;
  VtuEncoding encoding_;
  std::vector<double> times_;
  std::vector<std::string> files_;  // relative to the .pvd folder
};

}  // namespace incise
