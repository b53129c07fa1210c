#include "tools/record_stage.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "tools/build_info.h"

namespace incise {

std::shared_ptr<ReplayWriter> install_record_stage(Simulation& sim, const std::string& path,
                                                   const std::vector<ScenePatch>& patches, int snapshot_every,
                                                   int last_frame) {
  ReplayMeta m;
  m.engine_version = engine_version();
  m.build = build_flags() + " on " + machine_name();
  m.scene_path = std::filesystem::absolute(sim.scene.path).lexically_normal().string();
  m.scene_text = read_input_file(sim.scene.path, kMaxSceneBytes, "scene file");
  for (const ScenePatch& p : patches) m.patches.push_back({p.key, p.value, p.given});
  m.mesh_file = sim.scene.mesh_file;
  m.mesh_hash = replay_file_hash(sim.scene.mesh_file, "mesh");
  // Absolute, as scene_path: a scene run by a relative path names its cut
  // files relative to the folder `run` was started in, and a replay from
  // another folder could not find them (or would hash another file).
  for (const CutSpec& c : sim.scene.cuts)
    if (!c.file.empty())
      m.files.emplace_back(std::filesystem::absolute(c.file).lexically_normal().string(),
                           replay_file_hash(c.file, "cut surface"));
  m.compliance = sim.ws.contacts.compliance;
  m.compliance.resize(sim.scene.instruments.size(), 0.0);
  m.snapshot_every = snapshot_every;
  auto w = std::make_shared<ReplayWriter>(path, m);
  sim.pipeline.set(kStageRecord, [w, snapshot_every, last_frame](Simulation& s) {
    const FrameTiming& t = s.ws.timing;
    ReplayFrame f;
    f.frame = s.state.frame;
    f.time = s.state.time;
    f.tools = s.tools;
    f.late_factor_call = t.late_factor_call;
    f.cut_frame = t.cut_frame;
    f.contacts = t.contacts;
    f.grasp_rows = t.grasp_rows;
    f.swept_triangles = static_cast<int>(s.state.swept.size() / 9);
    f.hashes = state_field_hashes(s.state);
    if ((snapshot_every > 0 && f.frame % snapshot_every == 0) || f.frame == last_frame) {
      std::ostringstream os;
      write_state(os, s.state);
      f.snapshot = os.str();
    }
    w->add_frame(f);
  });
  return w;
}

void record_ticks(ReplayWriter& w, const std::vector<TickRecord>& records, size_t from, int frame) {
  std::vector<ReplayTick> ticks;
  ticks.reserve(records.size() - std::min(from, records.size()));
  for (size_t i = from; i < records.size(); ++i) {
    const TickRecord& r = records[i];
    ReplayTick k;
    k.frame = frame;
    k.t = r.t;
    k.raw = r.raw.pose;
    k.buttons = r.raw.buttons;
    k.have_reading = r.have_reading;
    k.force = r.force;
    ticks.push_back(k);
  }
  w.add_ticks(ticks);
}

}  // namespace incise
