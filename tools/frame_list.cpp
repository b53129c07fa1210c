#include "tools/frame_list.h"

#include <algorithm>
#include <cstdlib>
#include <sstream>

#include "engine/util/error.h"

namespace incise {

std::vector<int> parse_frame_list(const std::string& text, const std::string& command) {
  std::vector<int> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || v < 1 || v > 1000000)
      throw Error(command + ": --frames must be a comma-separated list of frame numbers from 1 to 1000000, got \"" + text + "\"");
    out.push_back(static_cast<int>(v));
  }
  if (out.empty()) throw Error(command + ": --frames is empty; give frame numbers such as 1,30,300");
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace incise
