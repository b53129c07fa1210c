#pragma once
// X-FEM layout of a mesh cut by surfaces: element classification, sub-element
// decomposition, the regions of each node's support and the enriched DOF
// nodes they need. The result feeds build_model (engine/model/cut_layout.h).
//
// Classification of an element against one cut, from the exact signs of the
// level set at its corners ([preprint] eq. (73)):
//   - corners strictly on both sides and every zero crossing on the surface's
//     extent: CUT (split into pieces);
//   - corners strictly on both sides but the surface ends inside: the cut
//     front. The element stays whole and its nodes get no enrichment from
//     this front, so the opening closes at the last fully crossed element
//     face (documented in docs/cutting.md);
//   - otherwise untouched or touched (a node, an edge or a face exactly on the
//     surface). A face exactly on a covered surface separates its two
//     elements: their pieces are not connected across it.
// Regions: pieces connect across shared faces where they overlap with positive
// area; the connected components of the pieces in a node's support are its
// regions. The home region (largest volume) keeps the standard DOF; every
// other region gets an enriched DOF node (shifted enrichment, [preprint] eqs.
// (42), (44); appended after the mesh nodes, eq. (74)). Choosing the largest
// region, not the one holding the node, keeps a cut 1e-12 h from a node from
// making the standard and enriched functions nearly equal (an ill-conditioned
// pair).
#include <string>
#include <vector>

#include "cutting/cut_surface.h"
#include "engine/model/cut_layout.h"
#include "engine/model/model.h"

namespace incise {

struct CutReport {
  int cut_elements = 0;    // elements split into pieces
  int front_elements = 0;  // the surface's boundary passes through (crossed, not fully: the cut front)
  int separated_faces = 0; // element faces lying on a cut
  int pieces = 0;          // pieces in split elements
  int enriched_nodes = 0;  // enriched DOF nodes
  double min_fraction = 1.0;  // smallest piece volume fraction
  int bodies = 1;          // connected pieces of tissue after the cuts
  // Surfaces (indices into `cuts`) flagged for front enrichment whose front
  // stayed on element faces: it lies too close to an earlier surface's
  // enriched front (a corner carries one front's level sets) or in an
  // element another cut splits.
  std::vector<int> fronts_on_faces;
};

// cuts: the active surfaces (order = enrichment order). base: a model of the
// mesh, cut or not (only its element mesh and element volumes are read).
// Known limit: node regions are found across shared faces, so a mesh pinched
// at a single node or edge already counts as two regions there; once a cut
// splits an element at such a node, the pinch is released.
// branch_front: the cut front enrichment of CutLayout::node_branch (scene
// cut_front "enriched", docs/cutting.md) for every surface, or (the vector
// form: one flag per surface of `cuts`) for those flagged; without it a
// front closes the opening at the last fully crossed element face. Flagged
// surfaces are taken in order; one whose front cannot be enriched beside
// the earlier ones keeps it on faces (report->fronts_on_faces).
CutLayout compute_cut_layout(const Model& base, const std::vector<const CutSurface*>& cuts, CutReport* report,
                             const std::vector<char>& branch_front);
inline CutLayout compute_cut_layout(const Model& base, const std::vector<const CutSurface*>& cuts,
                                    CutReport* report = nullptr, bool branch_front = false) {
  return compute_cut_layout(base, cuts, report, std::vector<char>(branch_front ? cuts.size() : 0, 1));
}

}  // namespace incise
