#include "render/video.h"

#include <unistd.h>

#include <cstdlib>
#include <sstream>

#include "engine/error.h"

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

namespace {
// Single-quoted for /bin/sh.
std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}
}  // namespace

std::string encode_mp4(const std::string& dir, double fps) {
  const std::string ffmpeg = find_ffmpeg();
  if (ffmpeg.empty()) return "";
  const std::string out = dir + "/frames.mp4";
  // yuv420p needs even sizes: pad by one pixel where odd.
  const std::string cmd = quote(ffmpeg) + " -loglevel error -y -framerate " + std::to_string(fps) + " -i " +
                          quote(dir + "/frame_%05d.png") +
                          " -vf pad=ceil(iw/2)*2:ceil(ih/2)*2 -c:v libx264 -pix_fmt yuv420p " + quote(out);
  if (std::system(cmd.c_str()) != 0) throw Error(out + ": ffmpeg failed (command: " + cmd + ")");
  return out;
}

}  // namespace incise
