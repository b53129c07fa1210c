#pragma once
// Ctrl-C (SIGINT) or SIGTERM during `incise run`: the first one stops the
// run at the end of the frame in progress, which then finishes its outputs
// (series, timing.json, haptic logs, replay) for the frames done, so no
// temporary file or half-listed series is left; the command exits with
// 128 + the signal. A second one kills at once (the default action).
namespace incise {

void catch_interrupts();
int interrupt_signal();  // 0, or the signal caught
const char* interrupt_name();  // "SIGINT", "SIGTERM" or ""

}  // namespace incise
