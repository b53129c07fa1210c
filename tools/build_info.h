#pragma once
// The binary's version and build flags: a replay records them (a bitwise
// match is expected only on the same build), `incise --version` prints them.
#include <string>

namespace incise {

std::string engine_version();  // "0.1.0"
// "Release GNU 12.2.0 -march=native" (+ " asan+ubsan" in the sanitizer build).
std::string build_flags();
// The CPU's model name (/proc/cpuinfo), "unknown CPU" elsewhere.
std::string machine_name();
// `incise --version`: the version, the build flags and the libraries found
// (CHOLMOD and SuiteSparse versions, the BLAS library loaded at run time,
// FCL, EGL's client version, OpenIGTLink when built), one per line.
std::string version_report();

}  // namespace incise
