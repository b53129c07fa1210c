#pragma once
// The record stage (engine/runtime/pipeline.h, kStageRecord) of
// `incise run --record F`: after each frame, what the frame consumed that the
// scene does not determine (the instruments' poses, the clock's solver
// choices) and the State's hashes go to a replay file
// (engine/runtime/replay_file.h; docs/replay.md).
#include <memory>
#include <string>
#include <vector>

#include "engine/runtime/replay_file.h"
#include "engine/runtime/simulation.h"
#include "haptics/haptic_loop.h"

namespace incise {

// Opens PATH (written as PATH.tmp until ReplayWriter::finish) with the
// scene's text, the patches, the mesh's hash and the run's coupling
// compliance (install after install_haptics), and fills the record slot. A
// State snapshot goes with every `snapshot_every`-th frame (0: none) and with
// frame `last_frame`. Throws incise::Error when the scene file or mesh cannot be read.
std::shared_ptr<ReplayWriter> install_record_stage(Simulation& sim, const std::string& path,
                                                   const std::vector<ScenePatch>& patches, int snapshot_every,
                                                   int last_frame);

// The haptic loop's records[from..] (drained after frame `frame`) into the replay.
void record_ticks(ReplayWriter& w, const std::vector<TickRecord>& records, size_t from, int frame);

}  // namespace incise
