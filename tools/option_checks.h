#pragma once
// Checks of numeric command-line options. CLI11's PositiveNumber,
// NonNegativeNumber and Range let NaN through (every comparison with NaN is
// false), accept inf, and state their range as 0 to 1.8e308; these read the
// text themselves and say the range allowed and why.
#include <string>

#include <CLI/CLI.hpp>

#include "engine/scene/scene.h"

namespace incise {

// The most frames a command steps (run, bench, replay, render --frame): the
// scene's limit for run.frames.
inline constexpr long long kMaxOptionFrames = kMaxFrames;
inline constexpr const char* kFramesWhy = "(9.3 h at 30 Hz)";
// The most tetrahedra mesh beam makes (6 per cell): about 0.5 GB as tet4, 1.5 GB as tet10.
inline constexpr long long kMaxBeamTets = 10000000;

// A finite number in [lo, hi]; "nan", "inf" and values that overflow a double are refused:
// "--pace: must be a finite number from 0 to 100000, got nan".
CLI::Validator finite_in(double lo, double hi, const std::string& why = "");
// A frame rate in Hz: 0 (frames back to back) or from 0.001 to 100000 (a
// longer period overflows the clock's duration).
CLI::Validator pace_rate();
// An integer in [lo, hi], written in decimal; `why` is appended to the message ("(9.3 h at 30 Hz)").
CLI::Validator integer_in(long long lo, long long hi, const std::string& why = "");

}  // namespace incise
