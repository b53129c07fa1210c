#pragma once
// Contacts of an instrument with the tissue surface, in FCL's request/result
// style: fill a ContactRequest, keep a ContactResult between frames (its
// buffers are reused), call query_contacts after CollisionModel::sync.
//
// FCL's own contact data for a mesh (o1) against a shape (o2), from its
// sources (fcl 0.7): the mesh-shape traversal node
// (narrowphase/detail/traversal/collision/mesh_shape_collision_traversal_node-inl.h)
// stores Contact(normal = -n) where n is the narrowphase's direction from
// the shape to the triangle, so Contact::normal points from the mesh to the
// shape, and Contact::b1 is the triangle. For a sphere
// (primitive_shape_algorithm/sphere_triangle-inl.h) the point lies on the
// triangle but the depth comes out negative, -(r - d), and outside the
// face's interior the point is on the LAST edge within reach, not the
// nearest. Other shapes go through libccd's MPR: a positive depth, a point
// midway between the surfaces and the direction of least translation, which
// on a zero-thickness triangle turns sideways or flips once the tool is more
// than half way through. So FCL's tree only says WHICH triangles may touch,
// and collision/narrowphase.h computes each contact in closed form with one
// convention: normal = the unit direction the tissue must move to leave the
// tool (into the tissue; a tool pressing on a face pushes it along -n_out,
// the face's inward normal), depth > 0 along it, point on the triangle.
// With the default AABB tree the query descends FCL's refitted BVHModel
// itself and the exact test is the leaf test (contact_query.cpp says why not
// fcl::collide); with OBBRSS, fcl::collide (enable_contact off, so no MPR
// penetration runs) picks the triangles and the exact test keeps those with
// depth.
#include <vector>

#include <fcl/narrowphase/collision_result.h>

#include "collision/collision_model.h"
#include "collision/point_weights.h"
#include "collision/tool_shape.h"

namespace incise {

struct ContactRequest {
  int max_contacts = 48;      // kept, deepest first (scene contact.max_rows)
  // Triangles the tree may pass per tool part; the descent stops there (in
  // tree order, not by depth), so this must exceed what a tool can touch.
  int max_candidates = 4096;
  // Round parts nearest a triangle's edge or corner are geometric on either
  // side of its plane (narrowphase.h; contact.rows "triangle").
  bool edges_geometric = false;
  // The tool's centre lies outside the tissue (the collision stage's
  // TissueLocator says so): no face rule (narrowphase.h).
  bool outside_tissue = false;
};

struct TissueContact {
  int tri = -1;          // triangle of the TissueSurface
  int face = -1;         // its source face (extracted Surface)
  bool on_cut = false;   // the face lies on a cut
  int part = 0;          // tool part: grasper jaw 0 (-y) or 1 (+y); 0 for a probe or scalpel
  double point[3] = {0, 0, 0};   // tissue point on the triangle (world)
  double normal[3] = {0, 0, 0};  // unit: the direction the tissue moves to leave the tool
  double depth = 0.0;            // > 0, along normal
  // Found by the frame's sweep of a fast probe, not at its end pose
  // (collision_stage.cpp, sweep_probe): normal from the first sub-pose
  // that touched the face, depth to leave the end pose along it.
  bool swept = false;
  // A speculative row for tissue that may reach a resting probe within the
  // frame (collision_stage.cpp, add_speculative_contacts): depth < 0.
  bool speculative = false;
  // The material point: element, piece (-1 without cuts), local coordinates
  // (the barycentric point mapped through the triangle's vertex rst, which is
  // linear over a tessellated triangle), and the DOFs that move it:
  // x = X(rst) + sum_k w_k u(dofnode_k). It reproduces `point` exactly on
  // straight-sided, affinely deformed faces; on curved ones it is the
  // material point, within the tessellation error of the triangle.
  int elem = -1, piece = -1;
  int side = 0;                  // of the front's cut plane (TissueSurface::vert_side)
  double rst[3] = {0, 0, 0};
  PointWeights weights;
};

struct ContactResult {
  std::vector<TissueContact> contacts;  // deepest first (ties: lower triangle id first)
  int candidates = 0;                   // triangles given to the exact test, all parts
  bool capped = false;                  // a part reached max_candidates: contacts may be missing
  int face_rule = 0;                    // contacts that took the face rule (narrowphase.h)
  double max_depth() const { return contacts.empty() ? 0.0 : contacts.front().depth; }
  // Scratch kept between queries, so a frame allocates nothing.
  std::vector<int> candidate_tris, stack;
  fcl::CollisionResultd fcl_result;
};

void query_contacts(const CollisionModel& model, const ToolShape& tool, const ContactRequest& request,
                    ContactResult& result);

// The deepest penetration of the tool into the surface (0: none), every
// triangle considered; for tests and reports.
double max_penetration(const CollisionModel& model, const ToolShape& tool);

}  // namespace incise
