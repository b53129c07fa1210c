// Tetrahedral mesh of a segmented image with CGAL's Mesh_3 (not part of the
// incise build: tools/scripts/mesh-liver.sh compiles and runs it once to make
// assets/meshes/liver.vtk). Every voxel label > 0 is tissue (the liver image
// of CGAL's data labels the parenchyma and its vessels; one material here;
// its own example, examples/Mesh_3/mesh_3D_image.cpp, meshes the same image).
// Writes legacy ASCII VTK tetrahedra in metres (the image's spacing is in
// mm), centred on the mesh's bounding box.
//
// usage: liver_mesh IMAGE.inr OUT.vtk CELL_SIZE_MM FACET_DISTANCE_MM
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <algorithm>
#include <map>
#include <vector>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Image_3.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/make_mesh_3.h>

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Domain = CGAL::Labeled_mesh_domain_3<K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;
namespace params = CGAL::parameters;

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: %s IMAGE.inr OUT.vtk CELL_SIZE_MM FACET_DISTANCE_MM\n", argv[0]);
    return 2;
  }
  CGAL::Image_3 image;
  if (!image.read(argv[1])) {
    std::fprintf(stderr, "%s: cannot read the image\n", argv[1]);
    return 1;
  }
  const double size = std::atof(argv[3]), distance = std::atof(argv[4]);
  // Each label > 0 a subdomain (parenchyma, vessels); all of them are tissue here.
  Domain domain = Domain::create_labeled_image_mesh_domain(image);
  Criteria criteria(params::facet_angle = 25, params::facet_size = size, params::facet_distance = distance,
                    params::cell_radius_edge_ratio = 2.5, params::cell_size = size);
  CGAL::get_default_random() = CGAL::Random(1);  // the same mesh on every run
  // Default optimisers: perturbation and sliver exudation.
  const C3t3 c3t3 = CGAL::make_mesh_3<C3t3>(domain, criteria);
  // Vertices of the cells in the complex, renumbered from 0.
  std::map<Tr::Vertex_handle, int> id;
  std::vector<Tr::Vertex_handle> verts;
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c)
    for (int i = 0; i < 4; ++i)
      if (id.emplace(c->vertex(i), static_cast<int>(verts.size())).second) verts.push_back(c->vertex(i));
  // Centred on its bounding box (the image's origin is a corner of the scan).
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (const auto& v : verts) {
    const auto p = v->point().point();
    const double x[3] = {p.x(), p.y(), p.z()};
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], x[k]), hi[k] = std::max(hi[k], x[k]);
  }
  const double c[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
  std::ofstream os(argv[2]);
  os.precision(9);
  os << "# vtk DataFile Version 3.0\nliver (CGAL Mesh_3 of CGAL's data/images/liver.inr.gz, metres)\nASCII\n"
        "DATASET UNSTRUCTURED_GRID\nPOINTS "
     << verts.size() << " double\n";
  for (const auto& v : verts) {
    const auto p = v->point().point();
    os << 1e-3 * (p.x() - c[0]) << ' ' << 1e-3 * (p.y() - c[1]) << ' ' << 1e-3 * (p.z() - c[2]) << '\n';
  }
  const std::size_t n = c3t3.number_of_cells_in_complex();
  os << "CELLS " << n << ' ' << 5 * n << '\n';
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    int t[4];
    for (int i = 0; i < 4; ++i) t[i] = id[c->vertex(i)];
    // Positive orientation (incise refuses inverted elements).
    const auto& a = verts[t[0]]->point().point();
    const auto& b = verts[t[1]]->point().point();
    const auto& cc = verts[t[2]]->point().point();
    const auto& d = verts[t[3]]->point().point();
    if (CGAL::orientation(a, b, cc, d) == CGAL::NEGATIVE) std::swap(t[2], t[3]);
    os << "4 " << t[0] << ' ' << t[1] << ' ' << t[2] << ' ' << t[3] << '\n';
  }
  os << "CELL_TYPES " << n << '\n';
  for (std::size_t i = 0; i < n; ++i) os << "10\n";
  if (!os) {
    std::fprintf(stderr, "%s: cannot write\n", argv[2]);
    return 1;
  }
  std::printf("%zu vertices, %zu tetrahedra\n", verts.size(), n);
  return 0;
}
