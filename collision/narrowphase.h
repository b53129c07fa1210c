#pragma once
// Contact geometry of one tool part against one tissue triangle, in closed
// form. FCL (collision/contact_query.cpp) decides which triangles touch; the
// contact itself is computed here, with one convention for every tool:
//   normal  the unit direction in which the tissue point must move to leave
//           the tool (into the tissue: the force on the tissue acts along it);
//   depth   how far it must move along `normal`, > 0;
//   point   the tissue point, on the triangle.
// n_out = (v1 - v0) x (v2 - v0) / |.| is the triangle's outward normal.
//
// Round tools (sphere: segment [p, q] with p = q; capsule) take the closest
// points x (triangle) and y (axis) at distance d < r. While the axis point is
// outside the face (s = (y - x) . n_out > 0) the contact is geometric:
// normal = (x - y) / d, depth = r - d, exact on curved surfaces and edges
// (over the face's interior that is -n_out and r - s, computed so). Once the
// axis reaches or passes the face plane the geometric direction would pull
// the tissue outward through the tool, so the contact follows the face:
// normal = -n_out and depth = r - min (z - x) . n_out over the axis points z
// within r of x: to the tangent plane, parallel to the face, of the part of
// the tool near the point (a sphere: r - s; at most 2r), continuous with the
// first rule where the axis point projects inside the face.
// Two exceptions: a capsule's side (y strictly between the ends) nearest an
// edge or corner of the face passes beside it, not through it: geometric on
// either side of the plane (a face beside a pressed shaft is pushed aside,
// not below the tip); and an axis that meets the face (d <= 1e-9 r) takes
// the face rule, whatever roundoff makes of the sign of s there. With
// edges_geometric any round part nearest an edge or corner is geometric on
// either side (contact.rows "triangle": small triangles folded round a
// sphere pressed deeper than its radius lie beside it, not over it). With
// outside_tissue (the caller found the tool's centre outside the tissue, so
// it came through no face: the faces behind it have folded round it) every
// round contact is geometric but where the axis meets the face.
//
// Boxes (scalpel blade, grasper jaws) always push along -n_out: depth is the
// largest distance the triangle must move along -n_out to clear the box,
// d_T - min { b . n_out : b in the box, b over the triangle } (d_T = v0 . n_out),
// a small linear program solved at its vertices; point is the projection of
// the minimising box point onto the triangle. This stays consistent however
// deep the box is, where a minimum-translation direction (libccd's MPR) may
// turn sideways or flip on a zero-thickness triangle.
#include <Eigen/Core>

namespace incise {

struct TriangleContact {
  Eigen::Vector3d point{0, 0, 0};
  Eigen::Vector3d normal{0, 0, 0};
  double depth = 0.0;
  double bary[3] = {0, 0, 0};  // of point: point = bary0 v0 + bary1 v1 + bary2 v2
  bool face_rule = false;      // round tools: the axis point at or behind the face's plane took the face rule
};

// Closest point of triangle (v0, v1, v2) to p (Ericson, Real-Time Collision
// Detection, 2005, sec. 5.1.5), as barycentric weights; returns the point.
Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& v0,
                                          const Eigen::Vector3d& v1, const Eigen::Vector3d& v2, double bary[3]);

// The point of segment [a, b] nearest x (a = b: a).
Eigen::Vector3d nearest_on_segment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& x);

// Closest points of segment [p, q] and the triangle: returns the squared
// distance; t in [0, 1] places the segment's point at p + t (q - p).
double closest_segment_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Vector3d& v0,
                                const Eigen::Vector3d& v1, const Eigen::Vector3d& v2, double& t, double bary[3]);

// false: no contact (also for a triangle of zero area).
bool round_triangle_contact(const Eigen::Vector3d& p, const Eigen::Vector3d& q, double radius,
                            const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2,
                            TriangleContact& out, bool edges_geometric = false, bool outside_tissue = false);
// How far x must move along the unit direction n to leave the round solid
// (segment [a, b] inflated by r; a = b: a sphere): the far end of the ray's
// interval inside it, the largest root over the two end spheres and the
// cylinder between them (the solid is convex, so the ray's exit lies on one
// of them). Negative infinity where the ray x + s n (s real) misses it.
double round_exit_distance(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r, const Eigen::Vector3d& x,
                           const Eigen::Vector3d& n);
// Box: centre, axes (columns of R, orthonormal), half extents.
bool box_triangle_contact(const Eigen::Vector3d& centre, const Eigen::Matrix3d& R, const Eigen::Vector3d& half,
                          const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2,
                          TriangleContact& out);

}  // namespace incise
