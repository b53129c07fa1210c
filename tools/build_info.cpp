#include "tools/build_info.h"

#include <fstream>

namespace incise {

std::string engine_version() { return INCISE_VERSION; }

std::string build_flags() {
  std::string s = std::string(INCISE_BUILD_TYPE) + " " + INCISE_COMPILER;
  if (INCISE_BUILD_NATIVE) s += " -march=native";
  if (INCISE_BUILD_SANITIZE) s += " asan+ubsan";
  return s;
}

std::string machine_name() {
  std::ifstream is("/proc/cpuinfo");
  std::string line;
  while (std::getline(is, line))
    if (line.rfind("model name", 0) == 0 && line.find(':') != std::string::npos)
      return line.substr(line.find(':') + 2);
  return "unknown CPU";
}

}  // namespace incise
