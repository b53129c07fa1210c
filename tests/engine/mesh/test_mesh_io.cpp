// Mesh readers and writers: samples in every format, round trips, errors.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>
#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <cstdlib>

#include "engine/util/error.h"
#include "engine/mesh/mesh_io.h"
#include "engine/mesh/mesh_tools.h"
#include "tests/engine/error_of.h"

namespace incise {
namespace {

namespace fs = std::filesystem;

std::string asset(const std::string& name) { return std::string(INCISE_SOURCE_DIR) + "/assets/meshes/" + name; }

// A fresh folder per test, removed afterwards.
class MeshIo : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("incise_mesh_io_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path(name)) << text;
    return path(name);
  }
  fs::path dir_;
};

using test::error_of;

std::string slurp(const std::string& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Coordinates of every element's nodes in element order: (ntet, npe, 3).
// Independent of node numbering, so it compares meshes across formats.
std::vector<double> element_coords(const Mesh& m) {
  std::vector<double> out;
  for (int n : m.tet) out.insert(out.end(), m.X.begin() + 3 * n, m.X.begin() + 3 * n + 3);
  return out;
}

// Every mid-edge node sits at the average of its two corners (straight
// meshes); a reader with a wrong tet10 permutation fails this.
void expect_midpoints(const Mesh& m) {
  ASSERT_EQ(m.order, 2);
  for (int e = 0; e < m.ntet(); ++e)
    for (int k = 0; k < 6; ++k)
      for (int c = 0; c < 3; ++c) {
        const int* t = &m.tet[10 * e];
        double avg = 0.5 * (m.X[3 * t[kTet10Edge[k][0]] + c] + m.X[3 * t[kTet10Edge[k][1]] + c]);
        EXPECT_DOUBLE_EQ(m.X[3 * t[4 + k] + c], avg) << m.source << " element " << e << " node " << 4 + k;
      }
}

const std::vector<std::string> kTet4Samples = {
    "box_tet4.vtk", "box_tet4_v51.vtk", "box_tet4.vtu",     "box_tet4_v22.msh", "box_tet4_v41.msh",
    "box_tet4_sparse_v22.msh", "box_tet4.node", "box_tet4.ele", "box_tet4.inp"};
const std::vector<std::string> kTet10Samples = {"box_tet10.vtk",     "box_tet10_classic.vtk", "box_tet10.vtu",
                                                "box_tet10_v22.msh", "box_tet10_v41.msh",     "box_tet10.ele",
                                                "box_tet10.inp",     "box_tet10_zlib.vtu",    "box_tet10_appended.vtu",
                                                "box_tet10_v41_bin.msh", "box_tet10_v22_bin.msh", "box_tet10_bin.vtk"};

TEST_F(MeshIo, EveryTet4SampleIsTheSameBox) {
  const Mesh ref = read_mesh(asset("box_tet4.vtk"));
  const auto ref_coords = element_coords(ref);
  for (const auto& name : kTet4Samples) {
    SCOPED_TRACE(name);
    Mesh m = read_mesh(asset(name));
    EXPECT_EQ(m.order, 1);
    EXPECT_EQ(m.nnode(), 8);  // the sparse .msh has an unused 9th node, dropped
    EXPECT_EQ(m.ntet(), 6);
    EXPECT_NO_THROW(check_mesh(m));
    EXPECT_NEAR(mesh_quality(m).total_volume, 1.0, 1e-14);
    EXPECT_EQ(element_coords(m), ref_coords);
  }
}

TEST_F(MeshIo, EveryTet10SampleIsTheSameBoxWithMidpointsInOurOrder) {
  const Mesh ref = read_mesh(asset("box_tet10.vtk"));
  const auto ref_coords = element_coords(ref);
  for (const auto& name : kTet10Samples) {
    SCOPED_TRACE(name);
    Mesh m = read_mesh(asset(name));
    EXPECT_EQ(m.order, 2);
    EXPECT_EQ(m.nnode(), 27);
    EXPECT_EQ(m.ntet(), 6);
    EXPECT_NO_THROW(check_mesh(m));  // includes positive Jacobians at all 10 nodes
    expect_midpoints(m);
    EXPECT_NEAR(mesh_quality(m).total_volume, 1.0, 1e-14);
    EXPECT_EQ(element_coords(m), ref_coords);
  }
}

TEST_F(MeshIo, SparseGmshTagsMapToRowsInFileOrder) {
  Mesh m = read_mesh(asset("box_tet4_sparse_v22.msh"));
  // Nodes are listed in reverse: tag 152 (corner (2,1,0.5)) comes first.
  EXPECT_EQ(m.X[0], 2.0);
  EXPECT_EQ(m.X[1], 1.0);
  EXPECT_EQ(m.X[2], 0.5);
  // First tet is "5 8 32 152": the rows of those tags are 7, 6, 4, 0.
  EXPECT_EQ(std::vector<int>(m.tet.begin(), m.tet.begin() + 4), (std::vector<int>{7, 6, 4, 0}));
  EXPECT_EQ(m.source, asset("box_tet4_sparse_v22.msh"));
}

TEST_F(MeshIo, RoundTripIsExactInEveryWritableFormat) {
  for (int order : {1, 2}) {
    // Lengths that are not binary fractions, so printing precision matters.
    Mesh m = make_beam(0.7, 0.3, 1.1, 3, 2, 5, order);
    for (const char* ext : {".vtu", ".vtk", ".msh"}) {
      SCOPED_TRACE(std::string(ext) + " order " + std::to_string(order));
      const std::string p = path(std::string("beam") + ext);
      write_mesh(m, p);
      Mesh r = read_mesh(p);
      EXPECT_EQ(r.order, m.order);
      EXPECT_EQ(r.tet, m.tet);
      ASSERT_EQ(r.X.size(), m.X.size());
      for (size_t i = 0; i < m.X.size(); ++i) EXPECT_LE(std::abs(r.X[i] - m.X[i]), 1e-15 * std::abs(m.X[i]));
    }
  }
}

TEST_F(MeshIo, WritesLeaveNoTemporaryFiles) {
  write_mesh(make_beam(1, 1, 1, 1, 1, 1, 1), path("a.vtu"));
  write_mesh(make_beam(1, 1, 1, 1, 1, 1, 1), path("a.vtu"));  // overwrite
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename().string());
  EXPECT_EQ(names, std::vector<std::string>{"a.vtu"});
}

TEST_F(MeshIo, VtuFieldsAndPvdSeries) {
  Mesh m = make_beam(1, 1, 1, 1, 1, 1, 2);
  VtuGrid g;
  g.points = m.X;
  g.connectivity = m.tet;
  for (int e = 0; e < m.ntet(); ++e) g.offsets.push_back(10 * (e + 1)), g.types.push_back(24);
  g.point_data.push_back({"displacement", 3, std::vector<double>(m.X.size(), 0.25)});
  g.cell_data.push_back({"stress<vm>", 1, std::vector<double>(m.ntet(), 1.5)});

  PvdSeries series(path("out/run.pvd"));  // creates the folder
  for (int step = 0; step < 3; ++step) series.add(step / 30.0, g);
  ASSERT_EQ(series.files().size(), 3u);
  EXPECT_EQ(series.files()[2], "run_000002.vtu");
  const std::string pvd = slurp(path("out/run.pvd"));
  EXPECT_NE(pvd.find("file=\"run_000000.vtu\""), std::string::npos);
  EXPECT_NE(pvd.find("file=\"run_000002.vtu\""), std::string::npos);
  EXPECT_NE(pvd.find("timestep=\"0.066666666666666666\""), std::string::npos);
  const std::string vtu = slurp(path("out/run_000001.vtu"));
  EXPECT_NE(vtu.find("Name=\"displacement\" NumberOfComponents=\"3\""), std::string::npos);
  EXPECT_NE(vtu.find("Name=\"stress&lt;vm&gt;\""), std::string::npos);
  Mesh r = read_mesh(path("out/run_000001.vtu"));  // fields are skipped by the reader
  EXPECT_EQ(r.tet, m.tet);
  EXPECT_EQ(r.X, m.X);
}

TEST_F(MeshIo, WriteVtuRejectsInconsistentGrids) {
  VtuGrid g;
  g.points = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  g.connectivity = {0, 1, 2, 4};
  g.offsets = {4};
  g.types = {10};
  EXPECT_NE(error_of([&] { write_vtu(g, path("g.vtu")); }).find("only 4 points"), std::string::npos);
  g.connectivity = {0, 1, 2, 3};
  g.point_data.push_back({"u", 3, {1, 2, 3}});
  EXPECT_NE(error_of([&] { write_vtu(g, path("g.vtu")); }).find("field 'u'"), std::string::npos);
  EXPECT_FALSE(fs::exists(path("g.vtu")));
}

TEST_F(MeshIo, UnknownExtensionListsTheAllowedOnes) {
  std::string e = error_of([] { read_mesh("liver.stl"); });
  EXPECT_NE(e.find("liver.stl"), std::string::npos) << e;
  for (const char* ext : {".msh", ".vtk", ".vtu", ".node", ".ele", ".inp"}) EXPECT_NE(e.find(ext), std::string::npos) << e;
  e = error_of([&] { write_mesh(make_beam(1, 1, 1, 1, 1, 1, 1), path("x.inp")); });
  EXPECT_NE(e.find(".vtu, .vtk, .msh"), std::string::npos) << e;
}

TEST_F(MeshIo, MissingFileIsNamed) {
  std::string e = error_of([&] { read_mesh(path("nope.msh")); });
  EXPECT_NE(e.find("nope.msh: cannot open"), std::string::npos) << e;
}

// Binary Gmsh files that do not hold what they claim: a 4-byte size_t, a
// node count beyond the file, a truncated node block.
TEST_F(MeshIo, BinaryGmshErrorsNameWhatDoesNotFit) {
  const std::string p4 = write("b4.msh", "$MeshFormat\n4.1 1 4\n\x01\0\0\0\n$EndMeshFormat\n");
  EXPECT_NE(error_of([&] { read_mesh(p4); }).find("b4.msh:2: binary data-size '4' is not supported"), std::string::npos);
  std::string big = std::string("$MeshFormat\n2.2 1 8\n") + std::string("\x01\0\0\0", 4) + "\n$EndMeshFormat\n$Nodes\n1000000\n";
  big += std::string(28, '\0') + "\n$EndNodes\n";
  const std::string e = error_of([&] { read_mesh(write("big.msh", big)); });
  EXPECT_NE(e.find("big.msh:6: the number of nodes is 1000000, more than the"), std::string::npos) << e;
  std::string cut = std::string("$MeshFormat\n4.1 1 8\n") + std::string("\x01\0\0\0", 4) + "\n$EndMeshFormat\n$Nodes\n";
  const uint64_t head[4] = {1, 2, 1, 2};
  cut.append(reinterpret_cast<const char*>(head), sizeof head);
  const int32_t block[3] = {3, 1, 0};
  const uint64_t nin = 2;
  cut.append(reinterpret_cast<const char*>(block), sizeof block);
  cut.append(reinterpret_cast<const char*>(&nin), 8);
  cut.append(std::string(20, '\0'));  // two tags need 16 bytes, their coordinates 48: cut short
  const std::string e2 = error_of([&] { read_mesh(write("cut.msh", cut)); });
  EXPECT_NE(e2.find("cut.msh:5: numNodesInBlock is 2, more than the"), std::string::npos) << e2;
}

// Binary Gmsh coordinates are raw doubles: a NaN or an infinity there is
// refused by name, as the ASCII readers refuse "nan" (the fuzzer found the gap).
TEST_F(MeshIo, BinaryGmshNonFiniteCoordinatesAreRefused) {
  for (const double bad : {std::nan(""), HUGE_VAL}) {
    std::string t = std::string("$MeshFormat\n2.2 1 8\n") + std::string("\x01\0\0\0", 4) + "\n$EndMeshFormat\n$Nodes\n2\n";
    for (int32_t tag = 1; tag <= 2; ++tag) {
      const double x[3] = {0.0, tag == 2 ? bad : 1.0, 0.0};
      t.append(reinterpret_cast<const char*>(&tag), 4);
      t.append(reinterpret_cast<const char*>(x), sizeof x);
    }
    t += "\n$EndNodes\n";
    const std::string e = error_of([&] { read_mesh(write("nan.msh", t)); });
    EXPECT_NE(e.find("nan.msh:6: binary node 2 has a non-finite coordinate"), std::string::npos) << e;
  }
}

// A binary legacy .vtk whose POINTS claim more than the file holds.
TEST_F(MeshIo, BinaryLegacyVtkCountsAreCheckedAgainstTheFile) {
  std::string t = "# vtk DataFile Version 4.2\nx\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 1000 double\n";
  t += std::string(24, '\0') + "\n";
  const std::string e = error_of([&] { read_mesh(write("p.vtk", t)); });
  EXPECT_NE(e.find("p.vtk:5: POINTS: 3000 values of 8 bytes, more than the 25 bytes left"), std::string::npos) << e;
}

TEST_F(MeshIo, GmshUndefinedNodeNamesFileLineAndElement) {
  std::string p = write("bad.msh",
                        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"
                        "$EndNodes\n$Elements\n2\n1 4 0 1 2 3 4\n12 4 0 1 2 3 99\n$EndElements\n");
  std::string e = error_of([&] { read_mesh(p); });
  EXPECT_NE(e.find("bad.msh:14: element 12 references node 99"), std::string::npos) << e;
  EXPECT_NE(e.find("4 nodes"), std::string::npos) << e;
}

TEST_F(MeshIo, GmshWithoutTetrahedraSaysWhatWasLookedFor) {
  std::string p = write("surf.msh",
                        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 3 1 3\n2 1 0 3\n1\n2\n3\n0 0 0\n1 0 0\n0 1 0\n"
                        "$EndNodes\n$Elements\n1 1 1 1\n2 1 2 1\n1 1 2 3\n$EndElements\n");
  std::string e = error_of([&] { read_mesh(p); });
  EXPECT_NE(e.find("surf.msh: no tetrahedra found"), std::string::npos) << e;
  EXPECT_NE(e.find("types 4 (tet4) and 11 (tet10)"), std::string::npos) << e;
}

TEST_F(MeshIo, MalformedNumbersNameFileAndLine) {
  std::string node = write("t.node", "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 x1 0\n4 0 0 1\n");
  write("t.ele", "1 4 0\n1 1 2 3 4\n");
  std::string e = error_of([&] { read_mesh(node); });
  EXPECT_NE(e.find("t.node:4: expected a point coordinate (a number), got 'x1'"), std::string::npos) << e;

  std::string inp = write("t.inp", "*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n3, 0, 1, 0\n4, 0, 0, 1\n*ELEMENT, TYPE=C3D10\n1, 1, 2, 3, 4,\n*END STEP\n");
  e = error_of([&] { read_mesh(inp); });
  EXPECT_NE(e.find("t.inp:7: element 1 lists 4 nodes, but its type needs 10"), std::string::npos) << e;
}

TEST_F(MeshIo, NonFiniteCoordinatesAreRejected) {
  // A count whose 3 values per point would overflow (found by fuzz_mesh).
  const std::string big = error_of([&] {
    read_mesh(write("big.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\n"
                               "POINTS 8647214748364882058 double\n0 0 0\n"));
  });
  EXPECT_NE(big.find("big.vtk:5: the number of points must be at most 3074457345618258602, got 8647214748364882058"),
            std::string::npos)
      << big;
  std::string p = write("nan.vtk",
                        "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0\n1 0 0\n"
                        "0 nan 0\n0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n");
  std::string e = error_of([&] { read_mesh(p); });
  EXPECT_NE(e.find("nan.vtk:8: a point coordinate is 'nan'"), std::string::npos) << e;
}

// A one-tet .vtu with appended raw data, as VTK writes it: each array a
// block (header: byte count, or for zlib [nblocks, block size, last size,
// compressed size]) at its offset after the '_'.
std::string base64(const std::string& bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t w = 0;
    const size_t n = std::min<size_t>(3, bytes.size() - i);
    for (size_t j = 0; j < 3; ++j) w = (w << 8) | (j < n ? static_cast<unsigned char>(bytes[i + j]) : 0);
    for (size_t j = 0; j < 4; ++j) out += j <= n ? k[(w >> (18 - 6 * j)) & 63] : '=';
  }
  return out;
}

