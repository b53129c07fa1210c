#pragma once
// Probe point files (incise static --probe, incise study --probe): x,y,z per
// line, an optional header line, blank lines and '#' comments skipped.
#include <array>
#include <string>
#include <vector>

namespace incise {

// Throws incise::Error naming the file and line of a malformed entry.
std::vector<std::array<double, 3>> read_probe_points(const std::string& path);

}  // namespace incise
