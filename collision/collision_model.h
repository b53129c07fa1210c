#pragma once
// The FCL model of the deformed tissue surface: a bounding-volume tree over
// the TissueSurface triangles (collision/tissue_surface.h). Each frame moves
// the vertices and REFITS the tree (same triangles, boxes recomputed bottom
// up); only a new Model version (a cut: new faces and DOFs) REBUILDS it: a
// new surface and a new tree. Both are counted, so a test can assert that a
// frame without a topology change rebuilds nothing.
//
// FCL's refit (BVHModel::endUpdateModel(true, true)) fits each leaf around
// the triangle's previous and current positions (its continuous-collision
// use), so the boxes are a little loose but never miss the current triangle.
#include <memory>

#include <fcl/geometry/collision_geometry.h>

#include "collision/tissue_surface.h"
#include "engine/dynamics/state.h"
#include "engine/model/model.h"

namespace incise {

// Bounding volume of the tree. AABB (the default): FCL refits it in 0.4 ms on
// the 20k organ, and queries descend it in collision/contact_query.cpp.
// OBBRSS (FCL's usual mesh choice): tighter, queried by fcl::collide itself,
// but FCL refits it in 14 ms (an eigen-decomposition fit per node).
// tools/bench/collision_bench.cpp measures both.
enum class TissueBV { AABB, OBBRSS };

enum class SyncAction { Refit, Rebuild };

class CollisionModel {
 public:
  // segments: per tet10 face edge (scene render.subdivision).
  explicit CollisionModel(int segments = 2, TissueBV bv = TissueBV::AABB) : segments_(segments), bv_(bv) {}

  // Refits when model_version is the one the tree was built for (and the
  // state fits it), otherwise rebuilds; says which.
  SyncAction sync(const Model& model, const State& state, int model_version);
  // New surface and tree from the model (after a topology change).
  void rebuild(const Model& model, const State& state, int model_version);
  // Vertex positions from the state, then the tree refitted to them; no allocation.
  void refit(const State& state);

  bool built() const { return geometry_ != nullptr; }
  const TissueSurface& surface() const { return surface_; }
  // The BVHModel (fcl::BVHModel<fcl::AABBd> or <fcl::OBBRSSd>), vertices in world coordinates.
  const fcl::CollisionGeometryd* geometry() const { return geometry_.get(); }
  TissueBV bv() const { return bv_; }
  int segments() const { return segments_; }
  int model_version() const { return version_; }
  long refits() const { return refits_; }
  long rebuilds() const { return rebuilds_; }

 private:
  int segments_;
  TissueBV bv_;
  TissueSurface surface_;
  std::shared_ptr<fcl::CollisionGeometryd> geometry_;
  int version_ = -1;
  long refits_ = 0, rebuilds_ = 0;
};

}  // namespace incise
