// incise: command-line entry point. Sub-commands live in tools/cmd_*.cpp.
#include "tools/cli.h"

int main(int argc, char** argv) { return incise::cli_main(argc, argv); }
