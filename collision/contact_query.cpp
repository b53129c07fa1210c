#include "collision/contact_query.h"

#include <algorithm>

#include <fcl/narrowphase/collision.h>

#include "collision/narrowphase.h"

namespace incise {

void query_contacts(const CollisionModel& model, const ToolShape& tool, const ContactRequest& request,
                    ContactResult& result) {
  result.contacts.clear();
  result.candidates = 0;
  result.capped = false;
  if (!model.built()) return;
  const TissueSurface& s = model.surface();
  const fcl::CollisionRequestd req(static_cast<size_t>(std::max(1, request.max_candidates)), false);
  // Identity for the mesh: its vertices are already in world coordinates
  // (FCL would rewrite them for any other transform).
  const fcl::Transform3d identity = fcl::Transform3d::Identity();
  auto vertex = [&s](int v) { return Eigen::Vector3d(s.x[3 * v], s.x[3 * v + 1], s.x[3 * v + 2]); };
  for (int p = 0; p < tool.nparts; ++p) {
    const ToolPart& part = tool.part[p];
    result.fcl_result.clear();
    fcl::collide(model.geometry(), identity, part.geometry.get(), part.tf, req, result.fcl_result);
    const int n = static_cast<int>(result.fcl_result.numContacts());
    result.candidates += n;
    result.capped = result.capped || n >= request.max_candidates;
    for (int k = 0; k < n; ++k) {
      const int t = result.fcl_result.getContact(k).b1;
      const int* tv = &s.tri[3 * static_cast<size_t>(t)];
      const Eigen::Vector3d v0 = vertex(tv[0]), v1 = vertex(tv[1]), v2 = vertex(tv[2]);
      TriangleContact tc;
      const bool hit = part.kind == ToolPart::Kind::Box
                           ? box_triangle_contact(part.tf.translation(), part.tf.linear(), part.half, v0, v1, v2, tc)
                           : round_triangle_contact(part.a, part.b, part.radius, v0, v1, v2, tc);
      if (!hit) continue;  // FCL's test keeps an epsilon of slack; grazing contacts have no depth
      TissueContact& c = result.contacts.emplace_back();
      c.tri = t;
      c.face = s.tri_face[t];
      c.on_cut = s.tri_cut[t] != 0;
      c.part = p;
      for (int d = 0; d < 3; ++d) c.point[d] = tc.point[d], c.normal[d] = tc.normal[d];
      c.depth = tc.depth;
      c.elem = s.vert_elem[tv[0]];
      c.piece = s.vert_piece[tv[0]];
      for (int d = 0; d < 3; ++d) {
        c.rst[d] = 0;
        for (int j = 0; j < 3; ++j) c.rst[d] += tc.bary[j] * s.vert_rst[3 * tv[j] + d];
      }
      c.weights = s.point_weights(c.elem, c.piece, c.rst);
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
