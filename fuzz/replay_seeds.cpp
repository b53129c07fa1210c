// Writes a few small, valid replay files with incise::ReplayWriter
// (engine/runtime/replay_file.h) as seeds for fuzz_replay, so the fuzz run
// needs no engine binary: replay_seeds OUTDIR. Each is read back with
// read_replay to check that it is valid.
#include <cmath>
#include <cstdio>
#include <string>

#include "engine/runtime/replay_file.h"
#include "engine/util/error.h"

using namespace incise;

namespace {

ReplayFrame frame(int k, size_t tools, bool snapshot) {
  ReplayFrame f;
  f.frame = k;
  f.time = k / 30.0;
  f.late_factor_call = k % 3 - 1;
  f.cut_frame = k == 2;
  f.contacts = k;
  f.grasp_rows = k % 2;
  f.swept_triangles = 3 * k;
  for (size_t i = 0; i < tools; ++i) {
    ToolFrame t;
    t.before.p = {0.01 * k, 0.02, -0.01 * static_cast<double>(i)};
    t.after = t.before;
    t.after.p[0] += 0.001;
    t.after.q = {std::sqrt(0.5), 0.0, std::sqrt(0.5), 0.0};
    t.after.jaw = 0.5;
    f.tools.push_back(t);
  }
  for (size_t h = 0; h < f.hashes.size(); ++h) f.hashes[h] = 0x9e3779b97f4a7c15ULL * (h + 1) + k;
  if (snapshot) f.snapshot = std::string("STATE\x01\x00\x00\x00", 9) + std::string(24, '\x42');
  return f;
}

void write(const std::string& path, size_t tools, int frames, bool ticks, const std::string& status) {
  ReplayMeta m;
  m.engine_version = "0.1.0";
  m.build = "fuzz seed";
  m.scene_path = "/work/assets/scenes/organ_instruments.json";
  m.scene_text = "{\"mesh\": {\"file\": \"../meshes/organ_10k.msh\", \"order\": 2}}";
  if (tools) m.patches.push_back({"solver.policy", "lagged", "--set solver.policy=lagged"});
  m.mesh_file = "/work/assets/meshes/organ_10k.msh";
  m.mesh_hash = 0xcbf29ce484222325ULL;
  for (size_t i = 0; i < tools; ++i) m.compliance.push_back(1e-4 * (i + 1));
  m.snapshot_every = frames > 1 ? 2 : 0;
  ReplayWriter w(path, m);
  for (int k = 1; k <= frames; ++k) {
    w.add_frame(frame(k, tools, m.snapshot_every && k % m.snapshot_every == 0));
    if (ticks) {
      std::vector<ReplayTick> ts(2);
      for (size_t i = 0; i < ts.size(); ++i) {
        ts[i].frame = k;
        ts[i].t = 0.001 * (k * 2 + i);
        ts[i].raw.p = {0.1, 0.2, 0.3};
        ts[i].raw.jaw = i ? NAN : 0.0;  // a device may report nan
        ts[i].buttons = 1u << i;
        ts[i].have_reading = i == 0;
        ts[i].force = {0.5, -0.25, 1.0};
      }
      w.add_ticks(ts);
    }
  }
  w.finish(status);
  // The seed must be what the reader accepts, else it seeds only the error paths.
  const ReplayFile r = read_replay(path);
  if (static_cast<int>(r.frames.size()) != frames || r.end_status != status || r.meta.compliance.size() != tools)
    throw Error(path + ": read back differently");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: replay_seeds OUTDIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  try {
    write(dir + "/empty.replay", 0, 0, false, "");
    write(dir + "/one_tool.replay", 1, 3, false, "");
    write(dir + "/haptic.replay", 2, 2, true, "");
    write(dir + "/stopped.replay", 1, 1, false, "scene.json: the step diverged");
  } catch (const Error& e) {
    std::fprintf(stderr, "replay_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
