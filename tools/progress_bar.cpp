#include "tools/progress_bar.h"

#include <unistd.h>

#include <cstdio>

namespace incise {

ProgressBar::ProgressBar(int total, double dt_s) : total_(total), dt_s_(dt_s), tty_(isatty(STDERR_FILENO) != 0) {}

void ProgressBar::update(int done) {
  const double ms = clock_.ms();
  if (ms < 2000.0 || done <= 0) return;
  if (done < total_ && ms - last_ms_ < (tty_ ? 250.0 : 10000.0)) return;
  if (!drawn_ && done == total_) return;  // finished before a first line was due
  last_ms_ = ms;
  const double per = ms / done, rt = done * dt_s_ * 1000.0 / ms, eta = (total_ - done) * per / 1000.0;
  constexpr int kWidth = 24;
  char bar[kWidth + 1];
  const int filled = static_cast<int>(static_cast<long long>(kWidth) * done / total_);
  for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '.';
  bar[kWidth] = '\0';
  std::fprintf(stderr, "%s[%s] %d/%d frames  %.1f ms/frame  %.2fx real time  ETA %.0f s%s", tty_ ? "\r" : "", bar,
               done, total_, per, rt, eta, tty_ ? "   " : "\n");
  std::fflush(stderr);
  drawn_ = true;
}

void ProgressBar::finish() {
  if (drawn_ && tty_) std::fprintf(stderr, "\n");
  drawn_ = false;
}

}  // namespace incise
