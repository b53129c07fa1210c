#pragma once
// One line on stderr for long runs (`incise run`, `incise replay`): frames
// done, ms per frame, real-time factor, ETA. Quiet for the first 2 s (short
// runs print nothing); on a terminal redrawn in place every 0.25 s, in a log
// one line every 10 s.
#include "engine/runtime/timing.h"

namespace incise {

class ProgressBar {
 public:
  ProgressBar(int total, double dt_s);
  void update(int done);  // after frame `done` (1-based)
  void finish();          // ends the line it drew, if any

 private:
  int total_;
  double dt_s_;
  bool tty_;
  bool drawn_ = false;
  double last_ms_ = 0.0;
  Stopwatch clock_;
};

}  // namespace incise
