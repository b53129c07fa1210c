#include "collision/contact_query.h"

#include <algorithm>

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/math/bv/utility.h>  // fit(), which BVH_model-inl.h uses but does not include
#include <fcl/narrowphase/collision.h>

#include "collision/narrowphase.h"

namespace incise {
namespace {

// World box around a tool part.
fcl::AABBd part_box(const ToolPart& part) {
  if (part.kind != ToolPart::Kind::Box) {
    const Eigen::Vector3d r = Eigen::Vector3d::Constant(part.radius);
    return fcl::AABBd(part.a.cwiseMin(part.b) - r, part.a.cwiseMax(part.b) + r);
  }
  const Eigen::Vector3d c = part.tf.translation(), e = part.tf.linear().cwiseAbs() * part.half;
  return fcl::AABBd(c - e, c + e);
}

// The triangles whose leaf box overlaps the part's box, in FCL's traversal
// order (depth first, left child first), at most `max`. This is FCL's
// mesh-shape descent without its set-up: fcl::collide on a tree of AABBs
// copies the whole BVHModel for every query (BVHShapeCollider in
// fcl/narrowphase/detail/collision_func_matrix-inl.h: 70 us and an allocation
// per query on the 20k organ), and FCL's traversal nodes cannot be built in
// this project's code: they hold Eigen transforms, which -march=native aligns
// to 32 bytes and Debian's libfcl to 16, so the node's fields would sit at
// other offsets than libfcl's constructor writes (valgrind showed it). The
// leaf test is then the exact one of collision/narrowphase.h.
bool aabb_candidates(const fcl::BVHModel<fcl::AABBd>& bvh, const fcl::AABBd& box, int max, std::vector<int>& out,
                     std::vector<int>& stack) {
  stack.clear();
  if (bvh.getNumBVs() > 0) stack.push_back(0);
  while (!stack.empty()) {
    const fcl::BVNode<fcl::AABBd>& node = bvh.getBV(stack.back());
    stack.pop_back();
    if (!node.bv.overlap(box)) continue;
    if (node.first_child < 0) {  // a leaf holds primitive -(first_child + 1)
      if (static_cast<int>(out.size()) >= max) return true;
      out.push_back(-(node.first_child + 1));
      continue;
    }
    stack.push_back(node.first_child + 1);  // right child after the left
    stack.push_back(node.first_child);
  }
  return false;
}

}  // namespace

void query_contacts(const CollisionModel& model, const ToolShape& tool, const ContactRequest& request,
                    ContactResult& result) {
  result.contacts.clear();
  result.candidates = 0;
  result.capped = false;
  result.face_rule = 0;
  if (!model.built()) return;
  const TissueSurface& s = model.surface();
  const int max_candidates = std::max(1, request.max_candidates);
  auto vertex = [&s](int v) { return Eigen::Vector3d(s.x[3 * v], s.x[3 * v + 1], s.x[3 * v + 2]); };
  for (int p = 0; p < tool.nparts; ++p) {
    const ToolPart& part = tool.part[p];
    std::vector<int>& cand = result.candidate_tris;
    cand.clear();
    if (model.bv() == TissueBV::AABB) {
      result.capped |= aabb_candidates(static_cast<const fcl::BVHModel<fcl::AABBd>&>(*model.geometry()),
                                       part_box(part), max_candidates, cand, result.stack);
    } else {
      // FCL's own query (oriented boxes: no copy); identity for the mesh,
      // whose vertices are in world coordinates already.
      const fcl::CollisionRequestd req(static_cast<size_t>(max_candidates), false);
      result.fcl_result.clear();
      fcl::collide(model.geometry(), fcl::Transform3d::Identity(), part.geometry.get(), part.tf, req,
                   result.fcl_result);
      for (size_t k = 0; k < result.fcl_result.numContacts(); ++k) cand.push_back(result.fcl_result.getContact(k).b1);
      result.capped |= static_cast<int>(cand.size()) >= max_candidates;
    }
    result.candidates += static_cast<int>(cand.size());
    for (const int t : cand) {
      const int* tv = &s.tri[3 * static_cast<size_t>(t)];
      const Eigen::Vector3d v0 = vertex(tv[0]), v1 = vertex(tv[1]), v2 = vertex(tv[2]);
      TriangleContact tc;
      const bool hit = part.kind == ToolPart::Kind::Box
                           ? box_triangle_contact(part.tf.translation(), part.tf.linear(), part.half, v0, v1, v2, tc)
                           : round_triangle_contact(part.a, part.b, part.radius, v0, v1, v2, tc, request.edges_geometric,
                                                    request.outside_tissue);
      if (!hit) continue;  // a box overlap, or FCL's test (an epsilon of slack): no depth
      result.face_rule += tc.face_rule;
      TissueContact& c = result.contacts.emplace_back();
      c.tri = t;
      c.face = s.tri_face[t];
      c.on_cut = s.tri_cut[t] != 0;
      c.part = p;
      for (int d = 0; d < 3; ++d) c.point[d] = tc.point[d], c.normal[d] = tc.normal[d];
      c.depth = tc.depth;
      c.elem = s.vert_elem[tv[0]];
      c.piece = s.vert_piece[tv[0]];
      c.side = s.vert_side[tv[0]];
      for (int d = 0; d < 3; ++d) {
        c.rst[d] = 0;
        for (int j = 0; j < 3; ++j) c.rst[d] += tc.bary[j] * s.vert_rst[3 * tv[j] + d];
      }
      c.weights = s.point_weights(c.elem, c.piece, c.rst, c.side);
    }
  }
  auto deeper = [](const TissueContact& a, const TissueContact& b) {
    return a.depth != b.depth ? a.depth > b.depth : (a.tri != b.tri ? a.tri < b.tri : a.part < b.part);
  };
  const size_t keep = static_cast<size_t>(std::max(0, request.max_contacts));
  if (result.contacts.size() > keep) {
    std::nth_element(result.contacts.begin(), result.contacts.begin() + keep, result.contacts.end(), deeper);
    result.contacts.resize(keep);
  }
  std::sort(result.contacts.begin(), result.contacts.end(), deeper);
}

double max_penetration(const CollisionModel& model, const ToolShape& tool) {
  ContactRequest req;
  req.max_contacts = 1;
  req.max_candidates = std::max(1, model.surface().ntri());
  ContactResult res;
  query_contacts(model, tool, req, res);
  return res.max_depth();
}

}  // namespace incise
