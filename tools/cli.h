#pragma once
namespace incise {
// Parses the command line, runs the sub-command, prints errors; returns the exit code.
int cli_main(int argc, char** argv);
}  // namespace incise
