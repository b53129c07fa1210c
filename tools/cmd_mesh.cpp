// incise mesh beam | convert | tetrahedralize: structured beams, format
// conversion, and a closed surface filled with tetrahedra (TetGen).
#include <array>
#include <cstdio>

#include "engine/util/error.h"
#include "engine/mesh/mesh_io.h"
#include "engine/mesh/mesh_tools.h"
#include "tools/commands.h"
#include "tools/option_checks.h"
#include "tools/tetrahedralize.h"

namespace incise {

namespace {
struct BeamOptions {
  std::array<double, 3> size{1, 1, 1};
  std::array<int, 3> cells{1, 1, 1};
  int order = 1;
  std::string out;
};
struct ConvertOptions {
  std::string in, out;
  int order = 0;  // 0: keep
};
struct TetOptions {
  std::string in, out;
  double size = 0, quality = 1.4;
  int order = 2;
  bool fill_cavities = false;
};

void report(const Mesh& m, const std::string& path) {
  std::printf("wrote %s\n%s", path.c_str(), format_quality(mesh_quality(m)).c_str());
}
}  // namespace

void add_mesh_command(CLI::App& app) {
  auto* mesh = app.add_subcommand("mesh", "Make or convert tetrahedral meshes");
  mesh->require_subcommand(1);

  auto b = std::make_shared<BeamOptions>();
  auto* beam = mesh->add_subcommand("beam", "Structured beam [0,LX]x[0,LY]x[0,LZ], 6 tetrahedra per cell");
  beam->add_option("--size", b->size, "LX LY LZ (each from 1e-6 to 1e6)")->required()->check(finite_in(1e-6, 1e6));
  beam->add_option("--cells", b->cells,
                   "NX NY NZ: cells along each side, 6 tetrahedra each, at most " + std::to_string(kMaxBeamTets) +
                       " tetrahedra in all")
      ->required()
      ->check(integer_in(1, kMaxBeamTets / 6));
  beam->add_option("--order", b->order, "1 = tet4, 2 = tet10")->check(CLI::IsMember({1, 2}));
  beam->add_option("--out", b->out, "Output mesh (.vtu, .vtk, .msh)")->required();
  beam->callback([b] {
    // Bounded before anything is allocated: 10^5 cells a side asked for 6e15 tetrahedra.
    const double tets = 6.0 * b->cells[0] * b->cells[1] * b->cells[2];
    if (tets > static_cast<double>(kMaxBeamTets)) {
      char buf[192];
      std::snprintf(buf, sizeof buf, "mesh beam: --cells %d %d %d makes %.3g tetrahedra (6 a cell), more than the %lld allowed",
                    b->cells[0], b->cells[1], b->cells[2], tets, kMaxBeamTets);
      throw Error(buf);
    }
    const Mesh m = make_beam(b->size[0], b->size[1], b->size[2], b->cells[0], b->cells[1], b->cells[2], b->order);
    write_mesh(m, b->out);
    report(m, b->out);
  });

  auto c = std::make_shared<ConvertOptions>();
  auto* conv = mesh->add_subcommand("convert", "Convert between mesh formats (optionally raise to tet10)");
  conv->add_option("in", c->in, "Input mesh (.msh, .vtk, .vtu, .node/.ele, .inp)")->required()->check(CLI::ExistingFile);
  conv->add_option("out", c->out, "Output mesh (.vtu, .vtk, .msh)")->required();
  conv->add_option("--order", c->order, "2 raises tet4 to tet10, 1 keeps a tet10 mesh's corner nodes")
      ->check(CLI::IsMember({1, 2}));
  conv->callback([c] {
    Mesh m = read_mesh(c->in);
    check_mesh(m);
    if (c->order == 2) m = raise_to_tet10(m);
    if (c->order == 1) m = lower_to_tet4(m);
    write_mesh(m, c->out);
    report(m, c->out);
  });

  auto t = std::make_shared<TetOptions>();
  auto* tet = mesh->add_subcommand("tetrahedralize", "Fill a closed triangle surface with tetrahedra (TetGen)");
  tet->add_option("surface", t->in, "Closed surface (.stl, .ply, .off, .obj), e.g. from a segmentation")
      ->required()
      ->check(CLI::ExistingFile);
  tet->add_option("--size", t->size, "Target edge length (the surface's units)")->required()->check(finite_in(1e-9, 1e9));
  tet->add_option("--order", t->order, "2 = tet10 (default), 1 = tet4")->check(CLI::IsMember({1, 2}));
  tet->add_option("--quality", t->quality, "Largest radius-edge ratio TetGen may leave (default 1.4; 1.1 to 10)")
      ->check(finite_in(1.1, 10));
  tet->add_option("--out", t->out, "Output mesh (.vtu, .vtk, .msh)")->required();
  tet->add_flag("--fill-cavities", t->fill_cavities,
                "Fill the inside of inner closed shells with tissue too (by default a region no outer face bounds is "
                "a cavity, left empty)");
  tet->callback([t] {
    std::string note;
    Mesh m = tetrahedralize(t->in, t->size, t->quality, t->fill_cavities, &note);
    std::printf("%s", note.c_str());
    check_mesh(m);
    if (t->order == 2) m = raise_to_tet10(m);
    write_mesh(m, t->out);
    report(m, t->out);
  });
}

}  // namespace incise
