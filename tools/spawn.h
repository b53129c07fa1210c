#pragma once
// Runs a program with its arguments as given (no shell: any character in an
// argument is safe) and waits for it.
#include <string>
#include <vector>

namespace incise {

// Exit status of args[0] (searched on PATH) run with args; its stdout and
// stderr go to `log` when not empty (created or truncated), else to ours.
// Throws incise::Error naming the program when it cannot be started; a
// program killed by a signal returns 128 + the signal.
int spawn_and_wait(const std::vector<std::string>& args, const std::string& log = "");

// The python3 that draws the plots: INCISE_PYTHON, else Debian's
// /usr/bin/python3 (where python3-matplotlib lives) before another on PATH.
std::string plot_python();

// This program's own path (/proc/self/exe), for running a sub-command as a
// process of its own.
std::string self_executable();

}  // namespace incise
