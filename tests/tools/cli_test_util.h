#pragma once
// Runs the incise program as a user does (INCISE_BINARY, set by CMake):
// its exit code and everything it printed.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace incise::test {

struct Result {
  int code;
  std::string out;
};

inline Result incise(const std::string& args) {
  const std::filesystem::path log =
      std::filesystem::temp_directory_path() / ("incise_cli_" + std::to_string(::getpid()) + ".log");
  const std::string cmd = std::string(INCISE_BINARY) + " " + args + " > " + log.string() + " 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream is(log);
  std::stringstream ss;
  ss << is.rdbuf();
  std::filesystem::remove(log);
  return {WEXITSTATUS(status), ss.str()};
}

// scene.json of a cantilever (L = 4, 1 x 1) on the beam.vtu `mesh beam`
// wrote beside it: fixed at x = 0, gravity -z; `material`: the keys inside
// "material"; `extra`: more top-level keys, each after a comma.
inline std::string beam_scene_json(int order, const std::string& material, const std::string& extra = "") {
  return R"({"mesh": {"file": "beam.vtu", "order": )" + std::to_string(order) + R"(},
    "material": {)" + material + R"(},
    "gravity": [0, 0, -1], "fixed": [{"box": [[-1, -1, -1], [0, 2, 2]]}])" + extra + "}";
}

}  // namespace incise::test
