// Fuzzes the scene parser: incise::parse_scene (engine/scene/scene.h) on
// arbitrary text, as `incise run scene.json` would read it. parse_scene
// documents incise::Error as its only failure; any other exception escaping
// (std::bad_alloc, nlohmann::json::exception, std::out_of_range, ...) is a
// bug and ends the run as a crash, like a sanitizer report does.
//
// Input: the scene's JSON text; after a NUL byte, NUL-separated --set
// patches "KEY=VALUE" (at most 8), applied as `incise run --set` does.
// The scene is named INCISE_ROOT/assets/scenes/fuzz.json so that the seeds'
// relative paths (../meshes/..., ../trajectories/...) resolve and the parser
// gets past the mesh.file existence check. Nothing is written to disk.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "engine/scene/scene.h"
#include "engine/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string path = std::string(INCISE_ROOT) + "/assets/scenes/fuzz.json";
  const std::string in(reinterpret_cast<const char*>(data), size);
  size_t end = in.find('\0');
  const std::string text = in.substr(0, end);
  try {
    std::vector<incise::ScenePatch> patches;
    while (end != std::string::npos && patches.size() < 8) {
      const size_t next = in.find('\0', end + 1);
      patches.push_back(incise::parse_scene_patch(in.substr(end + 1, next == std::string::npos ? next : next - end - 1)));
      end = next;
    }
    const incise::Scene scene = incise::parse_scene(text, path, patches);
    (void)incise::resolved_settings(scene);  // what the solver report prints
  } catch (const incise::Error&) {
    // the documented failure: a message for the user
  }
  return 0;
}
