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

}  // namespace incise::test
