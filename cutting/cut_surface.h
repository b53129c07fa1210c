#pragma once
// Cut surfaces as sets of planar facets: an infinite plane, a bounded planar
// polygon, a triangle mesh, and the surface swept by a blade edge (a segment
// moving between two poses), which grows with time.
//
// The level set of a cut at a point is the signed distance ([preprint] eq.
// (72)) to the plane of the nearest facet; its sign is decided exactly against that facet's plane
// (cutting/exact_sign.h), so "node on the surface" is a yes/no question that
// does not depend on the model's scale or a tolerance.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "engine/scene/scene.h"

namespace incise {

struct Facet {
  std::array<Vec3, 3> v{};  // triangle corners; unused for an unbounded plane
  Vec3 p{}, n{};            // plane point and unit normal (the sign convention)
  bool unbounded = false;   // the infinite plane: every point of it is covered
};

class CutSurface {
 public:
  explicit CutSurface(std::vector<Facet> facets, std::string name);

  // Signed distance to the nearest facet's plane and the exact sign of it.
  struct Value {
    double phi;
    int sign;  // -1, 0, +1, exact against the chosen facet's plane
  };
  Value value(const double x[3]) const;
  // Whether y (a point on the zero set near an element) lies on the surface's
  // extent, within tol: distance to the nearest facet triangle <= tol.
  bool covers(const double y[3], double tol) const;
  // Whether the segment a-b passes through one of the facets (within tol of
  // its triangle where it crosses the facet's plane). For a curved or kinked
  // surface the zero of the nearest-facet level set interpolated along an
  // edge lies off the facets although the edge is cut.
  bool crosses_segment(const double a[3], const double b[3], double tol) const;
  const std::string& name() const { return name_; }
  // Extra reach of covers(), in multiples of the caller's tolerance. 0 for
  // the scene's cuts (their extent is exact); an instrument's sweep is a
  // chain of bands mapped through the deformed tissue, slightly out of plane
  // with each other, so the zero set of the nearest-facet level set strays
  // from its facets by a fraction of an element (make_swept_surface).
  void set_cover_slack(double multiple) { slack_ = multiple; }
  const std::vector<Facet>& facets() const { return facets_; }
  // Signed distance from x, in the plane of the surface's boundary edge
  // nearest to x, to that edge's line: > 0 outside the surface (ahead of its
  // front), < 0 inside. The second level set of a cut front (psi, beside phi
  // = value(); [preprint] sec. 4 uses one per crack front). 1e300 for a
  // surface without boundary (the infinite plane). A boundary edge is an
  // edge of one facet only (vertices matched exactly).
  double front_distance(const double x[3]) const;
  // The facet nearest to x (distance to its triangle; the level set's), and
  // that distance.
  const Facet& nearest(const double x[3]) const { return facets_[nearest_facet(x)]; }
  double distance(const double x[3]) const;

 private:
  struct Edge {
    Vec3 a{}, b{}, m{};  // end points; in-plane unit normal pointing away from its facet
  };
  std::vector<Facet> facets_;
  std::vector<Edge> boundary_;
  // (facets, 3) pseudonormals (unnormalised; their direction is what counts)
  // of each facet's edges (edge j: corners j, j + 1; the sum of the normals
  // of the facets that share it) and corners (the normals of the facets
  // around it, each weighted by its angle there): the sign of the level set
  // where the nearest point of the surface is on an edge or a corner
  // (Baerentzen and Aanaes, "Signed distance computation using the angle
  // weighted pseudonormal", IEEE TVCG 11(3), 2005).
  std::vector<std::array<Vec3, 3>> edge_normal_, corner_normal_;
  // (facets) each facet's bounding sphere: centre (corner mean) and radius
  // (infinite for the unbounded plane). |x - c| - r bounds the distance to
  // the triangle from below, so the queries skip a facet that cannot be
  // nearer than one already found (or within the tolerance) and return what
  // the full scan would: a scalpel's surface has one band of 2 ns triangles
  // per motion step (blade_sweep.h), hundreds after a long incision.
  std::vector<Vec3> centre_;
  std::vector<double> radius_;
  // An AABB tree over the facets (Eigen's KdBVH), built where there are
  // kTreeFacets or more and none is unbounded: the queries then visit only
  // the facets near x. A long incision's surface has a thousand facets and
  // the layout asks for the level set at every corner node of the mesh
  // (organ_20k late in a stroke: layout 14.6 ms a cut frame with the scan,
  // 5.2 with the tree). Every query returns what the scan would, ties
  // included (the nearest facet of lowest index; CutSurfaceTree test,
  // fuzz_cut_surface). Shared: the tree is immutable, and a copy of the
  // surface may keep it.
  static constexpr size_t kTreeFacets = 16;
  struct FacetTree;
  std::shared_ptr<const FacetTree> tree_;
  std::string name_;
  double slack_ = 0.0;
  int nearest_facet(const double x[3]) const;
  double lower_bound(const double x[3], size_t k) const;
  double facet_distance(size_t k, const double x[3]) const;  // to facet k's triangle (plane if unbounded)
  double triangle_distance(size_t k, const double x[3]) const;  // to facet k's triangle, bounded (the .cpp)
  bool facet_crosses(size_t k, const double a[3], const double b[3], double tol) const;  // crosses_segment's test
  bool facet_covers(size_t k, const double y[3], double tol) const;                      // covers' test
};

// Builds the surface of a scene cut at time t (a swept cut covers the part of
// its sweep done by t; nullptr when nothing has been swept yet). Mesh cuts
// read .obj or ASCII .stl triangle files; errors name the file and line.
std::unique_ptr<CutSurface> make_cut_surface(const CutSpec& spec, double t);

// The surface instrument `tool` swept (State::swept, swept_tool: (ntri, 9)
// and (ntri)): all of its triangles, or those in `ranges` ([begin, end)
// counted over its own, in order); nullptr when that swept nothing.
std::unique_ptr<CutSurface> make_swept_surface(const std::vector<double>& swept, const std::vector<double>& swept_tool,
                                               int tool, const std::string& name,
                                               const std::vector<std::pair<size_t, size_t>>& ranges = {});

// Whether triangle (a, b, c) (3 coordinates each) has no usable plane: twice
// its area over its longest edge squared is <= 1e-12 (an angle below about
// 1e-12 rad), in scaled coordinates.
bool degenerate_triangle(const double* a, const double* b, const double* c);

// Reads a triangle surface (.obj or ASCII .stl) as facets.
std::vector<Facet> read_triangle_surface(const std::string& path);

}  // namespace incise
