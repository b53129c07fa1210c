#include "collision/collision_model.h"

#include <string>
#include <vector>

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/math/bv/utility.h>  // fit(), which BVH_model-inl.h uses but does not include

#include "engine/util/error.h"

namespace incise {
namespace {

template <class BV>
std::shared_ptr<fcl::CollisionGeometryd> build_bvh(const TissueSurface& s) {
  auto m = std::make_shared<fcl::BVHModel<BV>>();
  std::vector<fcl::Vector3d> pts(s.nvert());
  for (int v = 0; v < s.nvert(); ++v) pts[v] = fcl::Vector3d(s.x[3 * v], s.x[3 * v + 1], s.x[3 * v + 2]);
  std::vector<fcl::Triangle> tris(s.ntri());
  for (int t = 0; t < s.ntri(); ++t) tris[t].set(s.tri[3 * t], s.tri[3 * t + 1], s.tri[3 * t + 2]);
  if (m->beginModel(s.ntri(), s.nvert()) != fcl::BVH_OK || m->addSubModel(pts, tris) != fcl::BVH_OK ||
      m->endModel() != fcl::BVH_OK)
    throw Error("CollisionModel: FCL could not build the tissue BVH (" + std::to_string(s.ntri()) + " triangles)");
  return m;
}

template <class BV>
void refit_bvh(fcl::CollisionGeometryd& g, const TissueSurface& s) {
  auto& m = static_cast<fcl::BVHModel<BV>&>(g);
  m.beginUpdateModel();
  for (int v = 0; v < s.nvert(); ++v) m.updateVertex(fcl::Vector3d(s.x[3 * v], s.x[3 * v + 1], s.x[3 * v + 2]));
  if (m.endUpdateModel(true, true) != fcl::BVH_OK) throw Error("CollisionModel: FCL could not refit the tissue BVH");
}

}  // namespace

void CollisionModel::rebuild(const Model& model, const State& state, int model_version) {
  if (static_cast<int>(state.u.size()) != model.ndof())
    throw Error("CollisionModel::rebuild: the state has " + std::to_string(state.u.size()) + " DOFs, the model " +
                std::to_string(model.ndof()));
  surface_ = TissueSurface(model, state, segments_);
  geometry_.reset();
  if (surface_.ntri() > 0)
    geometry_ = bv_ == TissueBV::AABB ? build_bvh<fcl::AABBd>(surface_) : build_bvh<fcl::OBBRSSd>(surface_);
  version_ = model_version;
  ++rebuilds_;
}

void CollisionModel::refit(const State& state) {
  surface_.update_positions(state);
  if (geometry_) {
    if (bv_ == TissueBV::AABB)
      refit_bvh<fcl::AABBd>(*geometry_, surface_);
    else
      refit_bvh<fcl::OBBRSSd>(*geometry_, surface_);
  }
  ++refits_;
}

SyncAction CollisionModel::sync(const Model& model, const State& state, int model_version) {
  if (version_ == model_version && surface_.ndof == model.ndof()) {
    refit(state);
    return SyncAction::Refit;
  }
  rebuild(model, state, model_version);
  return SyncAction::Rebuild;
}

}  // namespace incise
