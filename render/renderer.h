#pragma once
// Offscreen renderer of a DisplayMesh (tissue, with cut faces in the
// interior colour) and instrument shapes, into an FBO read back as an Image.
//
// Per frame: update(mesh) -> set_instruments(...) -> render(). update()
// rebuilds the faces, smoothing groups and index buffer only when the mesh's
// cell structure changed (topology_signature, e.g. after a cut); otherwise it
// recomputes and re-uploads positions and normals only.
#include <cstdint>
#include <memory>
#include <vector>

#include "engine/output/display_mesh.h"
#include "engine/scene/scene.h"
#include "render/camera.h"
#include "render/egl_context.h"
#include "render/image.h"
#include "render/instrument_shape.h"
#include "engine/output/surface_extract.h"
#include "render/tessellate.h"

namespace incise {

class Renderer {
 public:
  // Creates the EGL context (platform: see egl_context.h) and the FBO.
  explicit Renderer(const RenderSettings& settings, EglPlatform platform = egl_platform_from_env());
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  void update(const DisplayMesh& mesh);
  void set_instruments(const std::vector<InstrumentShape>& instruments);
  Image render();

  // Framed from the first mesh given to update() (then fixed, so the view
  // does not follow the motion); set_camera overrides it.
  const Camera& camera() const { return camera_; }
  void set_camera(const Camera& c) { camera_ = c, camera_set_ = true; }
  const EglContext& context() const { return *context_; }

  struct Stats {
    int topology_builds = 0;  // times faces and index buffers were rebuilt
    int position_uploads = 0; // times positions/normals were re-uploaded
    int nboundary = 0, ncut = 0, ntriangle = 0, nvertex = 0;
  };
  const Stats& stats() const { return stats_; }

 private:
  struct Gl;
  void rebuild_topology(const DisplayMesh& mesh);

  RenderSettings settings_;
  std::unique_ptr<EglContext> context_;
  std::unique_ptr<Gl> gl_;
  Camera camera_;
  bool camera_set_ = false;
  std::uint64_t signature_ = 0;
  bool have_mesh_ = false;
  Surface surface_;
  Tessellation tess_;
  std::vector<float> pos_, nrm_;   // (nvert, 3) each
  std::vector<double> work_;       // tessellate scratch
  std::vector<float> ipos_, inrm_; // instrument triangles, (3 * ntri, 3) each
  std::vector<std::pair<int, Vec3>> instrument_draws_;  // vertex count and colour per instrument
  std::vector<unsigned char> readback_;                 // (height, width, 4)
  Stats stats_;
};

}  // namespace incise
