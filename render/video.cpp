#include "render/video.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <vector>

#include "engine/util/error.h"

namespace incise {

std::string find_ffmpeg() {
  const char* path = std::getenv("PATH");
  if (!path) return "";
  std::stringstream dirs(path);
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string f = (dir.empty() ? "." : dir) + "/ffmpeg";
    if (access(f.c_str(), X_OK) == 0) return f;
  }
  return "";
}

std::string encode_mp4(const std::string& dir, double fps) {
  const std::string ffmpeg = find_ffmpeg();
  if (ffmpeg.empty()) return "";
  const std::string out = dir + "/frames.mp4";
  char rate[32];
  std::snprintf(rate, sizeof rate, "%g", fps);
  // yuv420p needs even sizes: pad by one pixel where odd. Spawned without a
  // shell, so paths need no quoting.
  std::vector<std::string> args = {ffmpeg, "-loglevel", "error", "-y", "-framerate", rate, "-i",
                                   dir + "/frame_%05d.png", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                                   "-c:v", "libx264", "-pix_fmt", "yuv420p", out};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawn(&pid, ffmpeg.c_str(), nullptr, nullptr, argv.data(), environ) != 0)
    throw Error(out + ": cannot start " + ffmpeg);
  int status = 0;
  if (waitpid(pid, &status, 0) < 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw Error(out + ": ffmpeg failed (exit status " + std::to_string(WEXITSTATUS(status)) + ")");
  return out;
}

}  // namespace incise