std::string appended_vtu(bool zlib, bool uint64, std::string* truncated = nullptr, bool b64 = false) {
  const double pts[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  const int64_t conn[4] = {0, 1, 2, 3};
  const int32_t offs[1] = {4};
  const uint8_t types[1] = {10};
  std::string blob;
  std::vector<size_t> at;
  auto header = [&](uint64_t v) {
    if (uint64) blob.append(reinterpret_cast<const char*>(&v), 8);
    else {
      const uint32_t w = static_cast<uint32_t>(v);
      blob.append(reinterpret_cast<const char*>(&w), 4);
    }
  };
  std::string text;  // base64: each block encoded on its own, header and data separately
  auto add = [&](const void* data, size_t n) {
    if (b64) {
      at.push_back(text.size());
      blob.clear();
    } else {
      at.push_back(blob.size());
    }
    if (!zlib) {
      header(n);
      blob.append(static_cast<const char*>(data), n);
      return;
    }
    std::vector<unsigned char> c(compressBound(n));
    uLongf cn = c.size();
    compress2(c.data(), &cn, static_cast<const Bytef*>(data), n, 6);
    header(1), header(n), header(n), header(cn);
    blob.append(reinterpret_cast<const char*>(c.data()), cn);
  };
  auto flush = [&](size_t header_bytes) {  // base64 text of the block just added
    if (b64) text += base64(blob.substr(0, header_bytes)) + base64(blob.substr(header_bytes));
  };
  const size_t hb = (uint64 ? 8 : 4) * (zlib ? 4 : 1);
  add(pts, sizeof pts), flush(hb), add(conn, sizeof conn), flush(hb), add(offs, sizeof offs), flush(hb);
  add(types, sizeof types), flush(hb);
  if (b64) blob = text;
  auto arr = [&](const char* type, const char* name, int k, int ncomp = 1) {
    return std::string("<DataArray type=\"") + type + "\" Name=\"" + name + "\" NumberOfComponents=\"" +
           std::to_string(ncomp) + "\" format=\"appended\" offset=\"" + std::to_string(at[static_cast<size_t>(k)]) + "\"/>\n";
  };
  std::string head = std::string("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"") +
                     (uint64 ? "UInt64" : "UInt32") + "\"" + (zlib ? " compressor=\"vtkZLibDataCompressor\"" : "") +
                     ">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n<Points>\n" +
                     arr("Float64", "Points", 0, 3) + "</Points>\n<Cells>\n" + arr("Int64", "connectivity", 1) +
                     arr("Int32", "offsets", 2) + arr("UInt8", "types", 3) +
                     "</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding=\"" + (b64 ? "base64" : "raw") + "\">\n_";
  if (truncated) *truncated = head + blob.substr(0, at[1] + 6) + "\n</AppendedData>\n</VTKFile>\n";
  return head + blob + "\n</AppendedData>\n</VTKFile>\n";
}

// The frame writer's two encodings give the same grid back: binary (the
// default, appended zlib) and ascii, fields included in the file.
TEST_F(MeshIo, BinaryAndAsciiVtuWritesReadBackTheSameMesh) {
  const Mesh ref = read_mesh(asset("box_tet10.vtu"));
  VtuGrid g;
  g.points = ref.X;
  g.connectivity = ref.tet;
  for (int e = 0; e < ref.ntet(); ++e) g.offsets.push_back(10 * (e + 1)), g.types.push_back(24);
  g.point_data.push_back({"displacement", 3, std::vector<double>(ref.X.size(), 0.25)});
  g.cell_data.push_back({"von_mises", 1, std::vector<double>(static_cast<size_t>(ref.ntet()), 7.0)});
  write_vtu(g, path("b.vtu"));
  write_vtu(g, path("a.vtu"), VtuEncoding::Ascii);
  EXPECT_NE(slurp(path("b.vtu")).find("compressor=\"vtkZLibDataCompressor\""), std::string::npos);
  EXPECT_NE(slurp(path("a.vtu")).find("format=\"ascii\""), std::string::npos);
  for (const char* f : {"a.vtu", "b.vtu"}) {
    const Mesh m = read_mesh(path(f));
    EXPECT_EQ(m.X, ref.X) << f;
    EXPECT_EQ(m.tet, ref.tet) << f;
  }
}

TEST_F(MeshIo, AppendedRawAndZlibVtuReadAsTheAsciiOne) {
  for (bool b64 : {false, true})
  for (bool zlib : {false, true})
    for (bool u64 : {false, true}) {
      const std::string p = write("a.vtu", appended_vtu(zlib, u64, nullptr, b64));
      const Mesh m = read_mesh(p);
      EXPECT_EQ(m.order, 1);
      EXPECT_EQ(m.tet, (std::vector<int>{0, 1, 2, 3})) << "zlib " << zlib << " uint64 " << u64;
      EXPECT_EQ(m.X, (std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}));
    }
}

TEST_F(MeshIo, TruncatedBinaryVtuNamesTheArrayAndTheSize) {
  std::string cut;
  appended_vtu(false, false, &cut);
  const std::string e = error_of([&] { read_mesh(write("t.vtu", cut)); });
  EXPECT_NE(e.find("t.vtu:9: DataArray 'connectivity': the block needs 32 bytes"), std::string::npos) << e;
  const std::string bad = write("b.vtu", "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\">\n<UnstructuredGrid>\n"
                                         "<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n<Points>\n"
                                         "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">AAA*</DataArray>\n"
                                         "</Points>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
  const std::string e2 = error_of([&] { read_mesh(bad); });
  EXPECT_NE(e2.find("b.vtu:6: DataArray '': the base64 data holds a character outside its alphabet"), std::string::npos) << e2;
}

// Round trips against meshio (Debian python3-meshio; skipped without it):
// every .vtu mode meshio writes (ascii, binary, binary + zlib), its legacy
// .vtk (ASCII, binary 5.1 and 4.2), and Gmsh 2.2 (ASCII and binary) and 4.1
// binary (meshio's default) and ASCII, Abaqus .inp and TetGen .node/.ele
// read back with the same elements; what
// incise writes (.vtu, .vtk, .msh) reads in meshio with the same points.
TEST_F(MeshIo, MeshioRoundTrips) {
  if (std::system("/usr/bin/python3 -c 'import meshio' > /dev/null 2>&1") != 0) GTEST_SKIP() << "python3-meshio not installed";
  for (const char* sample : {"box_tet4.vtu", "box_tet10.vtu"}) {
    const Mesh ref = read_mesh(asset(sample));
    const std::string py = write("rt.py",
                                 "import meshio, sys\n"
                                 "m = meshio.read(sys.argv[1])\n"
                                 "d = sys.argv[2]\n"
                                 "meshio.vtu.write(d + '/a.vtu', m, binary=False)\n"
                                 "meshio.vtu.write(d + '/b.vtu', m, binary=True, compression=None)\n"
                                 "meshio.vtu.write(d + '/z.vtu', m, binary=True, compression='zlib')\n"
                                 "meshio.vtk.write(d + '/l.vtk', m, binary=False)\n"
                                 "meshio.vtk.write(d + '/lb.vtk', m, binary=True)\n"
                                 "meshio.vtk.write(d + '/lb42.vtk', m, binary=True, fmt_version='4.2')\n"
                                 "meshio.gmsh.write(d + '/g.msh', m, fmt_version='2.2', binary=False)\n"
                                 "t = [c for c in m.cells if c.type.startswith('tetra')][0]\n"
                                 "m = meshio.Mesh(m.points, [(t.type, t.data)])  # gmsh 4.1 wants one cell block\n"
                                 "meshio.gmsh.write(d + '/g22b.msh', m, fmt_version='2.2', binary=True)\n"
                                 "meshio.gmsh.write(d + '/g41b.msh', m, fmt_version='4.1', binary=True)\n"
                                 "meshio.gmsh.write(d + '/g41a.msh', m, fmt_version='4.1', binary=False)\n"
                                 "meshio.abaqus.write(d + '/ab.inp', m)\n"
                                 "if t.type == 'tetra': meshio.tetgen.write(d + '/tg.node', m)  # tetgen: linear tets\n");
    ASSERT_EQ(std::system(("/usr/bin/python3 " + py + " " + asset(sample) + " " + dir_.string() + " 2>/dev/null").c_str()), 0);
    std::vector<std::string> files = {"a.vtu", "b.vtu", "z.vtu", "l.vtk", "lb.vtk", "lb42.vtk", "g.msh",
                                      "g22b.msh", "g41b.msh", "g41a.msh", "ab.inp"};
    if (ref.order == 1) files.push_back("tg.ele");
    for (const std::string& f : files) {
      const Mesh m = read_mesh(path(f));
      EXPECT_EQ(m.order, ref.order) << sample << " via meshio " << f;
      EXPECT_EQ(element_coords(m), element_coords(ref)) << sample << " via meshio " << f;
    }
    for (const char* f : {"w.vtu", "w.vtk", "w.msh"}) {
      write_mesh(ref, path(f));
      const std::string check = write("check.py",
                                      "import meshio, sys\n"
                                      "m = meshio.read(sys.argv[1])\n"
                                      "print(len(m.points), sum(len(c.data) for c in m.cells if c.type.startswith('tetra')))\n");
      const std::string out_file = path("check.out");
      ASSERT_EQ(std::system(("/usr/bin/python3 " + check + " " + path(f) + " > " + out_file + " 2>/dev/null").c_str()), 0) << f;
      std::string got = slurp(out_file);  // meshio may print a notice first: the last line
      while (!got.empty() && got.back() == '\n') got.pop_back();
      got = got.substr(got.rfind('\n') == std::string::npos ? 0 : got.rfind('\n') + 1);
      EXPECT_EQ(got, std::to_string(ref.nnode()) + " " + std::to_string(ref.ntet())) << sample << " written as " << f;
    }
  }
}

TEST_F(MeshIo, MixedTet4AndTet10IsAnError) {
  std::string p = write("mix.vtk",
                        "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 10 double\n"
                        "0 0 0 1 0 0 0 1 0 0 0 1 .5 0 0 .5 .5 0 0 .5 0 0 0 .5 .5 0 .5 0 .5 .5\n"
                        "CELLS 2 16\n4 0 1 2 3\n10 0 1 2 3 4 5 6 7 8 9\nCELL_TYPES 2\n10\n24\n");
  std::string e = error_of([&] { read_mesh(p); });
  EXPECT_NE(e.find("mix.vtk:9: cell 1 has 10 nodes but earlier tetrahedra have 4"), std::string::npos) << e;
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

#define EXPECT_ERR(expr, part)                                             \
  do {                                                                     \
    const std::string e_ = error_of([&] { expr; });                        \
    EXPECT_NE(e_.find(part), std::string::npos) << e_;                     \
  } while (0)

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

const std::string kTet22 =
    "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n"
    "$Elements\n1\n1 4 0 1 2 3 4\n$EndElements\n";

// Issue 24: a header count that contradicts the data is an error naming the
// header's line and value and what the data holds (it was ignored or dropped
// elements silently).
TEST_F(MeshIo, GmshHeaderCountsAreCheckedAgainstTheData) {
  EXPECT_ERR(read_mesh(write("few.msh", replaced(kTet22, "$Nodes\n4\n", "$Nodes\n5\n"))),
             "few.msh:10: $Nodes on line 5 says 5 nodes, but the data ends after 4 (at '$EndNodes')");
  EXPECT_ERR(read_mesh(write("more.msh", replaced(kTet22, "$Nodes\n4\n", "$Nodes\n3\n"))),
             "more.msh:9: $Nodes on line 5 says 3 nodes, but the data holds more (expected $EndNodes, got '4')");
  EXPECT_ERR(read_mesh(write("el.msh", replaced(kTet22, "$Elements\n1\n1 4 0 1 2 3 4\n", "$Elements\n1\n1 4 0 1 2 3 4\n2 4 0 1 2 4 3\n"))),
             "el.msh:14: $Elements on line 12 says 1 elements, but the data holds more");
  EXPECT_ERR(read_mesh(write("ovf.msh", replaced(kTet22, "$Nodes\n4\n", "$Nodes\n99999999999999999999\n"))),
             "ovf.msh:5: expected the number of nodes (an integer), got '99999999999999999999'");
  EXPECT_ERR(read_mesh(write("pm.msh", replaced(kTet22, "$Nodes\n4\n", "$Nodes\n+-4\n"))),
             "pm.msh:5: expected the number of nodes (an integer), got '+-4'");
  EXPECT_ERR(read_mesh(write("neg.msh", replaced(kTet22, "$Nodes\n4\n", "$Nodes\n-4\n"))),
             "neg.msh:5: the number of nodes must not be negative, got -4");
  // An absurd count is refused when the data runs out, with nothing reserved for it.
  EXPECT_ERR(read_mesh(write("huge.msh", replaced(kTet22, "$Nodes\n4\n", "$Nodes\n1000000000000000\n"))),
             "$Nodes on line 5 says 1000000000000000 nodes, but the data ends after 4");

  const std::string v41 = slurp(asset("box_tet4_v41.msh"));
  EXPECT_ERR(read_mesh(write("n41.msh", replaced(v41, "$Nodes\n2 8 10 59\n", "$Nodes\n2 9 10 59\n"))),
             "n41.msh:28: $Nodes on line 10 says numNodes = 9, but its 2 entity blocks hold 8");
  EXPECT_ERR(read_mesh(write("t41.msh", replaced(v41, "$Nodes\n2 8 10 59\n", "$Nodes\n2 8 10 50\n"))),
             "t41.msh:22: node tag 52 is outside [10, 50], the range $Nodes on line 10 gives");
  EXPECT_ERR(read_mesh(write("b41.msh", replaced(v41, "$Nodes\n2 8 10 59\n", "$Nodes\n3 8 10 59\n"))),
             "b41.msh:29: $Nodes (numEntityBlocks) on line 10 says 3 entity blocks, but the data ends after 2 (at '$EndNodes')");
  EXPECT_ERR(read_mesh(write("p41.msh", replaced(v41, "$Nodes\n2 8 10 59\n", "$Nodes\n2 7 10 59\n"))),
             "p41.msh:18: this block's 5 nodes bring the count past numNodes = 7 on line 10");
  // A block count one too high swallowed the next block's header as a skipped triangle.
  EXPECT_ERR(read_mesh(write("k41.msh", replaced(v41, "2 7 1 7\n2 1 2 1\n", "2 7 1 7\n2 1 2 2\n"))),
             "expected entity block 2's header 'entityDim entityTag elementType numElementsInBlock' (4 values), got 5; "
             "does the previous block's count match its data?");
  const size_t el = v41.find("$Elements\n");
  const std::string el_head = v41.substr(el + 10, v41.find('\n', el + 10) - el - 10);  // "nblocks n min max"
  std::istringstream hs(el_head);
  long long nb, ne, lo, hi;
  hs >> nb >> ne >> lo >> hi;
  EXPECT_ERR(read_mesh(write("e41.msh", replaced(v41, "$Elements\n" + el_head + "\n",
                                                "$Elements\n" + std::to_string(nb) + " " + std::to_string(ne + 1) + " " +
                                                    std::to_string(lo) + " " + std::to_string(hi) + "\n"))),
             "says numElements = " + std::to_string(ne + 1) + ", but its " + std::to_string(nb) + " entity blocks hold " +
                 std::to_string(ne));
  EXPECT_ERR(read_mesh(write("r41.msh", replaced(v41, "$Elements\n" + el_head + "\n",
                                                "$Elements\n" + std::to_string(nb) + " " + std::to_string(ne) + " " +
                                                    std::to_string(lo + 1) + " " + std::to_string(hi) + "\n"))),
             "element tag " + std::to_string(lo) + " is outside [" + std::to_string(lo + 1));

  // Binary 4.1: numNodes of the header (after "$Nodes\n" and numEntityBlocks).
  std::string b41 = slurp(asset("box_tet10_v41_bin.msh"));
  const size_t at = b41.find("$Nodes\n") + 7 + 8;
  uint64_t nn;
  std::memcpy(&nn, b41.data() + at, 8);
  const uint64_t more = nn + 1;
  std::memcpy(&b41[at], &more, 8);
  EXPECT_ERR(read_mesh(write("nb41.msh", b41)), "binary $Nodes: the header says numNodes = " + std::to_string(nn + 1) +
                                                    ", but its");
}

TEST_F(MeshIo, LegacyVtkHeaderCountsAreCheckedAgainstTheData) {
  const std::string t =
      "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
      "CELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n";
  ASSERT_EQ(read_mesh(write("ok.vtk", t)).ntet(), 1);
  EXPECT_ERR(read_mesh(write("p5.vtk", replaced(t, "POINTS 4", "POINTS 5"))),
             "p5.vtk:10: POINTS 5 on line 5 announces 15 values, but the data ends after 12 (expected a point coordinate, got 'CELLS')");
  EXPECT_ERR(read_mesh(write("p3.vtk", replaced(t, "POINTS 4", "POINTS 3"))),
             "p3.vtk:9: POINTS 3 on line 5 announces fewer values than follow ('0' is one too many)");
  EXPECT_ERR(read_mesh(write("c6.vtk", replaced(t, "CELLS 1 5", "CELLS 1 6"))),
             "c6.vtk:11: CELLS on line 10 says the cell list holds 6 integers, but its 1 cells hold 5");
  EXPECT_ERR(read_mesh(write("c2.vtk", replaced(t, "CELLS 1 5", "CELLS 2 10"))),
             "c2.vtk:12: CELLS 2 10 (its cells) on line 10 announces 2 values, but the data ends after 1 (expected the node count of a cell, got 'CELL_TYPES')");
  EXPECT_ERR(read_mesh(write("t2.vtk", replaced(t, "CELL_TYPES 1", "CELL_TYPES 2"))),
             "t2.vtk:13: CELL_TYPES 2 on line 12 announces 2 values, but the data ends after 1 (expected a cell type, got the end of the file)");
  EXPECT_ERR(read_mesh(write("huge.vtk", replaced(t, "POINTS 4", "POINTS 1000000000000000"))),
             "POINTS 1000000000000000 on line 5 announces 3000000000000000 values, but the data ends after 12");
  // VTK 5.1 layout: the last offset must be the connectivity's size.
  const std::string v51 = slurp(asset("box_tet4_v51.vtk"));
  const size_t c = v51.find("CELLS ");
  std::istringstream cs(v51.substr(c + 6, 40));
  long long a, b;
  cs >> a >> b;
  const std::string head = "CELLS " + std::to_string(a) + " " + std::to_string(b);
  EXPECT_ERR(read_mesh(write("v51.vtk", replaced(v51, head, "CELLS " + std::to_string(a) + " " + std::to_string(b + 1)))),
             "CONNECTIVITY");
  // Binary: CELLS size against the offsets (5.1 layout in this sample).
  EXPECT_ERR(read_mesh(write("bin.vtk", replaced(slurp(asset("box_tet10_bin.vtk")), "CELLS 7 60", "CELLS 7 61"))),
             "CELLS says 61 CONNECTIVITY entries, but the last offset is 60");
}

TEST_F(MeshIo, VtuPieceCountsAreCheckedAgainstTheArrays) {
  const std::string v = slurp(asset("box_tet4.vtu"));
  ASSERT_EQ(read_mesh(write("ok.vtu", v)).ntet(), 6);
  EXPECT_ERR(read_mesh(write("p.vtu", replaced(v, "NumberOfPoints=\"8\"", "NumberOfPoints=\"9\""))),
             "p.vtu:7: <Piece NumberOfPoints=\"9\"> but the Points DataArray holds 8 points");
  EXPECT_ERR(read_mesh(write("c.vtu", replaced(v, "NumberOfCells=\"7\"", "NumberOfCells=\"6\""))),
             "<Piece NumberOfCells=\"6\"> but the offsets DataArray holds 7 values");
  EXPECT_ERR(read_mesh(write("nc.vtu", replaced(v, "NumberOfComponents=\"3\"", "NumberOfComponents=\"4294967299\""))),
             "nc.vtu:7: DataArray 'Points' has NumberOfComponents=\"4294967299\"; allowed: 1 to 1000");
  EXPECT_ERR(read_mesh(write("n.vtu", replaced(v, "NumberOfCells=\"7\"", ""))),
             "n.vtu:4: <Piece> needs NumberOfCells=\"n\" (n >= 0), got ''");
}

TEST_F(MeshIo, TetgenHeaderColumnsAndCountsAreChecked) {
  const std::string node = "4 3 1 1\n1 0 0 0 0.5 0\n2 1 0 0 0.5 0\n3 0 1 0 0.5 0\n4 0 0 1 0.5 0\n";
  const std::string ele = "1 4 1\n1 1 2 3 4 7\n";
  write("a.ele", ele);
  ASSERT_EQ(read_mesh(write("a.node", node)).ntet(), 1);
  write("b.ele", ele);
  EXPECT_ERR(read_mesh(write("b.node", replaced(node, "4 3 1 1", "4 3 0 1"))),
             "b.node:2: expected 5 values (index x y z, 0 attributes, 1 markers, as the header on line 1 says), got 6");
  write("c.ele", ele);
  EXPECT_ERR(read_mesh(write("c.node", replaced(node, "4 3 1 1", "3 3 1 1"))),
             "c.node:5: the header on line 1 says 3 points, but more data follows");
  write("d.node", node);
  EXPECT_ERR(read_mesh(write("d.ele", "1 4 0\n1 1 2 3 4 7\n")),
             "d.ele:2: expected 5 values (index, 4 node indices, 0 region attributes, as the header on line 1 says), got 6");
  write("e.node", node);
  EXPECT_ERR(read_mesh(write("e.ele", ele + "2 1 2 4 3 7\n")), "e.ele:3: the header on line 1 says 1 tetrahedra, but more data follows");
  write("f.node", node);
  EXPECT_ERR(read_mesh(write("f.ele", "2 4 1\n1 1 2 3 4 7\n")), "unexpected end of file: 1 of 2 tetrahedra read");
}

}  // namespace
}  // namespace incise
