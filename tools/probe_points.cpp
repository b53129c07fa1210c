#include "tools/probe_points.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "engine/util/error.h"
#include "engine/util/file_io.h"

namespace incise {

std::vector<std::array<double, 3>> read_probe_points(const std::string& path) {
  std::istringstream is(read_input_file(path, kMaxTableBytes, "probe file"));
  std::vector<std::array<double, 3>> pts;
  std::string line;
  for (int lineno = 1; std::getline(is, line); ++lineno) {
    if (line.empty() || line[0] == '#' || line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ls(line);
    std::array<double, 3> p;
    std::string extra;
    if (!(ls >> p[0] >> p[1] >> p[2])) {
      if (pts.empty() && lineno == 1) continue;  // header
      throw Error(path + ":" + std::to_string(lineno) + ": expected three numbers x,y,z");
    }
    if (ls >> extra) throw Error(path + ":" + std::to_string(lineno) + ": expected exactly three values x,y,z, got more");
    for (double v : p)
      if (!std::isfinite(v)) throw Error(path + ":" + std::to_string(lineno) + ": coordinates must be finite");
    pts.push_back(p);
  }
  if (pts.empty()) throw Error(path + ": no probe points");
  return pts;
}

}  // namespace incise
