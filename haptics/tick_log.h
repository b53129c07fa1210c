#pragma once
// The force log and the device stream of a haptic run, written while it runs
// (each frame's drained records appended), so a run of hours holds no
// records in memory. Each file is written to PATH.tmpPID and renamed into
// place by finish(); a writer destroyed before finish() (a run that failed
// while writing) removes its temporary files. Throws incise::Error naming the
// file when a write fails.
#include <cstdio>
#include <string>
#include <vector>

#include "haptics/haptic_loop.h"

namespace incise {

class TickLogWriter {
 public:
  // An empty path: that file is not written.
  TickLogWriter(std::string force_path, std::string device_path);
  ~TickLogWriter();
  TickLogWriter(const TickLogWriter&) = delete;
  TickLogWriter& operator=(const TickLogWriter&) = delete;

  // Force log "t,fx,fy,fz,tick_us,late_us": one row per tick; device stream
  // (haptics/replay_device.h's format): fresh readings only.
  void append(const std::vector<TickRecord>& records);
  void finish();

 private:
  struct Out {
    std::string path, tmp;
    std::FILE* f = nullptr;
  };
  void open(Out& o, const char* header);
  void check(Out& o, bool ok);
  Out force_, device_;
};

}  // namespace incise
