// Fuzzes the cut-surface readers and validation (cutting/cut_surface.cpp):
// read_triangle_surface (.obj, ASCII .stl) through make_cut_surface, and the
// polygon checks (simple, convex, planar, scaled normal).
//
// Input: one selector byte, then the payload. 'o' .obj, 's' .stl (the file's
// text, written to a private folder: the reader takes a path), 'p' a polygon
// cut whose points are the payload read as doubles (3 a point, up to 64
// points); any other byte picks by its value mod 3.
// Only incise::Error may escape; a surface that is returned must have finite
// corners and unit normals, and its facet tree (16 facets or more) must
// answer what a scan over its facets does.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "cutting/cut_surface.h"
#include "engine/util/error.h"
#include "fuzz/fuzz_tmp.h"

namespace {

[[noreturn]] void bad(const char* what) {
  std::fprintf(stderr, "fuzz_cut_surface: an accepted cut surface is inconsistent: %s\n", what);
  std::abort();
}

void same_as_scan(const incise::CutSurface& s, const double x0[3]);

void check(const incise::CutSurface& s) {
  for (const incise::Facet& f : s.facets()) {
    const double n = std::sqrt(f.n[0] * f.n[0] + f.n[1] * f.n[1] + f.n[2] * f.n[2]);
    if (!(std::abs(n - 1.0) < 1e-9)) bad("a facet normal is not a unit vector");
    for (const auto& v : f.v)
      for (double x : v)
        if (!std::isfinite(x)) bad("a non-finite corner");
  }
  const double x[3] = {0.25, -0.5, 1.0};
  const incise::CutSurface::Value v = s.value(x);
  if (std::isnan(v.phi) || v.sign < -1 || v.sign > 1) bad("value() at a point");
  if (std::isnan(s.front_distance(x))) bad("front_distance() at a point");
  same_as_scan(s, x);
}

// A surface of many facets answers through its facet tree: it must answer
// what the scan over every facet does (each facet alone is a surface that
// is scanned), at the fixed point, the first facets' corners and a centroid.
void same_as_scan(const incise::CutSurface& s, const double x0[3]) {
  const auto& facets = s.facets();
  if (facets.size() < 16 || facets.size() > 256) return;
  std::vector<incise::CutSurface> single;
  for (const incise::Facet& f : facets) single.emplace_back(std::vector<incise::Facet>{f}, "one");
  std::vector<incise::Vec3> pts = {{x0[0], x0[1], x0[2]}};
  for (size_t k = 0; k < 3; ++k)
    for (const auto& c : facets[k].v) pts.push_back(c);
  incise::Vec3 g{};
  for (const auto& c : facets[3].v)
    for (int d = 0; d < 3; ++d) g[d] += c[d] / 3.0;
  pts.push_back(g);
  for (size_t i = 0; i < pts.size(); ++i) {
    const double* p = pts[i].data();
    long first = 0;  // as the scan: facet 0 where no distance is below 1e300 (NaN where coordinates overflow)
    double best = 1e300;
    bool covered = false, crossed = false;
    const double* q = pts[(i + 1) % pts.size()].data();
    for (size_t k = 0; k < single.size(); ++k) {
      const double d = single[k].distance(p);
      if (d < best) best = d, first = static_cast<long>(k);
      covered = covered || single[k].covers(p, 1e-9);
      crossed = crossed || single[k].crosses_segment(p, q, 1e-9);
    }
    if (&s.nearest(p) - facets.data() != first) bad("the nearest facet differs from the scan's");
    if (s.covers(p, 1e-9) != covered) bad("covers() differs from the scan's");
    if (s.crosses_segment(p, q, 1e-9) != crossed) bad("crosses_segment() differs from the scan's");
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz_tmp::init("incise-fuzz-cut.", {"in.obj", "in.stl"});
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  int mode = data[0] % 3;
  switch (data[0]) {
    case 'o': mode = 0; break;
    case 's': mode = 1; break;
    case 'p': mode = 2; break;
  }
  incise::CutSpec c;
  c.json_path = "cuts[0]";
  if (mode < 2) {
    c.type = incise::CutSpec::Type::Mesh;
    c.file = fuzz_tmp::put(mode == 0 ? "in.obj" : "in.stl", data + 1, size - 1);
  } else {
    c.type = incise::CutSpec::Type::Polygon;
    const size_t np = std::min<size_t>((size - 1) / 24, 64);
    if (np < 3) return 0;  // the scene parser requires 3 points
    for (size_t k = 0; k < np; ++k) {
      incise::Vec3 p;
      std::memcpy(p.data(), data + 1 + 24 * k, 24);
      for (double& x : p)
        if (!std::isfinite(x)) x = 0;  // the scene parser admits finite numbers only
      c.points.push_back(p);
    }
  }
  try {
    const auto s = incise::make_cut_surface(c, 0.0);
    if (s) check(*s);
  } catch (const incise::Error&) {
    // the documented failure: "FILE:LINE: what was wrong"
  }
  return 0;
}
